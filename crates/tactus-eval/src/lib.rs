//! # tactus-eval: how well does the glove convey the music?
//!
//! Pure metrics (no I/O besides parsing JSON text handed in by the caller) for scoring
//! Tactus's extracted features against exact ground truth from the synthetic corpus
//! (`corpus/generate.py`), and the three signal-fidelity metrics of the paper
//! (Alcuitas et al., *Electronics* 2025, 14(18), 3658, §3.1).
//!
//! | module | metrics | source |
//! |---|---|---|
//! | [`paper`] | normalized MAE of pitch, normalized DTW distance, rhythm accuracy per bin | the paper, §3.1.1–§3.1.3 |
//! | [`melody`] | raw pitch / raw chroma accuracy (50 cents), voicing recall / false alarm | `mir_eval.melody` 0.8 |
//! | [`onset`] | onset precision / recall / F-measure within ±50 ms, maximum bipartite matching | `mir_eval.onset` 0.8 |
//! | [`levels`] | ground-truth pitch levels per bin, level accuracy (exact and ±1) | docs/design.md "levels" |
//! | [`sdr`] | plain signal-to-distortion ratio, 10·log10(‖s‖² / ‖s − ŝ‖²) | — |
//! | [`truth`] | reader for the corpus `truth.json` | `corpus/README.md` |
//! | [`glove_log`] | the paper's Table 3 from a glove actuation log: levels and beats decoded through the map, scored against pattern and audio | the paper, §3 |
//! | [`features`] | minimal reader for the features file | docs/design.md "Files" |
//! | [`report`] | [`evaluate`]: all of the above per stem and band, as Markdown or JSON | — |
//!
//! ```
//! use tactus_eval::paper::{mae, normalized_dtw, rhythm_accuracy};
//! let y = [0.0, 0.5, 1.0];
//! let y_hat = [0.0, 0.5, 0.5];
//! assert!((mae(&y, &y_hat).unwrap() - 0.5 / 3.0).abs() < 1e-12);
//! assert_eq!(normalized_dtw(&y, &y).unwrap(), 0.0);
//! assert_eq!(rhythm_accuracy(&[true, false], &[true, true]).unwrap(), 0.5);
//! ```
//!
//! Nothing here sits on the real-time path: functions allocate freely and return
//! [`EvalError`] on malformed input instead of panicking.
#![forbid(unsafe_code)]

pub mod features;
pub mod files;
pub mod glove_log;
pub mod levels;
pub mod melody;
pub mod onset;
pub mod paper;
pub mod report;
pub mod sdr;
pub mod truth;

pub use features::FeaturesLike;
pub use report::{evaluate, BandRow, Report, StemRow};
pub use truth::Truth;

/// Why a metric could not be computed, or a file could not be read.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EvalError {
    /// A metric needs at least one element.
    #[error("{0}: empty input")]
    Empty(&'static str),
    /// Two sequences that must be aligned have different lengths.
    #[error("{what}: length mismatch ({left} vs {right})")]
    LengthMismatch {
        /// Which metric.
        what: &'static str,
        /// Length of the first sequence.
        left: usize,
        /// Length of the second sequence.
        right: usize,
    },
    /// A value is NaN or infinite.
    #[error("{0}: non-finite value")]
    NonFinite(&'static str),
    /// A parameter is out of range.
    #[error("invalid {name}: {reason}")]
    Invalid {
        /// The parameter's name.
        name: &'static str,
        /// Why it is rejected.
        reason: String,
    },
    /// The JSON text does not parse or does not have the expected shape.
    #[error("json: {0}")]
    Json(#[from] serde_json::Error),
}

pub(crate) fn check_finite(what: &'static str, x: &[f64]) -> Result<(), EvalError> {
    if x.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(EvalError::NonFinite(what))
    }
}

/// [`check_finite`] on each named sequence, in order.
pub(crate) fn check_all_finite(seqs: &[(&'static str, &[f64])]) -> Result<(), EvalError> {
    seqs.iter().try_for_each(|&(what, x)| check_finite(what, x))
}

/// Two sequences that a metric `what` compares element by element: the same length, not
/// empty.
pub(crate) fn check_aligned(
    what: &'static str,
    left: usize,
    right: usize,
) -> Result<(), EvalError> {
    if left != right {
        Err(EvalError::LengthMismatch { what, left, right })
    } else if left == 0 {
        Err(EvalError::Empty(what))
    } else {
        Ok(())
    }
}
