//! The paper's signal-fidelity metrics (Alcuitas et al. 2025, §3.1), exactly as written there.
//!
//! * **MAE** (§3.1.1): `MAE = (1/N) Σ_{i=1..N} |y_i − ŷ_i|`, N time bins, `y` the normalized
//!   audio pitch, `ŷ` the normalized tactile pitch ([`mae`]).
//! * **Normalized DTW** (§3.1.2): `DTW_norm = (1/K) Σ_{k=1..K} d(a_{i_k}, b_{j_k})`, where
//!   `(i_k, j_k)` is the optimal warping path of length K, `d` the Euclidean distance
//!   between the two (scalar) values, and the path obeys the boundary
//!   (`(0,0)` … `(n−1,m−1)`), monotonicity and continuity (steps (1,0), (0,1), (1,1) only)
//!   constraints ([`dtw`], [`normalized_dtw`]). The accumulated cost is the usual
//!   recursion `D(i,j) = d(i,j) + min(D(i−1,j−1), D(i−1,j), D(i,j−1))`.
//! * **Rhythm accuracy** (§3.1.3): `ACC = (1/N) Σ_{i=1..N} 1(y_i = ŷ_i)` over 100 ms bins
//!   where `y_i`, `ŷ_i` say whether an onset falls in bin i ([`rhythm_accuracy`]).
//!
//! What the paper leaves open, and our choice:
//! * "normalized" is not defined; we use min–max normalization per sequence
//!   ([`normalize_min_max`]). With unvoiced bins stored as 0 the minimum is 0, so this is
//!   `x / max(x)`, which matches the paper's levels "relative to the maximum pitch value".
//!   A constant sequence normalizes to all zeros.
//! * Several warping paths can share the optimal cost but differ in length K. We backtrack
//!   from `(n−1, m−1)` preferring the diagonal step, then `(i−1, j)`, then `(i, j−1)` on
//!   exact ties; this gives the shortest-looking, most diagonal path and is deterministic.
//!
//! Cost: DTW is O(n·m) time and memory (a 3-minute song at 10 bins/s: 1800² cells, 26 MB).
//! There is no latency: these are offline metrics.
use crate::{check_aligned, check_all_finite, check_finite, EvalError};

/// Min–max normalization to [0, 1]: `(x − min) / (max − min)`; all zeros if `max == min`.
pub fn normalize_min_max(x: &[f64]) -> Vec<f64> {
    let lo = x.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let span = hi - lo;
    if !span.is_finite() || span <= 0.0 {
        return vec![0.0; x.len()];
    }
    x.iter().map(|v| (v - lo) / span).collect()
}

/// The paper's MAE: mean of `|y_i − ŷ_i|` over the N bins (§3.1.1).
/// The caller normalizes first (see [`normalize_min_max`]).
pub fn mae(y: &[f64], y_hat: &[f64]) -> Result<f64, EvalError> {
    check_aligned("mae", y.len(), y_hat.len())?;
    check_all_finite(&[("mae", y), ("mae", y_hat)])?;
    let sum: f64 = y.iter().zip(y_hat).map(|(a, b)| (a - b).abs()).sum();
    Ok(sum / y.len() as f64)
}

/// The result of a DTW alignment.
#[derive(Debug, Clone, PartialEq)]
pub struct Dtw {
    /// Accumulated cost `D(n−1, m−1)` = Σ d over the optimal path.
    pub total_cost: f64,
    /// The optimal warping path, from `(0, 0)` to `(n−1, m−1)`, as `(i, j)` index pairs.
    pub path: Vec<(usize, usize)>,
}

impl Dtw {
    /// K, the length of the warping path.
    pub fn path_len(&self) -> usize {
        self.path.len()
    }

    /// The paper's normalized DTW distance: `total_cost / K`.
    pub fn normalized(&self) -> f64 {
        self.total_cost / self.path.len() as f64
    }
}

/// Dynamic time warping of two scalar sequences with `d(a, b) = |a − b|`, boundary,
/// monotonicity and continuity constraints; see the module docs for the tie rule.
pub fn dtw(a: &[f64], b: &[f64]) -> Result<Dtw, EvalError> {
    if a.is_empty() || b.is_empty() {
        return Err(EvalError::Empty("dtw"));
    }
    check_all_finite(&[("dtw", a), ("dtw", b)])?;
    let (n, m) = (a.len(), b.len());
    let mut acc = vec![0.0f64; n * m];
    let at = |i: usize, j: usize| i * m + j;
    for i in 0..n {
        for j in 0..m {
            let d = (a[i] - b[j]).abs();
            let prev = match (i, j) {
                (0, 0) => 0.0,
                (0, _) => acc[at(0, j - 1)],
                (_, 0) => acc[at(i - 1, 0)],
                _ => acc[at(i - 1, j - 1)]
                    .min(acc[at(i - 1, j)])
                    .min(acc[at(i, j - 1)]),
            };
            acc[at(i, j)] = d + prev;
        }
    }
    let mut path = Vec::with_capacity(n + m);
    let (mut i, mut j) = (n - 1, m - 1);
    path.push((i, j));
    while (i, j) != (0, 0) {
        (i, j) = if i == 0 {
            (0, j - 1)
        } else if j == 0 {
            (i - 1, 0)
        } else {
            let diag = acc[at(i - 1, j - 1)];
            let up = acc[at(i - 1, j)];
            let left = acc[at(i, j - 1)];
            if diag <= up && diag <= left {
                (i - 1, j - 1)
            } else if up <= left {
                (i - 1, j)
            } else {
                (i, j - 1)
            }
        };
        path.push((i, j));
    }
    path.reverse();
    Ok(Dtw {
        total_cost: acc[at(n - 1, m - 1)],
        path,
    })
}

/// The paper's normalized DTW distance (§3.1.2) of two already-normalized sequences.
pub fn normalized_dtw(a: &[f64], b: &[f64]) -> Result<f64, EvalError> {
    Ok(dtw(a, b)?.normalized())
}

/// The paper's rhythm accuracy (§3.1.3): the fraction of bins where the tactile beat
/// (`y_hat`) equals the audio beat (`y`).
pub fn rhythm_accuracy(y: &[bool], y_hat: &[bool]) -> Result<f64, EvalError> {
    check_aligned("rhythm_accuracy", y.len(), y_hat.len())?;
    let hits = y.iter().zip(y_hat).filter(|(a, b)| a == b).count();
    Ok(hits as f64 / y.len() as f64)
}

/// Bins onset times: bin `i` is true when an onset falls in `[i·bin_s, (i+1)·bin_s)`.
/// Onsets before 0 or at/after `n_bins · bin_s` are ignored; times within 1e-9 bins below
/// a bin edge count in the later bin. `bin_s` must be > 0.
pub fn onsets_to_bins(onsets_s: &[f64], bin_s: f64, n_bins: usize) -> Result<Vec<bool>, EvalError> {
    if !bin_s.is_finite() || bin_s <= 0.0 {
        return Err(EvalError::Invalid {
            name: "bin_s",
            reason: format!("{bin_s} is not a positive number"),
        });
    }
    check_finite("onsets_to_bins", onsets_s)?;
    let mut bins = vec![false; n_bins];
    for &t in onsets_s {
        if t < 0.0 {
            continue;
        }
        // 1e-9 bins of slack so that an onset written as exactly 0.3 s lands in bin 3
        // although 0.3 / 0.1 = 2.9999999999999996 in binary floating point.
        let k = (t / bin_s + 1e-9).floor() as usize;
        if let Some(b) = bins.get_mut(k) {
            *b = true;
        }
    }
    Ok(bins)
}
