//! The drum model files: a single network (`"TACTUSDR"`, versions 1, 2 and 4), and the
//! files that wrap one: an ensemble (`"TACTUSDE"`), test-time retunings (`"TACTUSDT"`) and a
//! second stage (`"TACTUSD2"`). Every read checks shapes and values and fails with a
//! [`ConfigError`] naming what is wrong.

use super::judge::{Judge, SecondStage, JUDGE_INPUTS, JUDGE_MAX_HIDDEN};
use super::model::DrumModel;
use super::retune::Retuning;
use super::CLASSES;
use crate::nn::format::{read_f32s, read_u32, take};
use crate::nn::{Conv, ConvNet};
use crate::ConfigError;

/// The embedded model (see `models/drums/README.md`).
static EMBEDDED: &[u8] = include_bytes!("../../weights/drums.bin");

/// The embedded low-latency model: one hop of look-ahead context (21.6 ms), for `live`.
static EMBEDDED_LIVE: &[u8] = include_bytes!("../../weights/drums_live.bin");

const WHAT: &str = "drum model";

const MAGIC: &[u8; 8] = b"TACTUSDR";

/// An ensemble file: networks whose activations are averaged.
const MAGIC_ENSEMBLE: &[u8; 8] = b"TACTUSDE";

/// A retuned file: one perceptron and its test-time retunings.
const MAGIC_RETUNED: &[u8; 8] = b"TACTUSDT";

/// A file with a second stage for some classes' onsets ([`SecondStage`]) around a model file.
const MAGIC_STAGED: &[u8; 8] = b"TACTUSD2";

impl DrumModel {
    /// The model embedded in the binary.
    pub fn embedded() -> DrumModel {
        // The embedded file is checked by a unit test, so this cannot fail in a build
        // whose tests pass.
        Self::from_bytes(EMBEDDED).expect("embedded drum model is valid")
    }

    /// The embedded low-latency model: the same network shape with one frame of future
    /// context instead of four, so a hit is decided 512 + 441 samples = 21.6 ms after it
    /// at 44.1 kHz (within the live profile's rhythm budget,
    /// `docs/decisions/0015-live-drums-by-the-one-hop-model.md`), at some cost in accuracy
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
        let layers = crate::nn::format::read_layers(b, n_layers, n_in0, WHAT)?;
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

#[cfg(test)]
mod tests;
