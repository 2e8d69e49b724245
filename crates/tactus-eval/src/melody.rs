//! Melody metrics with `mir_eval.melody`'s definitions (mir_eval 0.8; Salamon et al.,
//! "Melody extraction from polyphonic music signals", IEEE SPM 2014).
//!
//! Both contours are f0 in Hz on the same time grid (one value per hop), 0 (or any value
//! ≤ 0) meaning unvoiced. As in `mir_eval.melody.freq_to_voicing`, voicing is `f > 0` and
//! the magnitude `|f|` is the pitch; cents are `1200·log2(|f| / 10 Hz)` (`hz2cents`, 0 for
//! f = 0).
//!
//! * **Voicing recall**: voiced-in-both / voiced-in-reference; 1 if the reference has no
//!   voiced frame (mir_eval 0.8 behaviour); 0 for empty input.
//! * **Voicing false alarm**: voiced-in-estimate among reference-unvoiced frames / reference
//!   unvoiced frames; 0 if the reference has no unvoiced frame.
//! * **Raw pitch accuracy (RPA)**: reference-voiced frames whose estimate, voiced or not but
//!   with a non-zero pitch, is within 50 cents (strictly `<`) / reference-voiced frames.
//!   Estimate voicing is ignored; a negative estimate (pitch guess on an unvoiced frame)
//!   counts with its magnitude.
//! * **Raw chroma accuracy (RCA)**: the same, after folding the cent difference to the
//!   nearest octave: `|Δ − 1200·floor(Δ/1200 + 0.5)| < 50`.
//!
//! When the estimate is shorter than the reference it is padded with unvoiced frames, when
//! longer it is cut (as `mir_eval.melody.to_cent_voicing` does after resampling). We do no
//! resampling: callers put both on the same hop (see [`resample_nearest`]).
use crate::EvalError;

/// Default tolerance of RPA and RCA, in cents.
pub const CENT_TOLERANCE: f64 = 50.0;

/// The four melody scores (all 0 by default, what mir_eval gives on empty input).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MelodyScores {
    /// Raw pitch accuracy at 50 cents.
    pub raw_pitch_accuracy: f64,
    /// Raw chroma accuracy at 50 cents.
    pub raw_chroma_accuracy: f64,
    /// Voicing recall.
    pub voicing_recall: f64,
    /// Voicing false alarm.
    pub voicing_false_alarm: f64,
}

/// `mir_eval.melody.hz2cents` with base 10 Hz: 0 for f = 0, else `1200·log2(|f|/10)`.
pub fn hz_to_cents(f_hz: f64) -> f64 {
    if f_hz == 0.0 {
        0.0
    } else {
        1200.0 * (f_hz.abs() / 10.0).log2()
    }
}

/// Resamples a contour with hop `from_hop_s` onto `n` frames of hop `to_hop_s` by taking,
/// for frame `k` at time `k·to_hop_s`, the nearest source frame (0 past the end).
pub fn resample_nearest(
    f0_hz: &[f64],
    from_hop_s: f64,
    to_hop_s: f64,
    n: usize,
) -> Result<Vec<f64>, EvalError> {
    if !(from_hop_s > 0.0 && to_hop_s > 0.0) {
        return Err(EvalError::Invalid {
            name: "hop_s",
            reason: format!("hops must be positive ({from_hop_s}, {to_hop_s})"),
        });
    }
    Ok((0..n)
        .map(|k| {
            let src = (k as f64 * to_hop_s / from_hop_s).round() as usize;
            f0_hz.get(src).copied().unwrap_or(0.0)
        })
        .collect())
}

/// Computes RPA, RCA, voicing recall and false alarm of `est_hz` against `ref_hz`
/// (same hop) with the given cent tolerance (50 in mir_eval's defaults).
pub fn melody_scores(
    ref_hz: &[f64],
    est_hz: &[f64],
    cent_tolerance: f64,
) -> Result<MelodyScores, EvalError> {
    crate::check_all_finite(&[("melody reference", ref_hz), ("melody estimate", est_hz)])?;
    if ref_hz.is_empty() || est_hz.is_empty() {
        // mir_eval returns 0 for every score on empty input.
        return Ok(MelodyScores::default());
    }
    let est = |i: usize| est_hz.get(i).copied().unwrap_or(0.0);
    let (mut ref_voiced, mut ref_unvoiced) = (0usize, 0usize);
    let (mut both_voiced, mut false_alarm) = (0usize, 0usize);
    let (mut pitch_ok, mut chroma_ok) = (0usize, 0usize);
    for (i, &r) in ref_hz.iter().enumerate() {
        let e = est(i);
        let r_voiced = r > 0.0;
        let e_voiced = e > 0.0;
        if r_voiced {
            ref_voiced += 1;
            both_voiced += usize::from(e_voiced);
        } else {
            ref_unvoiced += 1;
            false_alarm += usize::from(e_voiced);
        }
        let (rc, ec) = (hz_to_cents(r), hz_to_cents(e));
        if r_voiced && rc != 0.0 && ec != 0.0 {
            let diff = (rc - ec).abs();
            pitch_ok += usize::from(diff < cent_tolerance);
            let octave = 1200.0 * (diff / 1200.0 + 0.5).floor();
            chroma_ok += usize::from((diff - octave).abs() < cent_tolerance);
        }
    }
    let ratio = |num: usize, den: usize| {
        if den == 0 {
            0.0
        } else {
            num as f64 / den as f64
        }
    };
    Ok(MelodyScores {
        raw_pitch_accuracy: ratio(pitch_ok, ref_voiced),
        raw_chroma_accuracy: ratio(chroma_ok, ref_voiced),
        voicing_recall: if ref_voiced == 0 {
            1.0
        } else {
            ratio(both_voiced, ref_voiced)
        },
        voicing_false_alarm: ratio(false_alarm, ref_unvoiced),
    })
}
