//! Onset precision, recall and F-measure with `mir_eval.onset.f_measure`'s definition
//! (mir_eval 0.8; Dixon 2006, "Onset detection revisited").
//!
//! A reference onset `r` and an estimated onset `e` may be paired when
//! `e − w ≤ r ≤ e + w` (w = 50 ms by default, bounds computed as in mir_eval's
//! `_fast_hit_windows`). Each onset is used at most once, and the number of pairs is the
//! size of a **maximum bipartite matching** of that hit graph (mir_eval uses Hopcroft–Karp;
//! we use Kuhn's augmenting paths with an explicit stack: the maximum size is the same).
//! Then `P = matches / |est|`, `R = matches / |ref|`, `F = 2PR / (P + R)` (0 if P + R = 0);
//! all three are 0 when either list is empty.
//!
//! Cost: O(V·E) in the worst case; the hit graph of real onset lists is sparse.
use crate::EvalError;

/// Default matching window in seconds (±50 ms).
pub const WINDOW_S: f64 = 0.05;

/// Onset scores (all 0 by default, what mir_eval gives on empty input).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct OnsetScores {
    /// Matched / estimated.
    pub precision: f64,
    /// Matched / reference.
    pub recall: f64,
    /// Harmonic mean of precision and recall.
    pub f_measure: f64,
    /// Number of matched pairs.
    pub matched: usize,
}

/// The size of a maximum matching between `reference` and `estimate` within `window_s`.
/// Inputs need not be sorted.
pub fn match_count(reference: &[f64], estimate: &[f64], window_s: f64) -> usize {
    let mut ref_sorted: Vec<f64> = reference.to_vec();
    ref_sorted.sort_by(f64::total_cmp);
    // adjacency: for each estimate, the contiguous range of sorted reference indices it hits
    let ranges: Vec<(usize, usize)> = estimate
        .iter()
        .map(|&e| {
            let lo_t = e - window_s;
            let hi_t = e + window_s;
            let lo = ref_sorted.partition_point(|&r| r < lo_t);
            let hi = ref_sorted.partition_point(|&r| r <= hi_t);
            (lo, hi.max(lo))
        })
        .collect();
    let mut ref_match: Vec<Option<usize>> = vec![None; ref_sorted.len()];
    let mut matched = 0;
    let mut visited = vec![usize::MAX; ref_sorted.len()];
    for root in 0..estimate.len() {
        // Iterative DFS for an augmenting path from estimate `root`.
        // Stack frames: (estimate index, next reference index to try, reference we came through).
        let mut stack: Vec<(usize, usize, Option<usize>)> = vec![(root, ranges[root].0, None)];
        let mut found = false;
        while let Some(&mut (u, ref mut next, _)) = stack.last_mut() {
            let (_, hi) = ranges[u];
            if *next >= hi {
                stack.pop();
                continue;
            }
            let v = *next;
            *next += 1;
            if visited[v] == root {
                continue;
            }
            visited[v] = root;
            match ref_match[v] {
                None => {
                    // augment along the stack: each frame's estimate takes the reference
                    // it descended through (or `v` for the top frame)
                    let mut take = v;
                    while let Some((u2, _, came)) = stack.pop() {
                        ref_match[take] = Some(u2);
                        match came {
                            Some(c) => take = c,
                            None => break,
                        }
                    }
                    found = true;
                    break;
                }
                Some(owner) => stack.push((owner, ranges[owner].0, Some(v))),
            }
        }
        matched += usize::from(found);
    }
    matched
}

/// `mir_eval.onset.f_measure(reference, estimate, window=window_s)`.
pub fn onset_scores(
    reference: &[f64],
    estimate: &[f64],
    window_s: f64,
) -> Result<OnsetScores, EvalError> {
    crate::check_all_finite(&[("onset reference", reference), ("onset estimate", estimate)])?;
    if !window_s.is_finite() || window_s < 0.0 {
        return Err(EvalError::Invalid {
            name: "window_s",
            reason: format!("{window_s} is not a non-negative number"),
        });
    }
    if reference.is_empty() || estimate.is_empty() {
        return Ok(OnsetScores::default());
    }
    let matched = match_count(reference, estimate, window_s);
    let precision = matched as f64 / estimate.len() as f64;
    let recall = matched as f64 / reference.len() as f64;
    let f_measure = if precision + recall == 0.0 {
        0.0
    } else {
        2.0 * precision * recall / (precision + recall)
    };
    Ok(OnsetScores {
        precision,
        recall,
        f_measure,
        matched,
    })
}
