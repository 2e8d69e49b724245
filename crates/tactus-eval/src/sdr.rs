//! Plain signal-to-distortion ratio of a separated stem:
//! `SDR = 10·log10(Σ s² / Σ (s − ŝ)²)` in dB, over the common length (the longer signal's
//! tail is compared against zeros). No projection, no allowed distortion filter, unlike
//! BSS Eval's SDR: a gain or delay error counts as distortion. Accumulates in f64.
//! A perfect estimate (including silent vs silent) gives +∞; a silent reference with a
//! non-silent estimate −∞.
use crate::EvalError;

/// Plain SDR in dB of `estimate` against `reference`.
pub fn sdr_db(reference: &[f32], estimate: &[f32]) -> Result<f64, EvalError> {
    let n = reference.len().max(estimate.len());
    if n == 0 {
        return Err(EvalError::Empty("sdr"));
    }
    if !reference.iter().chain(estimate).all(|x| x.is_finite()) {
        return Err(EvalError::NonFinite("sdr"));
    }
    let (mut signal, mut noise) = (0.0f64, 0.0f64);
    for i in 0..n {
        let s = f64::from(reference.get(i).copied().unwrap_or(0.0));
        let e = f64::from(estimate.get(i).copied().unwrap_or(0.0));
        signal += s * s;
        noise += (s - e) * (s - e);
    }
    if noise == 0.0 {
        return Ok(f64::INFINITY);
    }
    Ok(10.0 * (signal / noise).log10())
}
