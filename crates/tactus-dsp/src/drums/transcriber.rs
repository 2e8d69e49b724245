//! The streaming transcriber ([`DrumTranscriber`]): the mel front ends (and the second
//! view's), the context window, the network per hop, and the peak pickers or the second
//! stage.

use super::judge::Staged;
use super::model::{BatchScratch, DrumModel};
use super::picker::Picker;
use super::{DrumFrame, CLASSES};
use crate::melbank::{MelBank, MelConfig, LOG_FLOOR};
use crate::{ConfigError, HopStage};

/// Streaming per-instrument drum transcriber. See the module docs.
pub struct DrumTranscriber {
    mel: MelBank,
    /// The second view's front end: the backing's (same configuration) for a model with
    /// the backing view, the short frame's ([`MelConfig::drums_short`], fed the drum
    /// signal itself) for a model with the short view.
    second_mel: Option<MelBank>,
    /// Second-view frames computed ahead of the drum signal's (at most one sub-block's worth).
    second_queue: Vec<f32>,
    core: Core,
}

/// Samples per step when a drum block and its backing are fed together: both front ends
/// see the same sub-block in turn, so at most this many samples' frames wait in the queue.
const BACKING_STEP: usize = 4096;

/// Hops the network runs on together ([`DrumModel::forward_batch`]). A feed call ends by
/// running the hops it queued, so batching delays no hop past the call that completed it:
/// the latency, and every output, are those of one hop at a time.
const BATCH: usize = 16;

struct Core {
    model: DrumModel,
    /// The last `past + 1 + future` mel frames, oldest first (shifted by hand).
    window: Vec<f32>,
    /// The second view's frames of the same hops: the backing's (silence without a
    /// backing) or the short view's.
    second_window: Vec<f32>,
    /// Assembled network inputs of the queued hops, [`BATCH`] rows.
    inputs: Vec<f32>,
    /// Hops assembled and waiting for the network (`next..next + queued`).
    queued: usize,
    scratch: BatchScratch,
    acts: Vec<[f32; CLASSES]>,
    pickers: [Picker; CLASSES],
    min_gap: usize,
    /// Mel frames received.
    frames: usize,
    /// Hops whose activations are computed.
    next: usize,
    /// The second stage's state, for a staged model.
    staged: Option<Staged>,
}

impl Core {
    /// One mel frame of the drum signal and, for a backing model, the backing's frame of
    /// the same hop (`None`: silence).
    fn push_frame(
        &mut self,
        bands: &[f32],
        back: Option<&[f32]>,
        emit: &mut dyn FnMut(usize, DrumFrame),
    ) {
        let n = self.model.bands;
        self.window.copy_within(n.., 0);
        let len = self.window.len();
        self.window[len - n..].copy_from_slice(bands);
        if self.model.has_second_view() {
            self.second_window.copy_within(n.., 0);
            let tail = &mut self.second_window[len - n..];
            match back {
                Some(b) => tail.copy_from_slice(b),
                None => tail.fill(LOG_FLOOR.ln()),
            }
        }
        self.frames += 1;
        // The window now ends at frame `frames - 1`, so it is centred (at `past`) on hop
        // `frames - 1 - future`.
        if self.frames > self.model.future {
            let i = self.frames - 1 - self.model.future;
            debug_assert_eq!(i, self.next + self.queued);
            let len = self.model.input_len();
            let slot = &mut self.inputs[self.queued * len..(self.queued + 1) * len];
            self.model
                .assemble_with_backing(&self.window, &self.second_window, slot);
            self.queued += 1;
            if self.queued == BATCH {
                self.run_queued(emit);
            }
        }
    }

    /// Runs the network on the queued hops and decides them in order.
    fn run_queued(&mut self, emit: &mut dyn FnMut(usize, DrumFrame)) {
        let count = std::mem::take(&mut self.queued);
        if count == 0 {
            return;
        }
        self.model
            .forward_batch(&self.inputs, count, &mut self.scratch, &mut self.acts);
        let thresholds = self.model.thresholds;
        for &act in &self.acts[..count] {
            let i = self.next;
            self.next += 1;
            if let (Some(st), Some(stage)) = (self.staged.as_mut(), self.model.stage.as_ref()) {
                let k = st.ring.len();
                st.ring[i % k] = act;
                if i + 1 >= k {
                    let j = i + 1 - k;
                    st.decide(
                        stage,
                        &mut self.pickers,
                        &thresholds,
                        self.min_gap,
                        j,
                        i + 1,
                        emit,
                    );
                }
                continue;
            }
            let mut f = DrumFrame {
                activation: act,
                onset: [false; CLASSES],
            };
            for (c, (onset, picker)) in f.onset.iter_mut().zip(&mut self.pickers).enumerate() {
                *onset = picker.step(i, act[c], thresholds[c], self.min_gap);
            }
            emit(i, f);
        }
    }

    /// Ends a staged stream: decides the hops still waiting for later ones, each on the
    /// hops that exist.
    fn drain(&mut self, emit: &mut dyn FnMut(usize, DrumFrame)) {
        if let (Some(st), Some(stage)) = (self.staged.as_mut(), self.model.stage.as_ref()) {
            let thresholds = self.model.thresholds;
            while st.emitted < self.next {
                let j = st.emitted;
                st.decide(
                    stage,
                    &mut self.pickers,
                    &thresholds,
                    self.min_gap,
                    j,
                    self.next,
                    emit,
                );
            }
        }
    }

    fn reset(&mut self) {
        self.window.fill(LOG_FLOOR.ln());
        self.second_window.fill(LOG_FLOOR.ln());
        self.pickers = [Picker::NEW; CLASSES];
        self.frames = 0;
        self.next = 0;
        self.queued = 0;
        match (self.staged.as_mut(), self.model.stage.as_ref()) {
            // Back to the start in place: a reset allocates nothing.
            (Some(st), Some(_)) => st.clear(),
            (_, stage) => self.staged = stage.map(Staged::new),
        }
    }
}

impl DrumTranscriber {
    /// A transcriber with the embedded model.
    pub fn new(sample_rate: u32) -> Result<Self, ConfigError> {
        Self::with_model(sample_rate, DrumModel::embedded())
    }

    /// A transcriber with a given model (its band count must match the front end).
    pub fn with_model(sample_rate: u32, model: DrumModel) -> Result<Self, ConfigError> {
        let cfg = MelConfig::drums(sample_rate);
        if model.bands != cfg.bands {
            return Err(ConfigError::invalid(
                "drum model",
                format!("has {} bands, the front end {}", model.bands, cfg.bands),
            ));
        }
        let (hop, cfg_bands) = (cfg.hop, cfg.bands);
        let second_mel = if model.short {
            Some(MelBank::new(MelConfig::drums_short(sample_rate))?)
        } else if model.backing.is_some() {
            Some(MelBank::new(cfg.clone())?)
        } else {
            None
        };
        let mel = MelBank::new(cfg)?;
        let min_gap = ((0.05 * sample_rate as f64) / hop as f64).ceil() as usize;
        let second_len = if model.has_second_view() {
            model.window_len()
        } else {
            0
        };
        let mut core = Core {
            window: vec![0.0; model.window_len()],
            second_window: vec![0.0; second_len],
            inputs: vec![0.0; BATCH * model.input_len()],
            queued: 0,
            scratch: BatchScratch::new(&model, BATCH),
            acts: vec![[0.0; CLASSES]; BATCH],
            model,
            pickers: [Picker::NEW; CLASSES],
            min_gap: min_gap.max(1),
            frames: 0,
            next: 0,
            staged: None,
        };
        core.reset();
        let queue = if second_mel.is_some() {
            (BACKING_STEP / hop + 2) * cfg_bands
        } else {
            0
        };
        Ok(DrumTranscriber {
            mel,
            second_mel,
            second_queue: Vec::with_capacity(queue),
            core,
        })
    }

    /// The model in use.
    pub fn model(&self) -> &DrumModel {
        &self.core.model
    }

    /// Whether the model reads a backing beside the drum signal (the side input of
    /// [`HopStage::process_with`]).
    pub fn wants_backing(&self) -> bool {
        self.core.model.backing.is_some()
    }

    /// Feeds a block of the drum signal alone. A model with the backing view sees silence
    /// as the backing (a supplied, clean drum stem).
    fn feed(&mut self, input: &[f32], emit: &mut dyn FnMut(usize, DrumFrame)) {
        if self.core.model.short {
            return self.feed_both(input, input, emit);
        }
        let core = &mut self.core;
        self.mel
            .process_bands(input, &mut |_, bands| core.push_frame(bands, None, emit));
        core.run_queued(emit);
    }

    /// Feeds the drum signal to the main front end and `second` (the backing, or the drum
    /// signal itself for the short view) to the second view's, in steps of `BACKING_STEP`.
    fn feed_both(&mut self, input: &[f32], second: &[f32], emit: &mut dyn FnMut(usize, DrumFrame)) {
        let Some(second_mel) = self.second_mel.as_mut() else {
            return;
        };
        let n = self.core.model.bands;
        let (queue, core) = (&mut self.second_queue, &mut self.core);
        for (x, b) in input.chunks(BACKING_STEP).zip(second.chunks(BACKING_STEP)) {
            second_mel.process_bands(b, &mut |_, bands| queue.extend_from_slice(bands));
            let mut k = 0;
            self.mel.process_bands(x, &mut |_, bands| {
                let back = queue.get(k * n..(k + 1) * n);
                core.push_frame(bands, back, emit);
                k += 1;
            });
            queue.clear();
        }
        core.run_queued(emit);
    }

    /// Ends the stream: emits every remaining hop (`n.div_ceil(hop)` in all), holding the
    /// last mel frame for the look-ahead frames past the end.
    fn end(&mut self, emit: &mut dyn FnMut(usize, DrumFrame)) {
        let n = self.core.model.bands;
        let (queue, core) = (&mut self.second_queue, &mut self.core);
        if let Some(second_mel) = self.second_mel.as_mut() {
            second_mel.finish_bands(&mut |_, bands| queue.extend_from_slice(bands));
        }
        let mut k = 0;
        self.mel.finish_bands(&mut |_, bands| {
            let back = queue.get(k * n..(k + 1) * n);
            core.push_frame(bands, back, emit);
            k += 1;
        });
        queue.clear();
        // Every hop has its mel frame now; the last `future` hops still wait for frames
        // past the end: hold the last one (of both views).
        let total = core.frames;
        let len = core.window.len();
        let mut last = [0f32; 512];
        last[..n].copy_from_slice(&core.window[len - n..]);
        let mut last_second = [0f32; 512];
        let has_second = core.model.has_second_view();
        if has_second {
            last_second[..n].copy_from_slice(&core.second_window[len - n..]);
        }
        while core.next + core.queued < total {
            let back = has_second.then_some(&last_second[..n]);
            core.push_frame(&last[..n], back, emit);
        }
        core.run_queued(emit);
        core.drain(emit);
    }
}

impl HopStage for DrumTranscriber {
    type Out = DrumFrame;

    /// Calls `emit(hop, frame)` for every decided hop, in order.
    fn process(&mut self, input: &[f32], emit: &mut dyn FnMut(usize, DrumFrame)) {
        self.feed(input, emit);
    }

    /// The side input is the backing: the same span of the separator's other stems, summed,
    /// as long as `input`. A model without the backing view ignores it.
    fn process_with(
        &mut self,
        input: &[f32],
        side: Option<&[f32]>,
        emit: &mut dyn FnMut(usize, DrumFrame),
    ) {
        match side {
            Some(backing) if self.core.model.backing.is_some() => {
                debug_assert_eq!(input.len(), backing.len());
                self.feed_both(input, backing, emit);
            }
            _ => self.feed(input, emit),
        }
    }

    fn finish(&mut self, emit: &mut dyn FnMut(usize, DrumFrame)) {
        self.end(emit);
    }

    fn reset(&mut self) {
        self.mel.reset();
        if let Some(m) = self.second_mel.as_mut() {
            m.reset();
        }
        self.second_queue.clear();
        self.core.reset();
    }

    fn latency_samples(&self) -> usize {
        let wait = self.core.model.stage.as_ref().map_or(0, |s| s.wait);
        self.mel.latency_samples() + (self.core.model.future + wait) * self.mel.hop()
    }

    fn hop(&self) -> usize {
        self.mel.hop()
    }
}
