//! Per-instrument drum transcription: kick, snare, toms and cymbals from one signal.
//!
//! Band-passing a drum kit does not isolate its instruments (a floor tom is loudest in the
//! "kick" band, a snare rings up to 10 kHz), so this stage looks at the *shape* of the
//! spectrum and how it moves, the way frame-wise drum transcribers do (Vogl et al. 2017;
//! Southall et al. 2017, ADTLib), with a network small enough to run per hop on one core.
//!
//! # Algorithm
//! 1. **Front end**: [`MelBank`] with [`MelConfig::drums`]: 48 log mel bands of a 2048-point
//!    frame every 10 ms, frame `i` ending 512 samples (11.6 ms) after hop `i`.
//! 2. **Context**: the mel frames `i - past ..= i + future` (7 + 4 in the embedded model), oldest
//!    first, band inside. Frames before the stream are silence (`ln 1e-20`).
//! 3. **Level invariance**: subtract the largest value of the whole context window and clip
//!    at `floor` (-16, about 70 dB below it): a gain change of the input changes nothing
//!    (up to the log floor), so a quiet ghost snare and a loud one look alike.
//!    Models with the *flux* input (file version 2) append, for every pair of consecutive
//!    context frames, the positive difference `max(0, x[t][b] - x[t-1][b])` of those
//!    normalised values (`(past + future) · bands` more inputs): where the spectrum rises.
//!    Models with the *backing* input (file version 2, feature set 2) append a second view:
//!    the mel frames of the backing a separator leaves beside its drum stem (its bass,
//!    vocals and other stems summed), same context, minus the *drum* window's maximum and
//!    clipped to
//!    `[floor, ceil]`, so that a note change of the backing can be told from a hit. Where
//!    there is no backing (a supplied drum stem) the view is silence, as in training.
//!    Models with the *short* view (file version 2, feature set 3) append the same
//!    signal's mel frames from a frame half as long ([`MelConfig::drums_short`]: 1024
//!    points ending at the same sample, so no added latency), same context, normalised by
//!    their own window's maximum and clipped at `floor`: a hit is sharper in time there.
//! 4. **Network**: a multilayer perceptron, ReLU hidden layers, one sigmoid per class. The
//!    input standardisation (training mean and standard deviation) is folded into the first
//!    layer's weights. The weights are trained by `models/drums/train.py` on kits rendered from
//!    free soundfonts and samples (provenance in `models/drums/README.md`) and embedded in the
//!    binary ([`DrumModel::embedded`]). A model file may instead hold a small convolutional
//!    network (file version 4, `models/drums/train_cnn.py`: [`Conv`] layers over time × band,
//!    "valid" in time and zero-padded in band, ReLU, max-pool; the standardisation applied
//!    explicitly, then dense layers), or be an ensemble of such files whose activations are
//!    averaged ([`DrumModel::members`]). The embedded models are perceptrons; the other kinds
//!    run through `render --drum-model FILE` (tried, and not adopted as a default). A *retuned*
//!    file (`"TACTUSDT"`, `models/drums/tta.py`) wraps a perceptron with a list of test-time
//!    retunings ([`Retuning`]): the network also runs on its normalised window with the mel
//!    axis retuned by each ratio (band `b` takes the value at frequency `centre_b / ratio`,
//!    linear between bands, then normalised again as in step 3), and the activations are
//!    averaged: the network is asked about each hit as if the kit were tuned a little lower and
//!    higher (`docs/decisions/0046-drum-test-time-retuning.md`). A short-view model's two views
//!    are retuned alike, each normalised by its own maximum.
//! 5. **Peak picking** per class, causal: hop `i` is an onset of class `c` when the activation
//!    `a_c[i] >= threshold_c`, the detector is *armed*, and at least `min_interval` (50 ms,
//!    docs/design.md) has passed since the last onset of that class. A class is disarmed by an
//!    onset and re-armed when its activation falls below the threshold or below half the peak
//!    it reached since the onset (so two hits whose activations overlap are both found). The
//!    onset's strength is `a_c[i]`. A *staged* file (`"TACTUSD2"`) replaces some classes'
//!    threshold with a [`SecondStage`]: candidates picked at a low threshold, judged a few hops
//!    later by a [`Judge`] (a logistic regression, or a perceptron with one hidden layer)
//!    learnt on activations of kits the network never heard, with the song's earlier candidates
//!    as context. The embedded default judges its snare so, with a perceptron of 32 units
//!    (`docs/decisions/0047-snare-second-stage.md`, `0049-snare-judge-perceptron.md`), and so
//!    does the live model, judging each candidate at its own hop
//!    (`0050-live-snare-second-stage.md`).
//!
//! # Latency
//! Hop `i` is decided once mel frame `i + future` exists:
//! `latency_samples() = lookahead + (future + wait) · hop`, `wait` being a staged file's
//! [`SecondStage::wait`] (0 without one) = 512 + (4 + 1) · 441 = 2,717 samples =
//! **61.6 ms** at 44.1 kHz with the embedded model (its snare's second stage waits one hop);
//! the embedded live model
//! ([`DrumModel::embedded_live`], `future = 1`, its snare's stage waits no hop) gives
//! 512 + 441 = 953 samples = **21.6 ms**
//! (`models/drums/README.md`). Peak picking adds nothing.
//!
//! # Cost
//! One 2048-point real FFT and one network pass (about 82 k multiply-adds with the
//! embedded model; a flux model with the same hidden layers, 1,104 inputs, about 150 k; a
//! short-view model, 1,152 inputs, about 156 k and one more 1024-point FFT) per 10 ms; a
//! retuned file runs its network once per retuning (the embedded models: three times, so
//! about 250 k for the default and 470 k for the live model, plus the retunings' linear
//! interpolation of each view). A staged file's judge runs only on its class's candidates:
//! 10 multiply-adds for a linear judge, `12 · hidden + 1` for a perceptron (385 for the
//! embedded snare's). No allocation after [`DrumTranscriber::new`].
//!
//! [`MelBank`]: crate::melbank::MelBank
//! [`MelConfig::drums`]: crate::melbank::MelConfig::drums
//! [`MelConfig::drums_short`]: crate::melbank::MelConfig::drums_short

mod format;
mod judge;
mod model;
mod picker;
mod retune;
mod transcriber;

pub use crate::nn::{Conv, ConvNet, Layer};
pub use judge::{Judge, SecondStage, JUDGE_INPUTS};
pub use model::{BatchScratch, DrumModel};
pub use retune::Retuning;
pub use transcriber::DrumTranscriber;

use crate::Band;

/// Number of drum classes, in [`Band::ALL`] order: kick, snare, toms, cymbals.
pub const CLASSES: usize = 4;

/// What the transcriber emits for every hop.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct DrumFrame {
    /// Network activation per class (kick, snare, toms, cymbals), 0..1.
    pub activation: [f32; CLASSES],
    /// Onset per class at this hop.
    pub onset: [bool; CLASSES],
}

impl DrumFrame {
    /// The activation of one class.
    pub fn get(&self, band: Band) -> f32 {
        self.activation[band as usize]
    }
}
