//! Ground-truth pitch per bin and pitch levels, and level accuracy.
//!
//! * [`bin_pitch`]: per-hop f0 into bins of `bin_s` (100 ms, the paper's bins). Bin `k`
//!   covers hops whose time `i·hop_s` lies in `[k·bin_s, (k+1)·bin_s)`. It is voiced when at
//!   least half of its hops are voiced, and then holds the median of the voiced f0 values
//!   (lower median for an even count); otherwise 0. This is the truth side's binning;
//!   the engine's binner may differ, which the level accuracy then shows.
//! * [`discretize`]: docs/design.md's levels: `levels` equal-width steps in semitones over the
//!   contour's non-zero range `[lo, hi]`; level `1 + floor((st − lo)/(hi − lo)·levels)`,
//!   clamped to `levels`; 0 = unvoiced. A constant contour maps to level 1.
//! * [`level_accuracy`]: fraction of bins where the levels agree exactly, and within ±1.
//!   The shorter sequence is padded with level 0 (silent) to the longer one's length.
use crate::EvalError;

/// Bins a per-hop f0 contour (Hz, 0 = unvoiced); see the module docs.
pub fn bin_pitch(f0_hz: &[f64], hop_s: f64, bin_s: f64) -> Result<Vec<f64>, EvalError> {
    if !(hop_s > 0.0 && bin_s > 0.0 && hop_s.is_finite() && bin_s.is_finite()) {
        return Err(EvalError::Invalid {
            name: "hop_s/bin_s",
            reason: format!("must be positive ({hop_s}, {bin_s})"),
        });
    }
    crate::check_finite("bin_pitch", f0_hz)?;
    if f0_hz.is_empty() {
        return Ok(Vec::new());
    }
    let bin_of = |i: usize| (i as f64 * hop_s / bin_s + 1e-9).floor() as usize;
    let n_bins = bin_of(f0_hz.len() - 1) + 1;
    let mut members: Vec<Vec<f64>> = vec![Vec::new(); n_bins];
    let mut counts = vec![0usize; n_bins];
    for (i, &f) in f0_hz.iter().enumerate() {
        let k = bin_of(i);
        counts[k] += 1;
        if f > 0.0 {
            members[k].push(f);
        }
    }
    Ok(members
        .into_iter()
        .zip(counts)
        .map(|(mut v, n)| {
            if v.is_empty() || 2 * v.len() < n {
                0.0
            } else {
                v.sort_by(f64::total_cmp);
                v[(v.len() - 1) / 2]
            }
        })
        .collect())
}

/// Discretizes f0 values (Hz, 0 = unvoiced) into `levels` equal-width semitone levels.
pub fn discretize(f0_hz: &[f64], levels: u8) -> Result<Vec<u8>, EvalError> {
    if levels == 0 {
        return Err(EvalError::Invalid {
            name: "levels",
            reason: "must be at least 1".into(),
        });
    }
    crate::check_finite("discretize", f0_hz)?;
    let st = |f: f64| 69.0 + 12.0 * (f / 440.0).log2();
    let voiced = f0_hz.iter().copied().filter(|&f| f > 0.0);
    let lo = voiced.clone().map(st).fold(f64::INFINITY, f64::min);
    let hi = voiced.map(st).fold(f64::NEG_INFINITY, f64::max);
    Ok(f0_hz
        .iter()
        .map(|&f| {
            if f <= 0.0 {
                0
            } else if hi > lo {
                let x = (st(f) - lo) / (hi - lo) * f64::from(levels);
                (1.0 + x.floor()).min(f64::from(levels)) as u8
            } else {
                1
            }
        })
        .collect())
}

/// Level accuracy: (exact, within ±1), over the longer length (shorter padded with 0).
pub fn level_accuracy(truth: &[u8], est: &[u8]) -> Result<(f64, f64), EvalError> {
    let n = truth.len().max(est.len());
    if n == 0 {
        return Err(EvalError::Empty("level_accuracy"));
    }
    let get = |v: &[u8], i: usize| i32::from(v.get(i).copied().unwrap_or(0));
    let (mut exact, mut near) = (0usize, 0usize);
    for i in 0..n {
        let d = (get(truth, i) - get(est, i)).abs();
        exact += usize::from(d == 0);
        near += usize::from(d <= 1);
    }
    Ok((exact as f64 / n as f64, near as f64 / n as f64))
}
