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
//! 4. **Network**: a multilayer perceptron, ReLU hidden layers, one sigmoid per class.
//!    The input standardisation (training mean and standard deviation) is folded into the
//!    first layer's weights. The weights are trained by `models/drums/train.py` on kits
//!    rendered from free soundfonts and samples (provenance in `models/drums/README.md`)
//!    and embedded in the binary ([`DrumModel::embedded`]).
//!    A model file may instead hold a small convolutional network (file version 4,
//!    `models/drums/train_cnn.py`: [`Conv`] layers over time × band, "valid" in time and
//!    zero-padded in band, ReLU, max-pool; the standardisation applied explicitly, then
//!    dense layers), or be an ensemble of such files whose activations are averaged
//!    ([`DrumModel::members`]). The embedded models are perceptrons; the other kinds run
//!    through `render --drum-model FILE` (a trial that was not adopted,
//!    `benches/trials/RULE_cnn_ensemble.md`).
//!    A *retuned* file (`"TACTUSDT"`, `models/drums/tta.py`) wraps a perceptron with a list
//!    of test-time retunings ([`Retuning`]): the network also runs on its normalised window
//!    with the mel axis retuned by each ratio (band `b` takes the value at frequency
//!    `centre_b / ratio`, linear between bands, then normalised again as in step 3), and the
//!    activations are averaged: the network is asked about each hit as if the kit were
//!    tuned a little lower and higher (`models/drums/trials/RULE_tta.md`). A short-view
//!    model's two views are retuned alike, each normalised by its own maximum.
//! 5. **Peak picking** per class, causal: hop `i` is an onset of class `c` when the
//!    activation `a_c[i] >= threshold_c`, the detector is *armed*, and at least
//!    `min_interval` (50 ms, docs/design.md) has passed since the last onset of that class. A
//!    class is disarmed by an onset and re-armed when its activation falls below the
//!    threshold or below half the peak it reached since the onset (so two hits whose
//!    activations overlap are both found). The onset's strength is `a_c[i]`.
//!    A *staged* file (`"TACTUSD2"`) replaces some classes' threshold with a
//!    [`SecondStage`]: candidates picked at a low threshold, judged a few hops later by a
//!    [`Judge`] (a logistic regression, or a perceptron with one hidden layer) learnt on
//!    activations of kits the network never heard, with the song's earlier candidates as
//!    context. The embedded default judges its snare so, with a perceptron of 32 units
//!    (`models/drums/trials/RULE_stage2.md`, `RULE_stage2_mlp.md`), and so does the live
//!    model, judging each candidate at its own hop (`RULE_stage2_live.md`).
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

use crate::melbank::{MelBank, MelConfig, LOG_FLOOR};
use crate::mlp::{read_f32s, read_u32, take};
use crate::{Band, ConfigError, HopStage};

/// Number of drum classes, in [`Band::ALL`] order: kick, snare, toms, cymbals.
pub const CLASSES: usize = 4;

/// The embedded model (see `models/drums/README.md`).
static EMBEDDED: &[u8] = include_bytes!("../weights/drums.bin");

/// The embedded low-latency model: one hop of look-ahead context (21.6 ms), for `live`.
static EMBEDDED_LIVE: &[u8] = include_bytes!("../weights/drums_live.bin");

const WHAT: &str = "drum model";

const MAGIC: &[u8; 8] = b"TACTUSDR";

/// An ensemble file: networks whose activations are averaged.
const MAGIC_ENSEMBLE: &[u8; 8] = b"TACTUSDE";

/// A retuned file: one perceptron and its test-time retunings.
const MAGIC_RETUNED: &[u8; 8] = b"TACTUSDT";

/// A file with a second stage for some classes' onsets ([`SecondStage`]) around a model file.
const MAGIC_STAGED: &[u8; 8] = b"TACTUSD2";

/// Features of a [`Judge`]: the four classes' logits, a bias, the four logits minus the
/// song's running mean (shrunk), and the shrink factor.
pub const JUDGE_INPUTS: usize = 2 * CLASSES + 2;

/// The largest number of hidden units a [`Judge`] may have.
const JUDGE_MAX_HIDDEN: usize = 256;

/// The second stage's decision for one class (see [`SecondStage`]): a linear score of the
/// [`JUDGE_INPUTS`] features (a logistic regression), or a perceptron with one hidden layer
/// of ReLU units on them.
#[derive(Clone, Debug, PartialEq)]
pub struct Judge {
    /// The hidden units, each its weights over the features and then its bias; empty for a
    /// linear judge.
    pub hidden: Vec<[f32; JUDGE_INPUTS + 1]>,
    /// The output's weights: over the features for a linear judge, else one per hidden unit.
    pub w: Vec<f32>,
    /// The output's bias (a linear judge's features hold their own bias: 0 there).
    pub bias: f32,
    /// A candidate is an onset where the score reaches this.
    pub cut: f32,
}

impl Judge {
    /// A linear judge: the score is `w · x`.
    pub fn linear(w: [f32; JUDGE_INPUTS], cut: f32) -> Judge {
        Judge {
            hidden: Vec::new(),
            w: w.to_vec(),
            bias: 0.0,
            cut,
        }
    }

    /// The score of the features `x`, in f64: `w · x` for a linear judge, else
    /// `bias + Σ_h w_h · max(0, hidden_h · x + hidden bias_h)`.
    pub fn score(&self, x: &[f64; JUDGE_INPUTS]) -> f64 {
        let dot = |w: &[f32]| -> f64 { w.iter().zip(x).map(|(&w, &x)| w as f64 * x).sum() };
        if self.hidden.is_empty() {
            return dot(&self.w);
        }
        let mut z = self.bias as f64;
        for (unit, &w) in self.hidden.iter().zip(&self.w) {
            let h = dot(&unit[..JUDGE_INPUTS]) + unit[JUDGE_INPUTS] as f64;
            z += w as f64 * h.max(0.0);
        }
        z
    }
}

/// A second stage for some classes' onsets, learnt on *out-of-family* activations (each
/// training kit family scored by a network that never heard it, `models/drums/trials/lofo/
/// stage2.py`; rule `models/drums/trials/RULE_stage2.md`): on an unheard kit the network's
/// activations are biased in a way its own training kits do not show, and this stage has
/// seen how.
///
/// For a judged class `c`: the candidates are the onsets of a [`Picker`] at threshold
/// `low`; candidate hop `i` waits `wait` hops, then its features are the logits `l` of the
/// four classes' largest activation over hops `i ..= i + wait`, a bias 1, the same `l` minus
/// the mean of `l` over the song's earlier candidates of class `c`, times `m / (m + shrink)`
/// (`m`: how many there were; the mean is 0 when `m = 0`), and that factor. Logits are
/// taken of the activation clamped to [1e-4, 0.9999]. The candidate is an onset where
/// the [`Judge`]'s score reaches its `cut`. Causal; every class's output is delayed by
/// `wait` hops, so the transcriber's latency grows by `wait` hops. Classes without a judge
/// keep the model's own picker.
#[derive(Clone, Debug, PartialEq)]
pub struct SecondStage {
    /// Hops a candidate waits before it is judged.
    pub wait: usize,
    /// The candidates' picker threshold.
    pub low: f32,
    /// The running mean's shrink count.
    pub shrink: f32,
    /// Per class: its judge, or `None` for the model's own picker.
    pub judges: [Option<Judge>; CLASSES],
}

/// The sample rate whose drum front end ([`MelConfig::drums`]: 20 Hz to 16 kHz) the
/// retunings are computed for: the models are trained at it (`models/drums/train.py`'s
/// `F_LO`, `F_HI`).
const RETUNE_RATE: u32 = 44_100;

/// One test-time retuning of the mel axis (see the module docs, step 4): band `b` of the
/// retuned window interpolates the bands around the one whose centre is `centre_b / ratio`
/// on the drum front end's mel scale (clamped to the first and last band).
#[derive(Clone, Debug, PartialEq)]
pub struct Retuning {
    /// The frequency ratio (1: the window as it is).
    pub ratio: f32,
    /// Per band: the lower source band.
    lower: Vec<usize>,
    /// Per band: the weight of the band above `lower`.
    frac: Vec<f32>,
}

impl Retuning {
    /// The retuning by `ratio` of `bands` mel bands between 20 Hz and 16 kHz.
    pub fn new(ratio: f32, bands: usize) -> Retuning {
        let (mel, hz) = (crate::melbank::hz_to_mel, crate::melbank::mel_to_hz);
        let cfg = MelConfig::drums(RETUNE_RATE);
        let f_hi = cfg.f_hi.min(0.45 * RETUNE_RATE as f32);
        let (lo, hi) = (mel(cfg.f_lo as f64), mel(f_hi as f64));
        let step = (hi - lo) / (bands + 1) as f64;
        let centres: Vec<f64> = (1..=bands).map(|j| lo + step * j as f64).collect();
        let r = ratio as f64;
        let last = bands.saturating_sub(1);
        let (mut lower, mut frac) = (Vec::with_capacity(bands), Vec::with_capacity(bands));
        for &c in &centres {
            let x = mel(hz(c) / r);
            // Fractional band index of x among the centres, clamped to the ends.
            let pos = if bands < 2 || x <= centres[0] {
                0.0
            } else if x >= centres[last] {
                last as f64
            } else {
                let j = centres.partition_point(|&m| m <= x) - 1;
                j as f64 + (x - centres[j]) / (centres[j + 1] - centres[j])
            };
            let i0 = (pos.floor() as usize).min(last);
            lower.push(i0);
            frac.push((pos - i0 as f64) as f32);
        }
        Retuning { ratio, lower, frac }
    }

    /// Whether this retuning leaves the window as it is.
    pub fn is_identity(&self) -> bool {
        self.ratio == 1.0
    }

    /// Retunes a normalised window (`frames × bands`, band inside) into `out` and normalises
    /// it again: its maximum subtracted, clipped at `floor`.
    pub fn apply(&self, window: &[f32], floor: f32, out: &mut [f32]) {
        let bands = self.lower.len();
        let Some(last) = bands.checked_sub(1) else {
            return;
        };
        let mut m = f32::NEG_INFINITY;
        for (src, dst) in window.chunks_exact(bands).zip(out.chunks_exact_mut(bands)) {
            for ((o, &i0), &f) in dst.iter_mut().zip(&self.lower).zip(&self.frac) {
                let a = src[i0];
                let b = src[(i0 + 1).min(last)];
                *o = a + (b - a) * f;
                m = m.max(*o);
            }
        }
        for o in out[..window.len()].iter_mut() {
            *o = (*o - m).max(floor);
        }
    }
}

/// One dense layer, `out = W · in + b`, `W` row-major `[n_out][n_in]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Layer {
    /// Inputs.
    pub n_in: usize,
    /// Outputs.
    pub n_out: usize,
    /// Weights, `n_out × n_in`, row-major.
    pub w: Vec<f32>,
    /// Biases, `n_out`.
    pub b: Vec<f32>,
}

/// A trained transcription network and its peak-picking thresholds.
#[derive(Clone, Debug, PartialEq)]
pub struct DrumModel {
    /// Mel bands per frame.
    pub bands: usize,
    /// Context frames before the current one.
    pub past: usize,
    /// Context frames after the current one.
    pub future: usize,
    /// Relative log floor (step 3).
    pub floor: f32,
    /// Whether the input also carries the positive first difference of the frames (step 3).
    pub flux: bool,
    /// `Some(ceil)`: the input also carries a second view, the backing beside the drum stem
    /// (step 3), normalised by the drum window's maximum and clipped to `[floor, ceil]`.
    pub backing: Option<f32>,
    /// Whether the input also carries the short view (file version 2, feature set 3): the
    /// same signal's mel frames from a frame half as long ([`MelConfig::drums_short`]), same
    /// context, normalised by their own window's maximum and clipped at `floor` (step 3).
    pub short: bool,
    /// Convolutional front layers (file version 4), run before the dense ones; `None` for a
    /// perceptron.
    pub conv: Option<ConvNet>,
    /// Dense layers; ReLU between them, sigmoid after the last.
    pub layers: Vec<Layer>,
    /// Activation threshold per class.
    pub thresholds: [f32; CLASSES],
    /// Further networks of an ensemble file, on the same input (same bands, context, floor
    /// and feature set): the activations are the mean of this network's and theirs. Their
    /// own thresholds are unused; empty for a single network.
    pub members: Vec<DrumModel>,
    /// Test-time retunings of a retuned file (`"TACTUSDT"`): the activations are the mean
    /// of the network's on each retuned window. Empty: one pass on the window as it is.
    pub retunings: Vec<Retuning>,
    /// The second stage of a staged file (`"TACTUSD2"`); `None`: every class is picked by
    /// its threshold alone.
    pub stage: Option<SecondStage>,
}

/// One convolution over (time × band) maps, "valid" in time and "same" (zero-padded by
/// `kb / 2` on each side) in band, then ReLU, then a max-pool of `pool_t × pool_b`
/// (incomplete windows at the end dropped).
#[derive(Clone, Debug, PartialEq)]
pub struct Conv {
    /// Output channels.
    pub c_out: usize,
    /// Input channels.
    pub c_in: usize,
    /// Kernel length in time (frames).
    pub kt: usize,
    /// Kernel width in band (odd).
    pub kb: usize,
    /// Pooling in time.
    pub pool_t: usize,
    /// Pooling in band.
    pub pool_b: usize,
    /// Weights `[c_out][c_in][kt][kb]`.
    pub w: Vec<f32>,
    /// Biases, `c_out`.
    pub b: Vec<f32>,
}

impl Conv {
    /// Output shape `(channels, frames, bands)` after pooling, for an input of
    /// `t × bands` per channel; `None` when the input is too short for the kernel or pool.
    pub fn out_shape(&self, t: usize, bands: usize) -> Option<(usize, usize, usize)> {
        let tc = t.checked_sub(self.kt - 1)?;
        let (to, bo) = (tc / self.pool_t, bands / self.pool_b);
        (to > 0 && bo > 0).then_some((self.c_out, to, bo))
    }

    /// Runs the layer on `x` (`c_in × t × bands`), using `tmp` (at least
    /// `c_out · (t - kt + 1) · bands`) for the maps before pooling; writes the pooled maps to
    /// `out`.
    pub fn run(&self, x: &[f32], t: usize, bands: usize, tmp: &mut [f32], out: &mut [f32]) {
        let tc = t + 1 - self.kt;
        let pad = self.kb / 2;
        let maps = &mut tmp[..self.c_out * tc * bands];
        for (o, map) in maps.chunks_exact_mut(tc * bands).enumerate() {
            map.fill(self.b[o]);
            for i in 0..self.c_in {
                let xi = &x[i * t * bands..(i + 1) * t * bands];
                for dt in 0..self.kt {
                    for db in 0..self.kb {
                        let w = self.w[((o * self.c_in + i) * self.kt + dt) * self.kb + db];
                        // Output band j reads input band j + db - pad, when inside.
                        let j0 = pad.saturating_sub(db);
                        let j1 = (bands + pad).saturating_sub(db).min(bands);
                        for tt in 0..tc {
                            let row = &mut map[tt * bands + j0..tt * bands + j1];
                            let src0 = (tt + dt) * bands + j0 + db - pad;
                            let src = &xi[src0..src0 + (j1 - j0)];
                            for (r, &v) in row.iter_mut().zip(src) {
                                *r += w * v;
                            }
                        }
                    }
                }
            }
        }
        let (_, to, bo) = self.out_shape(t, bands).expect("shape checked at load");
        for o in 0..self.c_out {
            let map = &maps[o * tc * bands..(o + 1) * tc * bands];
            for a in 0..to {
                for c in 0..bo {
                    let mut m = 0f32; // ReLU, then max: the max of 0 and the window
                    for pt in 0..self.pool_t {
                        let r = &map[(a * self.pool_t + pt) * bands + c * self.pool_b..];
                        for &v in &r[..self.pool_b] {
                            m = m.max(v);
                        }
                    }
                    out[(o * to + a) * bo + c] = m;
                }
            }
        }
    }
}

/// The convolutional part of a version-4 model: the input standardisation (not foldable
/// into weights shared across positions) and the layers.
#[derive(Clone, Debug, PartialEq)]
pub struct ConvNet {
    /// Training mean per input value (`window_len`).
    pub mean: Vec<f32>,
    /// Training standard deviation per input value.
    pub std: Vec<f32>,
    /// Layers, in order.
    pub layers: Vec<Conv>,
}

impl DrumModel {
    /// The model embedded in the binary.
    pub fn embedded() -> DrumModel {
        // The embedded file is checked by a unit test, so this cannot fail in a build
        // whose tests pass.
        Self::from_bytes(EMBEDDED).expect("embedded drum model is valid")
    }

    /// The embedded low-latency model: the same network shape with one frame of future
    /// context instead of four, so a hit is decided 512 + 441 samples = 21.6 ms after it
    /// at 44.1 kHz (issue 10's live budget is 30 ms), at some cost in accuracy
    /// (`models/drums/README.md`).
    pub fn embedded_live() -> DrumModel {
        // Checked by a unit test, like `embedded`.
        Self::from_bytes(EMBEDDED_LIVE).expect("embedded live drum model is valid")
    }

    /// Parses the binary format written by `models/drums/train.py`:
    /// `"TACTUSDR"`, then little-endian u32 `version (1 or 2), bands, past, future,
    /// classes = 4, layers`, f32 `floor`, in version 2 only a u32 input feature set
    /// (0: mel, 1: mel + flux, 2: mel + backing, followed by the backing's f32 `ceil`),
    /// then per layer u32 `n_in, n_out`, f32 `w[n_out·n_in],
    /// b[n_out]`, and f32 `thresholds[4]`.
    ///
    /// An ensemble file (`models/drums/train_cnn.py --combine`) is `"TACTUSDE"`, u32
    /// `version = 1, members (2..=4)`, per member a u32 byte length and a whole single-model
    /// file as above, then f32 `thresholds[4]` for the averaged activations.
    pub fn from_bytes(mut bytes: &[u8]) -> Result<DrumModel, ConfigError> {
        if bytes.starts_with(MAGIC_ENSEMBLE) {
            return Self::ensemble_from_bytes(&bytes[8..]);
        }
        if bytes.starts_with(MAGIC_RETUNED) {
            return Self::retuned_from_bytes(&bytes[8..]);
        }
        if bytes.starts_with(MAGIC_STAGED) {
            return Self::staged_from_bytes(&bytes[8..]);
        }
        let b = &mut bytes;
        if take(b, 8, WHAT)? != MAGIC {
            return Err(ConfigError::invalid(
                "drum model",
                "not a Tactus drum model",
            ));
        }
        let version = read_u32(b, WHAT)?;
        if !(1..=2).contains(&version) && version != 4 {
            return Err(ConfigError::invalid(
                "drum model",
                format!("version {version} is not supported (1, 2 and 4 are)"),
            ));
        }
        let bands = read_u32(b, WHAT)? as usize;
        let past = read_u32(b, WHAT)? as usize;
        let future = read_u32(b, WHAT)? as usize;
        let classes = read_u32(b, WHAT)? as usize;
        let n_layers = read_u32(b, WHAT)? as usize;
        let floor = read_f32s(b, 1, WHAT)?[0];
        let (flux, backing, short) = if version == 2 {
            match read_u32(b, WHAT)? {
                0 => (false, None, false),
                1 => (true, None, false),
                3 => (false, None, true),
                2 => {
                    let ceil = read_f32s(b, 1, WHAT)?[0];
                    if !(ceil.is_finite() && ceil > floor) {
                        return Err(ConfigError::invalid(
                            "drum model",
                            "the backing's ceiling must be finite and above the floor",
                        ));
                    }
                    (false, Some(ceil), false)
                }
                f => {
                    return Err(ConfigError::invalid(
                        "drum model",
                        format!(
                            "input feature set {f} is not supported (0: mel, 1: mel + flux, 2: mel + backing, 3: mel + short view)"
                        ),
                    ))
                }
            }
        } else {
            (false, None, false)
        };
        if classes != CLASSES {
            return Err(ConfigError::invalid("drum model", "must have 4 classes"));
        }
        if !(1..=512).contains(&bands) || past > 64 || future > 8 || !(1..=8).contains(&n_layers) {
            return Err(ConfigError::invalid("drum model", "implausible shape"));
        }
        let frames = past + 1 + future;
        let mut n_in0 = bands * frames
            + if flux { bands * (past + future) } else { 0 }
            + if backing.is_some() || short {
                bands * frames
            } else {
                0
            };
        let conv = if version == 4 {
            let (net, flat) = read_conv(b, frames, bands)?;
            n_in0 = flat;
            Some(net)
        } else {
            None
        };
        let layers = crate::mlp::read_layers(b, n_layers, n_in0, WHAT)?;
        let expect = layers.last().map_or(n_in0, |l| l.n_out);
        if expect != CLASSES {
            return Err(ConfigError::invalid(
                "drum model",
                "last layer must have 4 outputs",
            ));
        }
        let t = read_f32s(b, CLASSES, WHAT)?;
        if !b.is_empty() {
            return Err(ConfigError::invalid("drum model", "trailing bytes"));
        }
        Ok(DrumModel {
            bands,
            past,
            future,
            floor,
            flux,
            backing,
            short,
            conv,
            layers,
            thresholds: [t[0], t[1], t[2], t[3]],
            members: Vec::new(),
            retunings: Vec::new(),
            stage: None,
        })
    }

    /// `"TACTUSDT"`, u32 `version = 1, n (2..=8)`, f32 `ratios[n]` (each in [0.5, 2]), u32
    /// byte length and a whole single-model file of a perceptron on mel frames (feature set
    /// 0, or 3 with the short view: both views are retuned by the same ratio, each
    /// normalised again by its own maximum), then f32 `thresholds[4]` for the averaged
    /// activations.
    fn retuned_from_bytes(mut bytes: &[u8]) -> Result<DrumModel, ConfigError> {
        let b = &mut bytes;
        let n = read_wrapper_head(
            b,
            "retuned-file",
            2..=8,
            "a retuned file has 2 to 8 retunings",
        )?;
        let ratios = read_f32s(b, n, WHAT)?;
        if !ratios.iter().all(|r| (0.5..=2.0).contains(r)) {
            return Err(ConfigError::invalid(
                "drum model",
                "retuning ratios must lie in [0.5, 2]",
            ));
        }
        let mut model = read_single(b, "a retuned file must hold a single network")?;
        if model.flux || model.backing.is_some() || model.conv.is_some() || model.bands < 2 {
            return Err(ConfigError::invalid(
                "drum model",
                "only a perceptron on mel frames (and its short view) can be retuned",
            ));
        }
        let t = read_f32s(b, CLASSES, WHAT)?;
        if !b.is_empty() {
            return Err(ConfigError::invalid("drum model", "trailing bytes"));
        }
        model.retunings = ratios
            .iter()
            .map(|&r| Retuning::new(r, model.bands))
            .collect();
        model.thresholds = [t[0], t[1], t[2], t[3]];
        Ok(model)
    }

    /// `"TACTUSD2"`, u32 `version (1 or 2), wait (0..=8)`, f32 `low` (in (0, 1)), f32
    /// `shrink` (> 0), u32 `classes` (a bit mask, bit `c` for class `c`, 1..=15), per class
    /// of the mask in class order its [`Judge`], then u32 byte length and a whole model file
    /// of any other kind ([`SecondStage`]). A version-1 judge is linear: f32 `w[10], cut`. A
    /// version-2 judge is u32 `hidden` (0..=256), then for 0 f32 `w[10], cut`, else f32
    /// `hidden × (w[10], bias)`, f32 `out[hidden], out_bias, cut`.
    fn staged_from_bytes(mut bytes: &[u8]) -> Result<DrumModel, ConfigError> {
        let b = &mut bytes;
        let (version, wait) = read_versioned_head(
            b,
            "staged-file",
            2,
            0..=8,
            "a second stage waits 0 to 8 hops",
        )?;
        let head = read_f32s(b, 2, WHAT)?;
        let (low, shrink) = (head[0], head[1]);
        if !(low > 0.0 && low < 1.0 && shrink > 0.0 && shrink.is_finite()) {
            return Err(ConfigError::invalid(
                "drum model",
                "a second stage needs a threshold in (0, 1) and a positive shrink count",
            ));
        }
        let mask = read_u32(b, WHAT)?;
        if !(1..16).contains(&mask) {
            return Err(ConfigError::invalid(
                "drum model",
                "a second stage judges 1 to 4 classes (mask 1..=15)",
            ));
        }
        let mut judges: [Option<Judge>; CLASSES] = Default::default();
        for (c, judge) in judges.iter_mut().enumerate() {
            if mask & (1 << c) != 0 {
                *judge = Some(read_judge(b, version)?);
            }
        }
        let len = read_u32(b, WHAT)? as usize;
        let inner = take(b, len, WHAT)?;
        if !b.is_empty() {
            return Err(ConfigError::invalid("drum model", "trailing bytes"));
        }
        if inner.starts_with(MAGIC_STAGED) {
            return Err(ConfigError::invalid(
                "drum model",
                "a staged file cannot hold another staged file",
            ));
        }
        let mut model = DrumModel::from_bytes(inner)?;
        model.stage = Some(SecondStage {
            wait,
            low,
            shrink,
            judges,
        });
        Ok(model)
    }

    fn ensemble_from_bytes(mut bytes: &[u8]) -> Result<DrumModel, ConfigError> {
        let b = &mut bytes;
        let n = read_wrapper_head(b, "ensemble", 2..=4, "an ensemble has 2 to 4 members")?;
        let mut models = Vec::with_capacity(n);
        for _ in 0..n {
            models.push(read_single(
                b,
                "an ensemble member is not a single network",
            )?);
        }
        let t = read_f32s(b, CLASSES, WHAT)?;
        if !b.is_empty() {
            return Err(ConfigError::invalid("drum model", "trailing bytes"));
        }
        let mut first = models.remove(0);
        let same = |m: &DrumModel| {
            (m.bands, m.past, m.future, m.flux, m.backing, m.short)
                == (
                    first.bands,
                    first.past,
                    first.future,
                    first.flux,
                    first.backing,
                    first.short,
                )
                && m.floor == first.floor
        };
        if !models.iter().all(same) {
            return Err(ConfigError::invalid(
                "drum model",
                "ensemble members must share bands, context, floor and input features",
            ));
        }
        first.members = models;
        first.thresholds = [t[0], t[1], t[2], t[3]];
        Ok(first)
    }

    /// Scratch values [`DrumModel::forward`] needs in each of its three buffers.
    pub fn scratch_len(&self) -> usize {
        let own = self.own_scratch_len();
        self.members
            .iter()
            .map(Self::own_scratch_len)
            .fold(own, usize::max)
    }

    fn own_scratch_len(&self) -> usize {
        let mut widest = self.input_len().max(CLASSES);
        for l in &self.layers {
            widest = widest.max(l.n_in).max(l.n_out);
        }
        if let Some(net) = &self.conv {
            let (mut t, mut bands) = (self.past + 1 + self.future, self.bands);
            for c in &net.layers {
                widest = widest.max(c.c_out * (t + 1 - c.kt) * bands);
                let (_, to, bo) = c.out_shape(t, bands).expect("checked at load");
                (t, bands) = (to, bo);
            }
        }
        widest
    }

    /// Mel values in the context window: `bands · (past + 1 + future)`.
    pub fn window_len(&self) -> usize {
        self.bands * (self.past + 1 + self.future)
    }

    /// Values in one network input: the window, plus `bands · (past + future)` flux values
    /// if [`DrumModel::flux`], plus the second view's window if [`DrumModel::backing`] or
    /// [`DrumModel::short`].
    pub fn input_len(&self) -> usize {
        let flux = if self.flux {
            self.bands * (self.past + self.future)
        } else {
            0
        };
        let second = if self.has_second_view() {
            self.window_len()
        } else {
            0
        };
        self.window_len() + flux + second
    }

    /// Whether the input carries a second view of mel frames: the backing or the short view.
    pub fn has_second_view(&self) -> bool {
        self.backing.is_some() || self.short
    }

    /// Step 3 of the module docs: `window` holds `past + 1 + future` mel frames
    /// ([`DrumModel::window_len`] values), oldest first; writes the network input
    /// ([`DrumModel::input_len`] values).
    pub fn assemble(&self, window: &[f32], input: &mut [f32]) {
        self.assemble_window(window, input);
    }

    /// [`DrumModel::assemble`]; returns the window's maximum it subtracted.
    fn assemble_window(&self, window: &[f32], input: &mut [f32]) -> f32 {
        let m = window.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        let n = window.len();
        let (x, d) = input.split_at_mut(n);
        for (o, &v) in x.iter_mut().zip(window) {
            *o = (v - m).max(self.floor);
        }
        if self.flux {
            let (prev, next) = (&x[..n - self.bands], &x[self.bands..]);
            for ((o, &p), &q) in d.iter_mut().zip(prev).zip(next) {
                *o = (q - p).max(0.0);
            }
        }
        m
    }

    /// [`DrumModel::assemble`] for a model with the backing view: `backing` holds the
    /// backing's mel frames of the same hops as `window`; its normalised values (the drum
    /// window's maximum subtracted, clipped to `[floor, ceil]`) follow the drum view's. For
    /// any other model `backing` is ignored.
    ///
    /// For a model with the short view, `backing` holds the short view's frames instead;
    /// they are normalised by their own window's maximum and clipped at `floor`.
    pub fn assemble_with_backing(&self, window: &[f32], backing: &[f32], input: &mut [f32]) {
        let m = self.assemble_window(window, input);
        let n = window.len();
        if self.short {
            let ms = backing.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            for (o, &v) in input[n..2 * n].iter_mut().zip(backing) {
                *o = (v - ms).max(self.floor);
            }
            return;
        }
        let Some(ceil) = self.backing else {
            return;
        };
        for (o, &v) in input[n..2 * n].iter_mut().zip(backing) {
            *o = (v - m).clamp(self.floor, ceil);
        }
    }

    /// Runs the network on one assembled input; `a`, `b` and `c` are scratch buffers of
    /// [`DrumModel::scratch_len`] values. Returns the activations: for an ensemble, the mean
    /// of its members' (this network's first, then [`DrumModel::members`] in order).
    pub fn forward(
        &self,
        input: &[f32],
        a: &mut [f32],
        b: &mut [f32],
        c: &mut [f32],
    ) -> [f32; CLASSES] {
        if !self.retunings.is_empty() {
            // A perceptron on mel frames and perhaps the short view (checked at load): `c`
            // is free for the retuned input, each view retuned and normalised on its own.
            let (w, rest) = c.split_at_mut(input.len());
            let view = self.window_len();
            let mut out = [0f32; CLASSES];
            for r in &self.retunings {
                let o = if r.is_identity() {
                    self.forward_one(input, a, b, rest)
                } else {
                    for (src, dst) in input.chunks_exact(view).zip(w.chunks_exact_mut(view)) {
                        r.apply(src, self.floor, dst);
                    }
                    self.forward_one(w, a, b, rest)
                };
                for (x, y) in out.iter_mut().zip(o) {
                    *x += y;
                }
            }
            let n = self.retunings.len() as f32;
            return out.map(|x| x / n);
        }
        let mut out = self.forward_one(input, a, b, c);
        if self.members.is_empty() {
            return out;
        }
        for m in &self.members {
            let o = m.forward_one(input, a, b, c);
            for (x, y) in out.iter_mut().zip(o) {
                *x += y;
            }
        }
        let n = (1 + self.members.len()) as f32;
        out.map(|x| x / n)
    }

    /// This network's activations alone (members ignored).
    fn forward_one(
        &self,
        input: &[f32],
        a: &mut [f32],
        b: &mut [f32],
        c: &mut [f32],
    ) -> [f32; CLASSES] {
        let src = match &self.conv {
            None => crate::mlp::run_layers(&self.layers, input, a, b),
            Some(net) => {
                let n = input.len();
                for (((o, &x), &m), &s) in c[..n].iter_mut().zip(input).zip(&net.mean).zip(&net.std)
                {
                    *o = (x - m) / s;
                }
                let (mut t, mut bands) = (self.past + 1 + self.future, self.bands);
                let (mut src, mut dst) = (&mut *c, &mut *b);
                for l in &net.layers {
                    l.run(src, t, bands, a, dst);
                    let (_, to, bo) = l.out_shape(t, bands).expect("checked at load");
                    (t, bands) = (to, bo);
                    std::mem::swap(&mut src, &mut dst);
                }
                let flat = self.layers[0].n_in;
                // `a` is free again: the dense layers take their input from it.
                let (x, _) = src.split_at(flat);
                crate::mlp::run_layers(&self.layers, x, a, dst)
            }
        };
        let mut out = [0f32; CLASSES];
        for (o, &z) in out.iter_mut().zip(src.iter()) {
            *o = 1.0 / (1.0 + (-z).exp());
        }
        out
    }
}

/// The head of a wrapper file (ensemble, retuned) after its magic: u32 `version = 1`, then u32
/// `n` in `counts`; returns `n`.
fn read_wrapper_head(
    b: &mut &[u8],
    kind: &str,
    counts: std::ops::RangeInclusive<usize>,
    bad_count: &'static str,
) -> Result<usize, ConfigError> {
    read_versioned_head(b, kind, 1, counts, bad_count).map(|(_, n)| n)
}

/// [`read_wrapper_head`] for a wrapper with versions 1 to `latest`: (version, count).
fn read_versioned_head(
    b: &mut &[u8],
    kind: &str,
    latest: u32,
    counts: std::ops::RangeInclusive<usize>,
    bad_count: &'static str,
) -> Result<(u32, usize), ConfigError> {
    let version = read_u32(b, WHAT)?;
    if !(1..=latest).contains(&version) {
        let known = if latest == 1 {
            "1 is".to_string()
        } else {
            format!("1 to {latest} are")
        };
        return Err(ConfigError::invalid(
            "drum model",
            format!("{kind} version {version} is not supported ({known})"),
        ));
    }
    let n = read_u32(b, WHAT)? as usize;
    if !counts.contains(&n) {
        return Err(ConfigError::invalid("drum model", bad_count));
    }
    Ok((version, n))
}

/// One [`Judge`] of a staged file of `version` (see `DrumModel::staged_from_bytes`).
fn read_judge(b: &mut &[u8], version: u32) -> Result<Judge, ConfigError> {
    let hidden = if version == 1 {
        0
    } else {
        read_u32(b, WHAT)? as usize
    };
    if hidden == 0 {
        let v = read_f32s(b, JUDGE_INPUTS + 1, WHAT)?;
        let mut w = [0f32; JUDGE_INPUTS];
        w.copy_from_slice(&v[..JUDGE_INPUTS]);
        return Ok(Judge::linear(w, v[JUDGE_INPUTS]));
    }
    if hidden > JUDGE_MAX_HIDDEN {
        return Err(ConfigError::invalid(
            "drum model",
            format!("a judge has at most {JUDGE_MAX_HIDDEN} hidden units"),
        ));
    }
    let units = read_f32s(b, hidden * (JUDGE_INPUTS + 1), WHAT)?;
    let out = read_f32s(b, hidden + 2, WHAT)?;
    Ok(Judge {
        hidden: units
            .chunks_exact(JUDGE_INPUTS + 1)
            .map(|u| std::array::from_fn(|k| u[k]))
            .collect(),
        w: out[..hidden].to_vec(),
        bias: out[hidden],
        cut: out[hidden + 1],
    })
}

/// A wrapped single-network file: u32 byte length, then the file (`"TACTUSDR"`).
fn read_single(b: &mut &[u8], not_single: &'static str) -> Result<DrumModel, ConfigError> {
    let len = read_u32(b, WHAT)? as usize;
    let one = take(b, len, WHAT)?;
    if !one.starts_with(MAGIC) {
        return Err(ConfigError::invalid("drum model", not_single));
    }
    DrumModel::from_bytes(one)
}

/// Reads the convolutional part of a version-4 file (after the floor): u32 layer count,
/// f32 mean and std (`frames · bands` each, every std > 0), then per layer u32 `c_out, c_in,
/// kt, kb, pool_t, pool_b` and f32 `w`, `b`. Returns the layers and the length of their
/// flattened output.
fn read_conv(b: &mut &[u8], frames: usize, bands: usize) -> Result<(ConvNet, usize), ConfigError> {
    let n = read_u32(b, WHAT)? as usize;
    if !(1..=4).contains(&n) {
        return Err(ConfigError::invalid(
            "drum model",
            "implausible conv layer count",
        ));
    }
    let mean = read_f32s(b, frames * bands, WHAT)?;
    let std = read_f32s(b, frames * bands, WHAT)?;
    if std.iter().any(|&s| s <= 0.0) {
        return Err(ConfigError::invalid(
            "drum model",
            "a standard deviation is not positive",
        ));
    }
    let (mut ch, mut t, mut bd) = (1usize, frames, bands);
    let mut layers = Vec::with_capacity(n);
    for _ in 0..n {
        let mut d = [0usize; 6];
        for v in &mut d {
            *v = read_u32(b, WHAT)? as usize;
        }
        let [c_out, c_in, kt, kb, pool_t, pool_b] = d;
        let sane = c_in == ch
            && (1..=64).contains(&c_out)
            && (1..=t).contains(&kt)
            && kb % 2 == 1
            && kb <= bd
            && (1..=4).contains(&pool_t)
            && (1..=4).contains(&pool_b);
        if !sane {
            return Err(ConfigError::invalid(
                "drum model",
                "conv layer shapes do not chain",
            ));
        }
        let w = read_f32s(b, c_out * c_in * kt * kb, WHAT)?;
        let bias = read_f32s(b, c_out, WHAT)?;
        let l = Conv {
            c_out,
            c_in,
            kt,
            kb,
            pool_t,
            pool_b,
            w,
            b: bias,
        };
        let (c2, t2, b2) = l
            .out_shape(t, bd)
            .ok_or_else(|| ConfigError::invalid("drum model", "conv layer shapes do not chain"))?;
        (ch, t, bd) = (c2, t2, b2);
        layers.push(l);
    }
    Ok((ConvNet { mean, std, layers }, ch * t * bd))
}

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

/// Causal peak picker of one class (step 5).
#[derive(Clone, Copy, Debug)]
struct Picker {
    armed: bool,
    peak: f32,
    last: Option<usize>,
}

impl Picker {
    const NEW: Picker = Picker {
        armed: true,
        peak: 0.0,
        last: None,
    };

    fn step(&mut self, i: usize, a: f32, threshold: f32, min_gap: usize) -> bool {
        if !self.armed {
            self.peak = self.peak.max(a);
            if a < threshold || a < 0.5 * self.peak {
                self.armed = true;
            }
        }
        let gap_ok = self.last.is_none_or(|l| i - l >= min_gap);
        if self.armed && a >= threshold && gap_ok {
            self.armed = false;
            self.peak = a;
            self.last = Some(i);
            return true;
        }
        false
    }
}

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

struct Core {
    model: DrumModel,
    /// The last `past + 1 + future` mel frames, oldest first (shifted by hand).
    window: Vec<f32>,
    /// The second view's frames of the same hops: the backing's (silence without a
    /// backing) or the short view's.
    second_window: Vec<f32>,
    input: Vec<f32>,
    a: Vec<f32>,
    b: Vec<f32>,
    c: Vec<f32>,
    pickers: [Picker; CLASSES],
    min_gap: usize,
    /// Mel frames received.
    frames: usize,
    /// Hops whose activations are computed.
    next: usize,
    /// The second stage's state, for a staged model.
    staged: Option<Staged>,
}

/// The running state of a [`SecondStage`].
struct Staged {
    /// The activations of the last `wait + 1` hops, hop `i` at `i % (wait + 1)`.
    ring: Vec<[f32; CLASSES]>,
    /// The candidates' pickers (threshold `low`).
    low: [Picker; CLASSES],
    /// Per judged class: the sum of its earlier candidates' logits, and how many there were.
    sums: [[f64; CLASSES]; CLASSES],
    seen: [usize; CLASSES],
    /// Hops emitted.
    emitted: usize,
}

/// The logit of an activation clamped to [1e-4, 0.9999] (`stage2.py`'s `lg`, in f32 as
/// numpy computes it on f32 activations).
fn logit(a: f32) -> f32 {
    let p = a.clamp(1e-4, 0.9999);
    (p / (1.0 - p)).ln()
}

impl Staged {
    fn new(stage: &SecondStage) -> Staged {
        Staged {
            ring: vec![[0.0; CLASSES]; stage.wait + 1],
            low: [Picker::NEW; CLASSES],
            sums: [[0.0; CLASSES]; CLASSES],
            seen: [0; CLASSES],
            emitted: 0,
        }
    }

    /// Back to the start of a stream, keeping the ring's memory.
    fn clear(&mut self) {
        self.ring.fill([0.0; CLASSES]);
        self.low = [Picker::NEW; CLASSES];
        self.sums = [[0.0; CLASSES]; CLASSES];
        self.seen = [0; CLASSES];
        self.emitted = 0;
    }

    /// Decides hop `j`, whose activations and those of the hops after it up to `end`
    /// (exclusive, at most `wait` more) are in the ring; emits it.
    #[allow(clippy::too_many_arguments)]
    fn decide(
        &mut self,
        stage: &SecondStage,
        pickers: &mut [Picker; CLASSES],
        thresholds: &[f32; CLASSES],
        min_gap: usize,
        j: usize,
        end: usize,
        emit: &mut dyn FnMut(usize, DrumFrame),
    ) {
        let k = self.ring.len();
        let act = self.ring[j % k];
        let mut f = DrumFrame {
            activation: act,
            onset: [false; CLASSES],
        };
        for c in 0..CLASSES {
            let Some(judge) = &stage.judges[c] else {
                f.onset[c] = pickers[c].step(j, act[c], thresholds[c], min_gap);
                continue;
            };
            if !self.low[c].step(j, act[c], stage.low, min_gap) {
                continue;
            }
            let mut peak = act;
            for h in j + 1..end {
                for (p, &x) in peak.iter_mut().zip(&self.ring[h % k]) {
                    *p = p.max(x);
                }
            }
            let l = peak.map(|x| logit(x) as f64);
            let m = self.seen[c] as f64;
            let sh = m / (m + stage.shrink as f64);
            let mut x = [0f64; JUDGE_INPUTS];
            x[CLASSES] = 1.0;
            x[2 * CLASSES + 1] = sh;
            for (i, &li) in l.iter().enumerate() {
                let mean = if self.seen[c] > 0 {
                    self.sums[c][i] / m
                } else {
                    0.0
                };
                x[i] = li;
                x[CLASSES + 1 + i] = sh * (li - mean);
                self.sums[c][i] += li;
            }
            self.seen[c] += 1;
            let z = judge.score(&x);
            f.onset[c] = z >= judge.cut as f64;
        }
        self.emitted = j + 1;
        emit(j, f);
    }
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
            debug_assert_eq!(i, self.next);
            self.model
                .assemble_with_backing(&self.window, &self.second_window, &mut self.input);
            let act = self
                .model
                .forward(&self.input, &mut self.a, &mut self.b, &mut self.c);
            let thresholds = self.model.thresholds;
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
                return;
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
        let widest = model.scratch_len();
        let min_gap = ((0.05 * sample_rate as f64) / hop as f64).ceil() as usize;
        let second_len = if model.has_second_view() {
            model.window_len()
        } else {
            0
        };
        let mut core = Core {
            window: vec![0.0; model.window_len()],
            second_window: vec![0.0; second_len],
            input: vec![0.0; model.input_len()],
            a: vec![0.0; widest],
            b: vec![0.0; widest],
            c: vec![0.0; widest],
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

    /// Whether the model reads a backing beside the drum signal
    /// ([`DrumTranscriber::process_with_backing`]).
    pub fn wants_backing(&self) -> bool {
        self.core.model.backing.is_some()
    }

    /// Feeds a block; calls `emit(hop, frame)` for every decided hop, in order. A model with
    /// the backing view sees silence as the backing (a supplied, clean drum stem).
    pub fn process_frames(&mut self, input: &[f32], emit: &mut dyn FnMut(usize, DrumFrame)) {
        if self.core.model.short {
            return self.feed_both(input, input, emit);
        }
        let core = &mut self.core;
        self.mel
            .process_bands(input, &mut |_, bands| core.push_frame(bands, None, emit));
    }

    /// Feeds a block of the drum signal and the same span of its backing (the separator's
    /// other stems, summed); `backing` must be as long as `input`. A model without the
    /// backing view ignores it. A stream is fed either always with a backing or never.
    pub fn process_with_backing(
        &mut self,
        input: &[f32],
        backing: &[f32],
        emit: &mut dyn FnMut(usize, DrumFrame),
    ) {
        if self.core.model.backing.is_none() {
            return self.process_frames(input, emit);
        }
        debug_assert_eq!(input.len(), backing.len());
        self.feed_both(input, backing, emit);
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
    }

    /// Ends the stream: emits every remaining hop (`n.div_ceil(hop)` in all), holding the
    /// last mel frame for the look-ahead frames past the end.
    pub fn finish_frames(&mut self, emit: &mut dyn FnMut(usize, DrumFrame)) {
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
        while core.next < total {
            let back = has_second.then_some(&last_second[..n]);
            core.push_frame(&last[..n], back, emit);
        }
        core.drain(emit);
    }
}

impl HopStage for DrumTranscriber {
    type Out = DrumFrame;

    fn process(&mut self, input: &[f32], emit: &mut dyn FnMut(usize, DrumFrame)) {
        self.process_frames(input, emit);
    }

    fn finish(&mut self, emit: &mut dyn FnMut(usize, DrumFrame)) {
        self.finish_frames(emit);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_model_parses() {
        for (bytes, future) in [(EMBEDDED, 4), (EMBEDDED_LIVE, 1)] {
            let m = DrumModel::from_bytes(bytes).unwrap();
            assert_eq!(m.bands, MelConfig::drums(44_100).bands);
            assert_eq!(m.future, future);
            assert!(m.thresholds.iter().all(|t| (0.0..1.0).contains(t)));
        }
    }

    #[test]
    fn truncated_or_foreign_models_are_errors() {
        for n in [0, 7, 8, 20, EMBEDDED.len() / 2, EMBEDDED.len() - 1] {
            assert!(DrumModel::from_bytes(&EMBEDDED[..n]).is_err(), "{n}");
        }
        let mut extra = EMBEDDED.to_vec();
        extra.push(0);
        assert!(DrumModel::from_bytes(&extra).is_err());
        let mut bad = EMBEDDED.to_vec();
        bad[0] = b'X';
        assert!(DrumModel::from_bytes(&bad).is_err());
    }

    fn ensemble(members: &[&[u8]], thresholds: [f32; 4]) -> Vec<u8> {
        let mut v = MAGIC_ENSEMBLE.to_vec();
        v.extend(1u32.to_le_bytes());
        v.extend((members.len() as u32).to_le_bytes());
        for m in members {
            v.extend((m.len() as u32).to_le_bytes());
            v.extend_from_slice(m);
        }
        for t in thresholds {
            v.extend(t.to_le_bytes());
        }
        v
    }

    #[test]
    fn ensemble_files_average_their_members() {
        let net = embedded_network();
        let one = DrumModel::from_bytes(net).unwrap();
        let two = ensemble(&[net, net], [0.1, 0.2, 0.3, 0.4]);
        let m = DrumModel::from_bytes(&two).unwrap();
        assert_eq!(m.members.len(), 1);
        assert_eq!(m.thresholds, [0.1, 0.2, 0.3, 0.4]);
        // Two copies of one network: the mean is that network's activation.
        let w = m.scratch_len();
        let (mut a, mut b, mut c) = (vec![0f32; w], vec![0f32; w], vec![0f32; w]);
        let window: Vec<f32> = (0..m.window_len())
            .map(|i| -(((i * 37) % 23) as f32))
            .collect();
        let mut input = vec![0f32; m.input_len()];
        m.assemble(&window, &mut input);
        let got = m.forward(&input, &mut a, &mut b, &mut c);
        let want = one.forward(&input, &mut a, &mut b, &mut c);
        for k in 0..CLASSES {
            assert!((got[k] - want[k]).abs() < 1e-6, "{got:?} vs {want:?}");
        }
        // Members must read the same input; counts, nesting and lengths are checked.
        let e = DrumModel::from_bytes(&ensemble(&[net, network_of(EMBEDDED_LIVE)], [0.5; 4]));
        assert!(e.unwrap_err().to_string().contains("must share"));
        assert!(DrumModel::from_bytes(&ensemble(&[net], [0.5; 4])).is_err());
        assert!(DrumModel::from_bytes(&ensemble(&[&two, net], [0.5; 4])).is_err());
        // A retuned file is not a single network.
        let e = DrumModel::from_bytes(&ensemble(&[EMBEDDED, net], [0.5; 4]));
        assert!(e.unwrap_err().to_string().contains("not a single network"));
        for n in [8, 12, 16, 20, two.len() / 2, two.len() - 1] {
            assert!(DrumModel::from_bytes(&two[..n]).is_err(), "{n}");
        }
        let mut extra = two.clone();
        extra.push(0);
        assert!(DrumModel::from_bytes(&extra).is_err());
    }

    /// A version-2 file by hand: 2 bands, 1 past and 1 future frame, one 10 → 4 layer
    /// (6 window values + 4 flux values with feature set 1, 6 with feature set 0).
    fn v2(features: u32, n_in: u32) -> Vec<u8> {
        let mut v = b"TACTUSDR".to_vec();
        for x in [2u32, 2, 1, 1, 4, 1] {
            v.extend(x.to_le_bytes());
        }
        v.extend((-16f32).to_le_bytes());
        v.extend(features.to_le_bytes());
        v.extend(n_in.to_le_bytes());
        v.extend(4u32.to_le_bytes());
        for k in 0..n_in * 4 + 4 + 4 {
            v.extend((k as f32 * 0.01).to_le_bytes());
        }
        v
    }

    #[test]
    fn version_2_carries_the_input_feature_set() {
        let m = DrumModel::from_bytes(&v2(1, 10)).unwrap();
        assert!(m.flux);
        assert_eq!((m.window_len(), m.input_len()), (6, 10));
        let m = DrumModel::from_bytes(&v2(0, 6)).unwrap();
        assert!(!m.flux);
        assert_eq!(m.input_len(), 6);
        // The layer must match the feature set's input length.
        let e = DrumModel::from_bytes(&v2(1, 6)).unwrap_err().to_string();
        assert!(e.contains("do not chain"), "{e}");
        let e = DrumModel::from_bytes(&v2(4, 10)).unwrap_err().to_string();
        assert!(e.contains("input feature set 4"), "{e}");
        // Feature set 3, the short view: 6 window + 6 short-view values, nothing else.
        let m = DrumModel::from_bytes(&v2(3, 12)).unwrap();
        assert!(m.short && !m.flux && m.backing.is_none());
        assert_eq!((m.window_len(), m.input_len()), (6, 12));
        let e = DrumModel::from_bytes(&v2(3, 6)).unwrap_err().to_string();
        assert!(e.contains("do not chain"), "{e}");
        // Feature set 2, the backing: its ceiling follows, then 6 window + 6 backing values.
        let backing = |ceil: f32, n_in: u32| {
            let mut v = v2(2, n_in);
            let at = 8 + 6 * 4 + 4 + 4;
            v.splice(at..at, ceil.to_le_bytes());
            v
        };
        let m = DrumModel::from_bytes(&backing(6.0, 12)).unwrap();
        assert_eq!((m.backing, m.flux), (Some(6.0), false));
        assert_eq!((m.window_len(), m.input_len()), (6, 12));
        let e = DrumModel::from_bytes(&backing(6.0, 6))
            .unwrap_err()
            .to_string();
        assert!(e.contains("do not chain"), "{e}");
        let e = DrumModel::from_bytes(&backing(-20.0, 12))
            .unwrap_err()
            .to_string();
        assert!(e.contains("ceiling"), "{e}");
        let mut v3 = v2(1, 10);
        v3[8] = 3;
        let e = DrumModel::from_bytes(&v3).unwrap_err().to_string();
        assert!(e.contains("version 3"), "{e}");
    }

    /// The retuned file inside an embedded file (bare, or inside a staged file).
    fn retuned_of(file: &'static [u8]) -> &'static [u8] {
        if !file.starts_with(MAGIC_STAGED) {
            return file;
        }
        let u = |at: usize| u32::from_le_bytes(file[at..at + 4].try_into().unwrap()) as usize;
        let mut at = 28;
        for _ in 0..u(24).count_ones() {
            at += match (u(8), u(at)) {
                (1, _) => 44,
                (_, 0) => 48,
                (_, h) => 4 + 4 * (12 * h + 2),
            };
        }
        &file[at + 4..at + 4 + u(at)]
    }

    /// The single network inside an embedded file (a retuned file, maybe staged).
    fn network_of(file: &'static [u8]) -> &'static [u8] {
        let file = retuned_of(file);
        assert!(file.starts_with(MAGIC_RETUNED));
        let u = |at: usize| u32::from_le_bytes(file[at..at + 4].try_into().unwrap()) as usize;
        let at = 16 + 4 * u(12);
        &file[at + 4..at + 4 + u(at)]
    }

    fn staged_file(wait: u32, low: f32, shrink: f32, mask: u32, inner: &[u8]) -> Vec<u8> {
        let mut v = MAGIC_STAGED.to_vec();
        for x in [1u32, wait] {
            v.extend(x.to_le_bytes());
        }
        v.extend(low.to_le_bytes());
        v.extend(shrink.to_le_bytes());
        v.extend(mask.to_le_bytes());
        for c in 0..CLASSES {
            if mask & (1 << c) != 0 {
                for k in 0..=JUDGE_INPUTS {
                    v.extend((k as f32 * 0.1 - c as f32).to_le_bytes());
                }
            }
        }
        v.extend((inner.len() as u32).to_le_bytes());
        v.extend_from_slice(inner);
        v
    }

    #[test]
    fn staged_files_parse_and_bad_ones_are_errors() {
        let inner = retuned_of(EMBEDDED);
        let m = DrumModel::from_bytes(&staged_file(2, 0.3, 8.0, 0b1010, inner)).unwrap();
        let st = m.stage.as_ref().unwrap();
        assert_eq!((st.wait, st.low, st.shrink), (2, 0.3, 8.0));
        assert!(st.judges[0].is_none() && st.judges[2].is_none());
        assert_eq!(st.judges[1].as_ref().unwrap().w[3], 0.3f32 - 1.0);
        assert_eq!(
            st.judges[3].as_ref().unwrap().cut,
            JUDGE_INPUTS as f32 * 0.1 - 3.0
        );
        assert_eq!(m.retunings.len(), 3, "the inner file's retunings are kept");
        let err = |v: Vec<u8>| DrumModel::from_bytes(&v).unwrap_err().to_string();
        assert!(err(staged_file(9, 0.3, 8.0, 2, inner)).contains("0 to 8 hops"));
        for (low, shrink) in [(0.0, 8.0), (1.0, 8.0), (0.3, 0.0), (0.3, -1.0)] {
            assert!(err(staged_file(1, low, shrink, 2, inner)).contains("threshold in (0, 1)"));
        }
        assert!(err(staged_file(1, f32::NAN, 8.0, 2, inner)).contains("non-finite"));
        for mask in [0, 16] {
            assert!(
                err(staged_file(1, 0.3, 8.0, mask, inner)).contains("mask"),
                "{mask}"
            );
        }
        let nested = staged_file(1, 0.3, 8.0, 2, inner);
        assert!(err(staged_file(1, 0.3, 8.0, 2, &nested)).contains("another staged"));
        assert!(err(staged_file(1, 0.3, 8.0, 2, b"TACTUSXX")).contains("not a Tactus"));
        let mut v = staged_file(1, 0.3, 8.0, 2, inner);
        v[8] = 3;
        assert!(err(v).contains("version 3 is not supported (1 to 2 are)"));
        let good = staged_file(1, 0.3, 8.0, 2, inner);
        for n in [8, 12, 20, 28, 40, good.len() / 2, good.len() - 1] {
            assert!(DrumModel::from_bytes(&good[..n]).is_err(), "{n}");
        }
        let mut extra = good.clone();
        extra.push(0);
        assert!(err(extra).contains("trailing"));
    }

    /// A version-2 staged file: a perceptron judge with `hidden` units for the snare (unit
    /// `h`'s weight `k` is `h - k / 10`, its bias `0.5 h`, its output weight `1 - h`), a
    /// linear one for the cymbals.
    fn staged_v2(hidden: u32, inner: &[u8]) -> Vec<u8> {
        let mut v = MAGIC_STAGED.to_vec();
        for x in [2u32, 1] {
            v.extend(x.to_le_bytes());
        }
        v.extend(0.3f32.to_le_bytes());
        v.extend(8f32.to_le_bytes());
        v.extend(0b1010u32.to_le_bytes());
        v.extend(hidden.to_le_bytes());
        let mut f = |x: f32| v.extend(x.to_le_bytes());
        for h in 0..hidden {
            for k in 0..JUDGE_INPUTS {
                f(h as f32 - k as f32 / 10.0);
            }
            f(0.5 * h as f32);
        }
        for h in 0..hidden {
            f(1.0 - h as f32);
        }
        f(0.25);
        f(-0.5);
        v.extend(0u32.to_le_bytes());
        for k in 0..=JUDGE_INPUTS {
            v.extend((k as f32).to_le_bytes());
        }
        v.extend((inner.len() as u32).to_le_bytes());
        v.extend_from_slice(inner);
        v
    }

    #[test]
    fn version_2_staged_files_hold_perceptron_judges() {
        let inner = retuned_of(EMBEDDED);
        let m = DrumModel::from_bytes(&staged_v2(3, inner)).unwrap();
        let st = m.stage.as_ref().unwrap();
        let snare = st.judges[1].as_ref().unwrap();
        assert_eq!(snare.hidden.len(), 3);
        assert_eq!(snare.hidden[2][4], 2.0 - 0.4);
        assert_eq!(snare.hidden[2][JUDGE_INPUTS], 1.0);
        assert_eq!(
            (snare.w.clone(), snare.bias, snare.cut),
            (vec![1.0, 0.0, -1.0], 0.25, -0.5)
        );
        let cym = st.judges[3].as_ref().unwrap();
        assert!(cym.hidden.is_empty());
        assert_eq!((cym.w[9], cym.cut, cym.bias), (9.0, 10.0, 0.0));
        // The score by hand: x = (1, 0, ..., 0): unit h gives max(0, h + 0.5 h).
        let mut x = [0f64; JUDGE_INPUTS];
        x[0] = 1.0;
        let want: f64 = 0.25
            + (0..3)
                .map(|h| (1.0 - h as f64) * 1.5 * h as f64)
                .sum::<f64>();
        assert!((snare.score(&x) - want).abs() < 1e-12);
        assert_eq!(cym.score(&x), 0.0);
        // The file inside is found whatever the judges' sizes.
        assert_eq!(
            retuned_of(Box::leak(staged_v2(5, inner).into_boxed_slice())),
            inner
        );
        let err = |v: Vec<u8>| DrumModel::from_bytes(&v).unwrap_err().to_string();
        assert!(err(staged_v2(JUDGE_MAX_HIDDEN as u32 + 1, inner)).contains("at most 256"));
        let good = staged_v2(3, inner);
        for n in [32, 40, 100, 200, good.len() - inner.len() - 5] {
            assert!(DrumModel::from_bytes(&good[..n]).is_err(), "{n}");
        }
    }

    fn embedded_network() -> &'static [u8] {
        network_of(EMBEDDED)
    }

    fn retuned_file(ratios: &[f32], net: &[u8], thresholds: [f32; 4]) -> Vec<u8> {
        let mut v = MAGIC_RETUNED.to_vec();
        v.extend(1u32.to_le_bytes());
        v.extend((ratios.len() as u32).to_le_bytes());
        for r in ratios {
            v.extend(r.to_le_bytes());
        }
        v.extend((net.len() as u32).to_le_bytes());
        v.extend_from_slice(net);
        for t in thresholds {
            v.extend(t.to_le_bytes());
        }
        v
    }

    #[test]
    fn bad_retuned_files_are_errors() {
        let net = embedded_network();
        let err = |v: Vec<u8>| DrumModel::from_bytes(&v).unwrap_err().to_string();
        assert!(err(retuned_file(&[1.0], net, [0.5; 4])).contains("2 to 8"));
        assert!(err(retuned_file(&[1.0; 9], net, [0.5; 4])).contains("2 to 8"));
        for bad in [3.0, 0.25] {
            assert!(
                err(retuned_file(&[1.0, bad], net, [0.5; 4])).contains("[0.5, 2]"),
                "{bad}"
            );
        }
        for bad in [f32::NAN, f32::INFINITY] {
            assert!(
                err(retuned_file(&[1.0, bad], net, [0.5; 4])).contains("non-finite"),
                "{bad}"
            );
        }
        // Only a perceptron on mel frames (and its short view): not a flux or backing
        // model, not a retuned file inside a retuned file.
        let mut backing = v2(2, 12);
        let at = 8 + 6 * 4 + 4 + 4;
        backing.splice(at..at, 6f32.to_le_bytes());
        for inner in [&v2(1, 10)[..], &backing[..]] {
            assert!(err(retuned_file(&[1.0, 1.3], inner, [0.5; 4])).contains("perceptron"));
        }
        let short = DrumModel::from_bytes(&retuned_file(&[1.0, 1.3], &v2(3, 12), [0.5; 4]));
        assert_eq!(short.unwrap().retunings.len(), 2);
        assert!(err(retuned_file(&[1.0, 1.3], EMBEDDED, [0.5; 4])).contains("single network"));
        let mut v = retuned_file(&[1.0, 1.3], net, [0.5; 4]);
        v[8] = 2;
        assert!(err(v).contains("version 2"));
        let good = retuned_file(&[1.0, 1.3], net, [0.5; 4]);
        for n in [8, 12, 16, 20, 24, good.len() / 2, good.len() - 1] {
            assert!(DrumModel::from_bytes(&good[..n]).is_err(), "{n}");
        }
        let mut extra = good.clone();
        extra.push(0);
        assert!(err(extra).contains("trailing"));
    }

    #[test]
    fn embedded_models_are_retuned_by_one_and_1_3_either_way() {
        for m in [DrumModel::embedded(), DrumModel::embedded_live()] {
            let ratios: Vec<f32> = m.retunings.iter().map(|r| r.ratio).collect();
            assert_eq!(ratios, [1.0, (1.0f64 / 1.3) as f32, 1.3]);
        }
        assert!(DrumModel::embedded_live().short);
    }
}
