//! ADTLib drum transcription (kick, snare, hi-hat) through ONNX Runtime.
//!
//! **Model.** ADTLib 2.1.2 (Southall, Stables, Hockman, ISMIR 2017: bidirectional LSTMs
//! with soft attention), one network per instrument, converted from the TensorFlow
//! checkpoints in the PyPI sdist by `models/setup_adtlib.sh` into `models/adtlib.onnx`:
//! input `spec` `[1, T, 1024]`, outputs `kick`, `snare`, `hihat` `[1, T]` (onset
//! activations in `[0, 1]`). See models/README.md for provenance and the licence question.
//!
//! **Front end** (madmom's `Spectrogram` as ADTLib calls it): mono 44.1 kHz, symmetric
//! Hann window of 2048 (`np.hanning`), hop 512 (86.13 frames/s), frame `i` centred on
//! sample `i·512` with zeros outside the signal, `ceil(n / 512)` frames for `n` samples,
//! magnitude of bins 0..1023 (no log). [`spectrogram`] is that front end on a whole signal.
//!
//! **Level.** The networks are level-sensitive (trained on 16-bit files read as
//! `[-1, 1]`). Each network call scales its input spectrogram by
//! `target / max(peak, floor)`, where `peak` is the running maximum of `|x|` over every
//! sample that the window's last frame has seen ([`Level::Peak`], default target 0.25,
//! floor 0.01; on a synthetic sonic-pi pattern, peaks of 0.1, 0.25 and 1.0 gave clean
//! onsets and 0.5 a few false kicks). The gain depends on sample positions only, never on
//! how the input is chunked.
//!
//! **Windows.** The network looks both ways in time, so it runs on sliding windows:
//! each call covers `context` frames of left context, `hop` frames that it emits and
//! `lookahead` frames of right context (zero frames of context at the start, and at
//! [`AdtLib::finish`] the window ends with the signal). [`AdtLibConfig::streaming`]
//! (8 / 32 / 12 frames) is the live setting, [`AdtLibConfig::offline`] long windows.
//!
//! **Peak picking** (ADTLib's `meanPPmm` with its `PPParams.npy`): frame `i` is an onset
//! of a class when `a[i] > a[i-1]`, `a[i] >= a[i+1]` (zeros outside the signal) and
//! `a[i] >` the class threshold: kick a fixed 0.3; snare `3 × mean(a)` but at least 0.05;
//! hi-hat `3.1 × mean(a)`. ADTLib takes the mean over the whole track; here it is the
//! running mean of every activation emitted so far, the only causal choice. ADTLib also
//! meant to merge onsets closer than 50 ms (its code drops the result of `np.delete`, so
//! it never does); here a peak less than [`AdtLibConfig::min_interval_s`] after the
//! previous onset of its class is dropped (the earlier one wins, so nothing waits).
//! An onset's time is its frame centre, `i · 512 / 44100` s; its strength is `a[i]`.
//!
//! **Latency.** [`AdtLib::latency_samples`] `= (hop + lookahead) · 512 + 1024`: the most
//! samples that can follow an onset's time before the `process` call that reports it
//! (a frame needs 1024 samples past its centre, a batch waits for its look-ahead, and a
//! peak needs the next frame). 255 ms for the streaming setting.
//!
//! **Allocation and blocking.** Buffers are allocated at construction; ONNX Runtime
//! allocates its outputs inside each network call, which runs on the caller's thread.
//! [`AdtLibConfig::keep_activations`] makes the detector append every activation to a
//! growing record (for tests and plots). Network failures do not stop the stream: the
//! frames of that call read as zero activation and [`AdtLib::last_error`] keeps the error.
//!
//! **Panics**: none; all indices derive from sizes fixed at construction.
//!
//! ```no_run
//! use tactus_separate::onnx::adtlib::{AdtLib, AdtLibConfig};
//! use tactus_separate::onnx::OnnxConfig;
//!
//! // models/setup_onnxruntime.sh and models/setup_adtlib.sh; ORT_DYLIB_PATH set.
//! let onnx = OnnxConfig { threads: 1, ..OnnxConfig::new("models/adtlib.onnx") };
//! let mut det = AdtLib::new(&onnx, 44_100, AdtLibConfig::streaming())?;
//! let block = vec![0.0f32; 512]; // mono 44.1 kHz, any block size
//! let mut print = |o: tactus_separate::onnx::adtlib::DrumOnset| {
//!     println!("{} at {:.3} s ({:.2})", o.class.name(), o.time_s, o.strength)
//! };
//! det.process(&block, &mut print);
//! det.finish(&mut print);
//! # Ok::<(), tactus_separate::onnx::adtlib::AdtLibError>(())
//! ```

use realfft::num_complex::Complex;
use realfft::{RealFftPlanner, RealToComplex};
use std::sync::Arc;

use ort::session::Session;
use ort::value::TensorRef;

use super::{open_session, OnnxConfig, OnnxError, Port};

/// The only sample rate the networks were trained at.
pub const SAMPLE_RATE: u32 = 44_100;
/// Analysis window length (samples).
pub const FRAME: usize = 2048;
/// Hop between frames (samples): 86.13 frames per second.
pub const HOP: usize = 512;
/// Spectrogram bins fed to the network (bins 0..1023 of the 2048-point FFT).
pub const BINS: usize = 1024;

const INPUTS: [Port; 1] = [Port {
    name: "spec",
    shape: &[Some(1), None, Some(BINS as i64)],
}];
const OUTPUTS: [Port; 3] = [
    Port {
        name: "kick",
        shape: &[Some(1), None],
    },
    Port {
        name: "snare",
        shape: &[Some(1), None],
    },
    Port {
        name: "hihat",
        shape: &[Some(1), None],
    },
];

/// The instrument classes ADTLib transcribes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DrumClass {
    /// Bass drum (ADTLib's `Kick`).
    Kick,
    /// Snare drum (ADTLib's `Snare`).
    Snare,
    /// Hi-hat (ADTLib's `Hihat`); Tactus files it under cymbals.
    Cymbals,
}

impl DrumClass {
    /// The classes in the model's output order.
    pub const ALL: [DrumClass; 3] = [DrumClass::Kick, DrumClass::Snare, DrumClass::Cymbals];

    /// Tactus's name of the class (`kick`, `snare`, `cymbals`).
    pub fn name(self) -> &'static str {
        match self {
            DrumClass::Kick => "kick",
            DrumClass::Snare => "snare",
            DrumClass::Cymbals => "cymbals",
        }
    }

    /// The model output that carries the class.
    pub fn output(self) -> &'static str {
        match self {
            DrumClass::Kick => "kick",
            DrumClass::Snare => "snare",
            DrumClass::Cymbals => "hihat",
        }
    }

    fn index(self) -> usize {
        self as usize
    }
}

/// One detected drum hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DrumOnset {
    /// The instrument.
    pub class: DrumClass,
    /// The frame (`time_s · 44100 / 512`).
    pub frame: usize,
    /// Seconds from the start of the stream (the frame centre).
    pub time_s: f64,
    /// The activation at the peak, in `[0, 1]`.
    pub strength: f32,
}

/// Input level normalisation (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Level {
    /// Feed the spectrogram as it is.
    Off,
    /// Scale each network call so that the running sample peak sits at `target`; peaks
    /// below `floor` count as `floor` (quiet input is not raised more than `target/floor`).
    Peak {
        /// The level the running peak is scaled to.
        target: f32,
        /// The smallest peak used.
        floor: f32,
    },
}

impl Default for Level {
    fn default() -> Self {
        Level::Peak {
            target: 0.25,
            floor: 0.01,
        }
    }
}

/// ADTLib's peak-picking parameters for one class (a row of `PPParams.npy`): the
/// threshold is `lambda × mean activation`, clamped to `[min, max]` where a zero bound is
/// no bound; `lambda = 0` gives the fixed threshold `min`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeakParams {
    /// Multiple of the mean activation.
    pub lambda: f32,
    /// Lower bound of the threshold (0: none).
    pub min: f32,
    /// Upper bound of the threshold (0: none).
    pub max: f32,
}

impl PeakParams {
    /// ADTLib 2.1.2's `PPParams.npy`, rows kick, snare, hi-hat.
    pub const ADTLIB: [PeakParams; 3] = [
        PeakParams {
            lambda: 0.0,
            min: 0.3,
            max: 0.0,
        },
        PeakParams {
            lambda: 3.0,
            min: 0.05,
            max: 0.0,
        },
        PeakParams {
            lambda: 3.1,
            min: 0.0,
            max: 0.0,
        },
    ];

    /// The threshold for a mean activation `mean` (ADTLib's `meanPPmm`).
    pub fn threshold(&self, mean: f32) -> f32 {
        let mut m = mean * self.lambda;
        if self.max != 0.0 && m > self.max {
            m = self.max;
        }
        if self.min != 0.0 && m < self.min {
            m = self.min;
        }
        m
    }
}

/// Windowing, level and peak-picking settings.
#[derive(Clone, Debug, PartialEq)]
pub struct AdtLibConfig {
    /// Frames emitted per network call (≥ 1).
    pub hop: usize,
    /// Frames of left context per call.
    pub context: usize,
    /// Frames of right context per call (look-ahead).
    pub lookahead: usize,
    /// Input level normalisation.
    pub level: Level,
    /// Peak picking per class (kick, snare, hi-hat).
    pub peaks: [PeakParams; 3],
    /// A peak closer than this to the previous onset of its class is dropped (seconds).
    pub min_interval_s: f64,
    /// Keep every activation (see [`AdtLib::activations`]).
    pub keep_activations: bool,
}

impl AdtLibConfig {
    /// Live setting: 8-frame (93 ms) calls, 32 frames (372 ms) of context, 12 frames
    /// (139 ms) of look-ahead; latency 255 ms.
    pub fn streaming() -> Self {
        AdtLibConfig {
            hop: 8,
            context: 32,
            lookahead: 12,
            level: Level::default(),
            peaks: PeakParams::ADTLIB,
            min_interval_s: 0.05,
            keep_activations: false,
        }
    }

    /// Offline setting: 10 s calls with 1 s of context either side.
    pub fn offline() -> Self {
        AdtLibConfig {
            hop: 861,
            context: 86,
            lookahead: 86,
            ..Self::streaming()
        }
    }

    fn window(&self) -> usize {
        self.context + self.hop + self.lookahead
    }
}

impl Default for AdtLibConfig {
    fn default() -> Self {
        Self::streaming()
    }
}

/// Errors of the ADTLib detector.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum AdtLibError {
    /// Runtime or model could not be loaded, or the model's ports are not ADTLib's.
    #[error(transparent)]
    Onnx(#[from] OnnxError),
    /// The networks only run at 44 100 Hz.
    #[error("ADTLib runs at 44100 Hz only, got {0} Hz: resample the input first")]
    SampleRate(u32),
    /// A configuration value is out of range.
    #[error("invalid ADTLib setting: {0}")]
    Config(&'static str),
    /// A spectrogram slice is not a whole number of 1024-bin frames.
    #[error("spectrogram of {0} values is not a whole number of 1024-bin frames")]
    SpectrogramShape(usize),
    /// ONNX Runtime failed in a network call.
    #[error("ADTLib network call failed")]
    Network(#[source] ort::Error),
    /// An output does not have one value per input frame.
    #[error("ADTLib output `{name}` has {got} values for {want} frames")]
    OutputShape {
        /// The output.
        name: &'static str,
        /// Values received.
        got: usize,
        /// Frames sent.
        want: usize,
    },
}

/// The symmetric Hann window `np.hanning(2048)`.
fn hanning() -> Vec<f32> {
    let n = FRAME as f64 - 1.0;
    (0..FRAME)
        .map(|k| (0.5 - 0.5 * (std::f64::consts::TAU * k as f64 / n).cos()) as f32)
        .collect()
}

/// Frames of madmom's framing for `n` samples: `ceil(n / 512)`.
pub fn frame_count(n: usize) -> usize {
    n.div_ceil(HOP)
}

/// The front end on a whole mono 44.1 kHz signal: `frame_count(n)` frames × 1024 bins,
/// frame-major (madmom's `Spectrogram(frame_size=2048, hop_size=512)`; no normalisation).
pub fn spectrogram(mono: &[f32]) -> Vec<f32> {
    let mut fe = FrontEnd::new();
    let frames = frame_count(mono.len());
    let mut out = vec![0.0; frames * BINS];
    let mut padded = vec![0.0f32; FRAME / 2 + mono.len() + FRAME];
    padded[FRAME / 2..FRAME / 2 + mono.len()].copy_from_slice(mono);
    for (f, dst) in out.chunks_exact_mut(BINS).enumerate() {
        fe.frame(&padded[f * HOP..f * HOP + FRAME], dst);
    }
    out
}

/// Window, FFT and magnitude of one frame.
struct FrontEnd {
    window: Vec<f32>,
    fft: Arc<dyn RealToComplex<f32>>,
    input: Vec<f32>,
    spectrum: Vec<Complex<f32>>,
    scratch: Vec<Complex<f32>>,
}

impl FrontEnd {
    fn new() -> Self {
        let fft = RealFftPlanner::<f32>::new().plan_fft_forward(FRAME);
        FrontEnd {
            window: hanning(),
            input: fft.make_input_vec(),
            spectrum: fft.make_output_vec(),
            scratch: fft.make_scratch_vec(),
            fft,
        }
    }

    /// `samples` has FRAME values; writes BINS magnitudes into `out`.
    fn frame(&mut self, samples: &[f32], out: &mut [f32]) {
        for ((d, &x), &w) in self.input.iter_mut().zip(samples).zip(&self.window) {
            *d = x * w;
        }
        // Lengths are fixed by the plan, so this cannot fail.
        let _ =
            self.fft
                .process_with_scratch(&mut self.input, &mut self.spectrum, &mut self.scratch);
        for (o, c) in out.iter_mut().zip(&self.spectrum) {
            *o = c.norm();
        }
    }
}

/// Streaming peak picker of one class.
#[derive(Clone, Debug, Default)]
struct Picker {
    /// `a[i-1]`, `a[i]` and `i` of the frame waiting for its right neighbour.
    prev: f32,
    cur: Option<(usize, f32)>,
    sum: f64,
    count: u64,
    last_onset: Option<usize>,
}

impl Picker {
    /// Feeds `a[frame]`; returns the onset decided by it (frame `frame - 1`), if any.
    fn push(
        &mut self,
        frame: usize,
        a: f32,
        params: &PeakParams,
        min_gap: usize,
    ) -> Option<(usize, f32)> {
        let a = if a.is_finite() { a } else { 0.0 };
        self.sum += a as f64;
        self.count += 1;
        let decided = self.judge(a, params, min_gap);
        self.cur = Some((frame, a));
        decided
    }

    /// Decides the waiting frame given its right neighbour `next`.
    fn judge(&mut self, next: f32, params: &PeakParams, min_gap: usize) -> Option<(usize, f32)> {
        let (i, v) = self.cur?;
        let prev = std::mem::replace(&mut self.prev, v);
        let mean = if self.count > 0 {
            (self.sum / self.count as f64) as f32
        } else {
            0.0
        };
        let gap_ok = self.last_onset.is_none_or(|l| i - l >= min_gap);
        if v > prev && v >= next && v > params.threshold(mean) && gap_ok {
            self.last_onset = Some(i);
            Some((i, v))
        } else {
            None
        }
    }
}

/// The ADTLib detector: mono 44.1 kHz samples in, kick / snare / hi-hat onsets out.
pub struct AdtLib {
    cfg: AdtLibConfig,
    session: Session,
    fe: FrontEnd,
    /// Zero-padded input (1024 zeros before sample 0): padded index `buf_start + k`.
    buf: Vec<f32>,
    buf_start: usize,
    /// Samples received.
    samples_in: usize,
    /// Padded index up to which the running peak has looked.
    peak_upto: usize,
    peak: f32,
    /// Spectrogram frames `spec_start..frames`, 1024 bins each.
    spec: Vec<f32>,
    spec_start: usize,
    frames: usize,
    /// The first frame not emitted yet.
    emitted: usize,
    net_in: Vec<f32>,
    acts: [Vec<f32>; 3],
    pickers: [Picker; 3],
    min_gap: usize,
    record: [Vec<f32>; 3],
    finished: bool,
    last_error: Option<AdtLibError>,
    calls: u64,
}

impl std::fmt::Debug for AdtLib {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AdtLib")
            .field("cfg", &self.cfg)
            .field("samples_in", &self.samples_in)
            .field("frames", &self.frames)
            .finish_non_exhaustive()
    }
}

impl AdtLib {
    /// Loads `onnx.model` (models/adtlib.onnx) with the runtime and threads of `onnx`.
    pub fn new(
        onnx: &OnnxConfig,
        sample_rate: u32,
        cfg: AdtLibConfig,
    ) -> Result<Self, AdtLibError> {
        if sample_rate != SAMPLE_RATE {
            return Err(AdtLibError::SampleRate(sample_rate));
        }
        if cfg.hop == 0 {
            return Err(AdtLibError::Config("hop must be at least 1 frame"));
        }
        if cfg.window() > 1 << 20 {
            return Err(AdtLibError::Config("window longer than 2^20 frames"));
        }
        if !(cfg.min_interval_s.is_finite() && cfg.min_interval_s >= 0.0) {
            return Err(AdtLibError::Config(
                "min_interval_s must be finite and >= 0",
            ));
        }
        if let Level::Peak { target, floor } = cfg.level {
            if !(target.is_finite() && target > 0.0 && floor.is_finite() && floor > 0.0) {
                return Err(AdtLibError::Config("level target and floor must be > 0"));
            }
        }
        let session = open_session(onnx, "kick/snare/hi-hat (ADTLib)", &INPUTS, &OUTPUTS)?;
        let window = cfg.window();
        let min_gap = (cfg.min_interval_s * SAMPLE_RATE as f64 / HOP as f64).ceil() as usize;
        let mut det = AdtLib {
            session,
            fe: FrontEnd::new(),
            buf: Vec::with_capacity(2 * FRAME + HOP),
            buf_start: 0,
            samples_in: 0,
            peak_upto: FRAME / 2,
            peak: 0.0,
            spec: Vec::with_capacity((window + 1) * BINS),
            spec_start: 0,
            frames: 0,
            emitted: 0,
            net_in: Vec::with_capacity(window * BINS),
            acts: std::array::from_fn(|_| Vec::with_capacity(window)),
            pickers: Default::default(),
            min_gap,
            record: Default::default(),
            finished: false,
            last_error: None,
            calls: 0,
            cfg,
        };
        det.reset();
        Ok(det)
    }

    /// The settings.
    pub fn config(&self) -> &AdtLibConfig {
        &self.cfg
    }

    /// The most samples that can follow an onset's time before the `process` call that
    /// reports it: `(hop + lookahead) · 512 + 1024`.
    pub fn latency_samples(&self) -> usize {
        (self.cfg.hop + self.cfg.lookahead) * HOP + FRAME / 2
    }

    /// Network calls since construction.
    pub fn network_calls(&self) -> u64 {
        self.calls
    }

    /// The error of the last failed network call, if any.
    pub fn last_error(&self) -> Option<&AdtLibError> {
        self.last_error.as_ref()
    }

    /// Every activation emitted since the last reset (kick, snare, hi-hat), when
    /// [`AdtLibConfig::keep_activations`] is set; empty otherwise.
    pub fn activations(&self) -> [&[f32]; 3] {
        [&self.record[0], &self.record[1], &self.record[2]]
    }

    /// Starts a new stream (keeps the model and settings).
    pub fn reset(&mut self) {
        self.buf.clear();
        self.buf.resize(FRAME / 2, 0.0);
        self.buf_start = 0;
        self.samples_in = 0;
        self.peak_upto = FRAME / 2;
        self.peak = 0.0;
        self.spec.clear();
        self.spec_start = 0;
        self.frames = 0;
        self.emitted = 0;
        self.pickers = Default::default();
        for r in &mut self.record {
            r.clear();
        }
        self.finished = false;
    }

    /// Feeds mono samples; calls `out` for each onset decided (in time order per class).
    /// After [`finish`](Self::finish), the next call starts a new stream.
    pub fn process(&mut self, mono: &[f32], out: &mut dyn FnMut(DrumOnset)) {
        if self.finished {
            self.reset();
        }
        for piece in mono.chunks(HOP) {
            self.buf.extend_from_slice(piece);
            self.samples_in += piece.len();
            while self.buf_start + self.buf.len() >= self.frames * HOP + FRAME {
                self.next_frame();
                while self.frames >= self.emitted + self.cfg.hop + self.cfg.lookahead {
                    let end = self.emitted + self.cfg.hop;
                    self.run_batch(end, self.frames.min(end + self.cfg.lookahead), out);
                }
            }
        }
    }

    /// Ends the stream: the last frames run with the context there is, and the final
    /// frame is judged against a zero after it (as ADTLib pads).
    pub fn finish(&mut self, out: &mut dyn FnMut(DrumOnset)) {
        if self.finished {
            return;
        }
        let total = frame_count(self.samples_in);
        self.buf.resize(self.buf.len() + FRAME, 0.0);
        while self.frames < total {
            self.next_frame();
        }
        while self.emitted < total {
            let end = (self.emitted + self.cfg.hop).min(total);
            self.run_batch(end, total.min(end + self.cfg.lookahead), out);
        }
        for c in DrumClass::ALL {
            let k = c.index();
            if let Some((i, v)) = self.pickers[k].judge(0.0, &self.cfg.peaks[k], self.min_gap) {
                out(onset(c, i, v));
            }
            self.pickers[k].cur = None;
        }
        self.finished = true;
    }

    /// Runs the networks on a whole spectrogram (`frames × 1024`, frame-major, used as
    /// given: no level normalisation) and returns the kick, snare and hi-hat activations.
    pub fn activations_of(&mut self, spec: &[f32]) -> Result<[Vec<f32>; 3], AdtLibError> {
        if !spec.len().is_multiple_of(BINS) {
            return Err(AdtLibError::SpectrogramShape(spec.len()));
        }
        let frames = spec.len() / BINS;
        let mut acts: [Vec<f32>; 3] = Default::default();
        if frames == 0 {
            return Ok(acts);
        }
        run_network(&mut self.session, spec, frames, &mut acts)?;
        Ok(acts)
    }

    /// Computes frame `self.frames` from the buffer and updates the running peak.
    fn next_frame(&mut self) {
        let f = self.frames;
        let lo = f * HOP - self.buf_start;
        let hi_abs = (f * HOP + FRAME).min(FRAME / 2 + self.samples_in);
        for &x in &self.buf[self.peak_upto.max(self.buf_start) - self.buf_start
            ..hi_abs.max(self.peak_upto) - self.buf_start]
        {
            self.peak = self.peak.max(x.abs());
        }
        self.peak_upto = self.peak_upto.max(hi_abs);
        let base = self.spec.len();
        self.spec.resize(base + BINS, 0.0);
        self.fe
            .frame(&self.buf[lo..lo + FRAME], &mut self.spec[base..base + BINS]);
        self.frames += 1;
        // Frame f + 1 starts at padded index (f + 1) · 512.
        let drop = (self.frames * HOP - self.buf_start).min(self.buf.len());
        self.buf.drain(..drop);
        self.buf_start += drop;
    }

    /// Runs the networks on frames `[emitted − context, stop)` and emits `[emitted, end)`.
    fn run_batch(&mut self, end: usize, stop: usize, out: &mut dyn FnMut(DrumOnset)) {
        let start = self.emitted.saturating_sub(self.cfg.context);
        let n = stop - start;
        let gain = match self.cfg.level {
            Level::Off => 1.0,
            Level::Peak { target, floor } => target / self.peak.max(floor),
        };
        let src = &self.spec[(start - self.spec_start) * BINS..(stop - self.spec_start) * BINS];
        self.net_in.clear();
        self.net_in.extend(src.iter().map(|&x| x * gain));
        self.calls += 1;
        if let Err(e) = run_network(&mut self.session, &self.net_in, n, &mut self.acts) {
            self.last_error = Some(e);
            for a in &mut self.acts {
                a.clear();
                a.resize(n, 0.0);
            }
        }
        for f in self.emitted..end {
            for c in DrumClass::ALL {
                let k = c.index();
                let a = self.acts[k][f - start];
                if self.cfg.keep_activations {
                    self.record[k].push(a);
                }
                let params = self.cfg.peaks[k];
                if let Some((i, v)) = self.pickers[k].push(f, a, &params, self.min_gap) {
                    out(onset(c, i, v));
                }
            }
        }
        self.emitted = end;
        // Keep the frames the next call's context needs.
        let keep_from = self
            .emitted
            .saturating_sub(self.cfg.context)
            .max(self.spec_start);
        self.spec.drain(..(keep_from - self.spec_start) * BINS);
        self.spec_start = keep_from;
    }
}

fn onset(class: DrumClass, frame: usize, strength: f32) -> DrumOnset {
    DrumOnset {
        class,
        frame,
        time_s: (frame * HOP) as f64 / SAMPLE_RATE as f64,
        strength,
    }
}

/// One network call on `frames` frames; fills `acts` with `frames` values each.
fn run_network(
    session: &mut Session,
    spec: &[f32],
    frames: usize,
    acts: &mut [Vec<f32>; 3],
) -> Result<(), AdtLibError> {
    let input =
        TensorRef::from_array_view(([1usize, frames, BINS], spec)).map_err(AdtLibError::Network)?;
    let outputs = session
        .run(ort::inputs!["spec" => input])
        .map_err(AdtLibError::Network)?;
    for c in DrumClass::ALL {
        let name = c.output();
        let Some(v) = outputs.get(name) else {
            return Err(AdtLibError::OutputShape {
                name,
                got: 0,
                want: frames,
            });
        };
        let (_, data) = v
            .try_extract_tensor::<f32>()
            .map_err(AdtLibError::Network)?;
        if data.len() != frames {
            return Err(AdtLibError::OutputShape {
                name,
                got: data.len(),
                want: frames,
            });
        }
        let a = &mut acts[c.index()];
        a.clear();
        a.extend_from_slice(data);
    }
    Ok(())
}
