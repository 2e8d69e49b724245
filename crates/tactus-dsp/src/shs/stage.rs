//! The stage ([`Shs`]): the framer (and a second one for the learned salience's view, the
//! side input of [`HopStage::process_with`]) in front of the tracker, and the [`HopStage`]
//! shape; [`WithDecoded`] emits the decoded estimate beside the reported one.

use super::config::ShsConfig;
use super::tracker::Tracker;
use crate::framer::Framer;
use crate::yin::PitchEstimate;
use crate::{ConfigError, HopStage};

/// Streaming bass tracker: harmonic-sum salience + fixed-lag Viterbi. See the module docs.
#[derive(Debug)]
pub struct Shs {
    cfg: ShsConfig,
    framer: Framer,
    tracker: Tracker,
    /// The view's framer and its frames, for the side input (a learned tracker only).
    view: Option<ViewFrames>,
}

/// The side input of [`HopStage::process_with`]: its framer, in step with the input's, and
/// room for the frames it emits in one step (at most one per hop of input, or the tail at
/// the end).
#[derive(Debug)]
struct ViewFrames {
    framer: Framer,
    frame: usize,
    /// Frames emitted and not yet consumed, `frame` samples each.
    buf: Vec<f32>,
    n: usize,
    next: usize,
    /// Whether this stream is fed with a side input (its tail then ends the stream too).
    fed: bool,
}

impl ViewFrames {
    fn take(&mut self) -> Option<&[f32]> {
        (self.next < self.n).then(|| {
            let k = self.next;
            self.next += 1;
            &self.buf[k * self.frame..(k + 1) * self.frame]
        })
    }
}

impl Shs {
    /// Validates `cfg` and allocates every buffer the stage will ever need.
    pub fn new(cfg: ShsConfig) -> Result<Shs, ConfigError> {
        let tracker = Tracker::new(&cfg)?;
        let framer = Framer::new(cfg.frame, cfg.hop)?;
        let view = if tracker.net.is_some() {
            // The tail at the end: at most the frames the framer still holds, plus one.
            let tail = cfg.frame / cfg.hop.max(1) + 2;
            Some(ViewFrames {
                framer: Framer::new(cfg.frame, cfg.hop)?,
                frame: cfg.frame,
                buf: vec![0.0; tail * cfg.frame],
                n: 0,
                next: 0,
                fed: false,
            })
        } else {
            None
        };
        Ok(Shs {
            cfg,
            framer,
            tracker,
            view,
        })
    }

    /// Feeds a block, emitting per hop the reported and the decoded estimate. With a side
    /// input `view` (another signal of the same span: as many samples, hop for hop the same
    /// instants) the learned salience reads it and the harmonic sum still reads `input`: the
    /// bass of a mix whose network was trained on the separator's harmonic sum
    /// ([`ShsConfig::learned_harmonic`]). With `view == input` it is the call without a
    /// view, bit for bit. A tracker without the learned salience ignores `view`. Extra
    /// samples of the longer input are not read.
    fn feed(
        &mut self,
        input: &[f32],
        view: Option<&[f32]>,
        emit: &mut dyn FnMut(usize, PitchEstimate, PitchEstimate),
    ) {
        let (Some(view), Some(vs)) = (view, self.view.as_mut()) else {
            let tracker = &mut self.tracker;
            self.framer.push(input, |_, fr| tracker.on_frame(fr, emit));
            self.tracker.flush_batch(emit);
            return;
        };
        vs.fed = true;
        let n = input.len().min(view.len());
        let hop = self.cfg.hop.max(1);
        let tracker = &mut self.tracker;
        // A hop of input at a time: each framer emits at most one frame per step, and
        // both emit at the same steps.
        for (a, b) in input[..n].chunks(hop).zip(view[..n].chunks(hop)) {
            vs.n = 0;
            vs.next = 0;
            let (buf, frame, count) = (&mut vs.buf, vs.frame, &mut vs.n);
            vs.framer.push(b, |_, fr| {
                buf[*count * frame..(*count + 1) * frame].copy_from_slice(fr);
                *count += 1;
            });
            self.framer.push(a, |_, fr| {
                let v = vs.take();
                tracker.on_frame_view(fr, v, emit);
            });
        }
        self.tracker.flush_batch(emit);
    }

    /// Ends the stream, emitting both estimates per hop ([`Shs::feed`]): the tails of the
    /// input and, for a stream fed with a side input, of the view.
    fn end(&mut self, emit: &mut dyn FnMut(usize, PitchEstimate, PitchEstimate)) {
        let Some(vs) = self.view.as_mut().filter(|vs| vs.fed) else {
            let tracker = &mut self.tracker;
            self.framer.finish(|_, fr| tracker.on_frame(fr, emit));
            self.tracker.drain_net(emit);
            self.tracker.flush(emit);
            return;
        };
        vs.n = 0;
        vs.next = 0;
        let (buf, frame, count) = (&mut vs.buf, vs.frame, &mut vs.n);
        vs.framer.finish(|_, fr| {
            if (*count + 1) * frame <= buf.len() {
                buf[*count * frame..(*count + 1) * frame].copy_from_slice(fr);
                *count += 1;
            }
        });
        let tracker = &mut self.tracker;
        self.framer.finish(|_, fr| {
            let v = vs.take();
            tracker.on_frame_view(fr, v, emit);
        });
        self.tracker.drain_net(emit);
        self.tracker.flush(emit);
    }

    /// The configuration in use.
    pub fn config(&self) -> &ShsConfig {
        &self.cfg
    }

    /// Number of candidates M.
    pub fn n_bins(&self) -> usize {
        self.tracker.m
    }

    /// The tracker emitting the decoded estimate beside the reported one ([`WithDecoded`]).
    pub fn with_decoded(self) -> WithDecoded {
        WithDecoded(self)
    }

    /// Salience of one frame (`cfg.frame` samples) per candidate, and its voicing evidence,
    /// computed like the stream's hops. Allocates the returned `Vec` (tests, plots).
    pub fn frame_salience(&mut self, frame: &[f32]) -> (Vec<f32>, f32) {
        let mut out = vec![0.0; self.tracker.m];
        if frame.len() != self.cfg.frame || !self.tracker.sal.spectrum(frame) {
            return (out, 0.02);
        }
        let v = self.tracker.sal.salience(&mut out);
        (out, v)
    }
}

impl HopStage for Shs {
    type Out = PitchEstimate;

    fn process(&mut self, input: &[f32], emit: &mut dyn FnMut(usize, PitchEstimate)) {
        self.feed(input, None, &mut |h, e, _| emit(h, e));
    }

    /// The side input is the view that the learned salience reads; the harmonic sum still
    /// reads `input` ([`ShsConfig::learned_harmonic`]).
    fn process_with(
        &mut self,
        input: &[f32],
        side: Option<&[f32]>,
        emit: &mut dyn FnMut(usize, PitchEstimate),
    ) {
        self.feed(input, side, &mut |h, e, _| emit(h, e));
    }

    fn finish(&mut self, emit: &mut dyn FnMut(usize, PitchEstimate)) {
        self.end(&mut |h, e, _| emit(h, e));
    }

    fn reset(&mut self) {
        self.framer.reset();
        if let Some(v) = &mut self.view {
            v.framer.reset();
            v.n = 0;
            v.next = 0;
            v.fed = false;
        }
        self.tracker.reset();
    }

    fn latency_samples(&self) -> usize {
        let future = self.tracker.net.as_ref().map_or(0, |n| n.future);
        self.framer.latency_samples() + (self.cfg.lag_hops + future) * self.cfg.hop
    }

    fn hop(&self) -> usize {
        self.cfg.hop
    }
}

/// An [`Shs`] that emits two estimates per hop, `(reported, decoded)`: the reported one
/// (after the attack alignment of step 9) and the decoded one (the Viterbi's decision,
/// before it); the two differ only where [`ShsConfig::attack_rise_db`] moved a note change.
/// The side input is the view, as for [`Shs`].
#[derive(Debug)]
pub struct WithDecoded(Shs);

impl WithDecoded {
    /// The tracker inside.
    pub fn shs(&self) -> &Shs {
        &self.0
    }
}

impl HopStage for WithDecoded {
    type Out = (PitchEstimate, PitchEstimate);

    fn process(&mut self, input: &[f32], emit: &mut dyn FnMut(usize, Self::Out)) {
        self.0.feed(input, None, &mut |h, e, d| emit(h, (e, d)));
    }

    fn process_with(
        &mut self,
        input: &[f32],
        side: Option<&[f32]>,
        emit: &mut dyn FnMut(usize, Self::Out),
    ) {
        self.0.feed(input, side, &mut |h, e, d| emit(h, (e, d)));
    }

    fn finish(&mut self, emit: &mut dyn FnMut(usize, Self::Out)) {
        self.0.end(&mut |h, e, d| emit(h, (e, d)));
    }

    fn reset(&mut self) {
        self.0.reset();
    }

    fn latency_samples(&self) -> usize {
        self.0.latency_samples()
    }

    fn hop(&self) -> usize {
        self.0.hop()
    }
}
