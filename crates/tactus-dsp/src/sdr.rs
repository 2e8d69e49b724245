//! Plain signal-to-distortion ratio: `SDR = 10·log10(Σ s² / Σ (s − ŝ)²)` in dB.
//!
//! Over the longer of the two lengths: the shorter signal's missing tail counts as zeros, so
//! a truncated estimate is penalised. No projection and no allowed distortion filter, unlike
//! BSS Eval's SDR: a gain or delay error counts as distortion. Accumulates in `f64`. A
//! perfect estimate (silent against silent included) gives `+∞`; a silent reference with a
//! non-silent estimate `−∞`. Used by the separator tests and by `tactus-eval`.

/// Plain SDR in dB of `estimate` against `reference`; see the module docs.
pub fn sdr_db(reference: &[f32], estimate: &[f32]) -> f64 {
    let n = reference.len().max(estimate.len());
    let (mut signal, mut noise) = (0.0f64, 0.0f64);
    for i in 0..n {
        let s = f64::from(reference.get(i).copied().unwrap_or(0.0));
        let e = f64::from(estimate.get(i).copied().unwrap_or(0.0));
        signal += s * s;
        noise += (s - e) * (s - e);
    }
    if noise == 0.0 {
        return f64::INFINITY;
    }
    10.0 * (signal / noise).log10()
}
