//! The paper's metrics (§3.1) on hand-computed cases, and DTW against a brute-force oracle
//! that enumerates every warping path.
use proptest::prelude::*;
use tactus_eval::paper::{
    dtw, mae, normalize_min_max, normalized_dtw, onsets_to_bins, rhythm_accuracy,
};

#[test]
fn dtw_hand_computed_4x3() {
    // a = [0, 1, 2, 3], b = [0, 2, 3]; d(i, j) = |a_i − b_j|:
    //            b0=0  b1=2  b2=3
    //   a0=0       0     2     3
    //   a1=1       1     1     2
    //   a2=2       2     0     1
    //   a3=3       3     1     0
    // Accumulated D(i,j) = d(i,j) + min(D(i−1,j−1), D(i−1,j), D(i,j−1)):
    //   row 0:  0  2  5
    //   row 1:  1  1  3        D11 = 1 + min(0, 2, 1) = 1; D12 = 2 + min(2, 5, 1) = 3
    //   row 2:  3  1  2        D21 = 0 + min(1, 1, 3) = 1; D22 = 1 + min(1, 3, 1) = 2
    //   row 3:  6  2  1        D31 = 1 + min(3, 1, 6) = 2; D32 = 0 + min(1, 2, 2) = 1
    // Backtrack from (3,2): diag D21 = 1 wins; from (2,1): diag D10 = 1 ties up D11 = 1,
    // diagonal preferred; from (1,0): up to (0,0).
    // Path (0,0) (1,0) (2,1) (3,2): K = 4, cost 0 + 1 + 0 + 0 = 1, normalized 1/4.
    let r = dtw(&[0.0, 1.0, 2.0, 3.0], &[0.0, 2.0, 3.0]).unwrap();
    assert_eq!(r.total_cost, 1.0);
    assert_eq!(r.path, vec![(0, 0), (1, 0), (2, 1), (3, 2)]);
    assert_eq!(r.path_len(), 4);
    assert_eq!(r.normalized(), 0.25);
}

#[test]
fn dtw_hand_computed_2x3() {
    // a = [1, 3], b = [1, 2, 3]; d: row a0 = [0, 1, 2], row a1 = [2, 1, 0].
    // D row 0: 0 1 3; row 1: D10 = 2, D11 = 1 + min(0, 1, 2) = 1, D12 = 0 + min(1, 3, 1) = 1.
    // Backtrack (1,2): diag D01 = 1 ties left D11 = 1 -> diag (0,1); then left to (0,0).
    // Path (0,0) (0,1) (1,2): K = 3, cost 0 + 1 + 0 = 1, normalized 1/3.
    let r = dtw(&[1.0, 3.0], &[1.0, 2.0, 3.0]).unwrap();
    assert_eq!(r.total_cost, 1.0);
    assert_eq!(r.path, vec![(0, 0), (0, 1), (1, 2)]);
    assert!((r.normalized() - 1.0 / 3.0).abs() < 1e-15);
}

#[test]
fn dtw_identical_and_shifted() {
    let x = [0.1, 0.5, 0.9, 0.3];
    assert_eq!(normalized_dtw(&x, &x).unwrap(), 0.0);
    // a delayed copy aligns at zero cost: DTW forgives latency, MAE does not
    let delayed = [0.1, 0.1, 0.5, 0.9, 0.3];
    assert_eq!(normalized_dtw(&x, &delayed).unwrap(), 0.0);
    // single elements: K = 1, distance |a − b|
    assert_eq!(normalized_dtw(&[0.25], &[0.75]).unwrap(), 0.5);
    assert!(dtw(&[], &[1.0]).is_err());
    assert!(dtw(&[f64::NAN], &[1.0]).is_err());
}

#[test]
fn mae_hand_computed() {
    // |0−0| + |0.5−0.25| + |1−1| + |0.25−0.75| = 0.75, over N = 4 bins
    let y = [0.0, 0.5, 1.0, 0.25];
    let y_hat = [0.0, 0.25, 1.0, 0.75];
    assert_eq!(mae(&y, &y_hat).unwrap(), 0.1875);
    assert!(mae(&y, &y_hat[..3]).is_err());
    assert!(mae(&[], &[]).is_err());
}

#[test]
fn normalization_is_min_max() {
    assert_eq!(normalize_min_max(&[0.0, 220.0, 440.0]), vec![0.0, 0.5, 1.0]);
    assert_eq!(normalize_min_max(&[0.0, 4.0, 8.0]), vec![0.0, 0.5, 1.0]);
    assert_eq!(
        normalize_min_max(&[100.0, 150.0, 200.0]),
        vec![0.0, 0.5, 1.0]
    );
    assert_eq!(normalize_min_max(&[3.0, 3.0]), vec![0.0, 0.0]);
}

#[test]
fn rhythm_accuracy_hand_computed() {
    // bins agree at 0, 1, 3 of 5
    let y = [true, false, false, true, false];
    let y_hat = [true, false, true, true, true];
    assert_eq!(rhythm_accuracy(&y, &y_hat).unwrap(), 0.6);
    assert!(rhythm_accuracy(&y, &y_hat[..4]).is_err());
}

#[test]
fn onsets_to_bins_edges() {
    // 0.3 / 0.1 = 2.9999999999999996 in f64: must still land in bin 3
    let b = onsets_to_bins(&[0.0, 0.3, 0.35, 0.99, 1.0, -0.1], 0.1, 10).unwrap();
    let want = [
        true, false, false, true, false, false, false, false, false, true,
    ];
    assert_eq!(b, want);
    assert!(onsets_to_bins(&[0.1], 0.0, 3).is_err());
}

/// Every boundary + monotone + continuous path from (0,0) to (n−1,m−1): (cost, K).
fn all_paths(a: &[f64], b: &[f64]) -> Vec<(f64, usize)> {
    fn go(
        a: &[f64],
        b: &[f64],
        i: usize,
        j: usize,
        cost: f64,
        k: usize,
        out: &mut Vec<(f64, usize)>,
    ) {
        let cost = cost + (a[i] - b[j]).abs();
        if i + 1 == a.len() && j + 1 == b.len() {
            out.push((cost, k + 1));
            return;
        }
        if i + 1 < a.len() {
            go(a, b, i + 1, j, cost, k + 1, out);
        }
        if j + 1 < b.len() {
            go(a, b, i, j + 1, cost, k + 1, out);
        }
        if i + 1 < a.len() && j + 1 < b.len() {
            go(a, b, i + 1, j + 1, cost, k + 1, out);
        }
    }
    let mut out = Vec::new();
    go(a, b, 0, 0, 0.0, 0, &mut out);
    out
}

proptest! {
    #[test]
    fn dtw_matches_brute_force(
        a in prop::collection::vec(0u8..5, 1..6),
        b in prop::collection::vec(0u8..5, 1..6),
    ) {
        // small integer values (as f64) make sums exact, so costs compare with ==,
        // and produce many ties, which exercises the tie rule
        let a: Vec<f64> = a.into_iter().map(f64::from).collect();
        let b: Vec<f64> = b.into_iter().map(f64::from).collect();
        let r = dtw(&a, &b).unwrap();
        let paths = all_paths(&a, &b);
        let best = paths.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
        prop_assert_eq!(r.total_cost, best);
        // the returned path obeys the three constraints and really costs total_cost
        prop_assert_eq!(r.path[0], (0, 0));
        prop_assert_eq!(*r.path.last().unwrap(), (a.len() - 1, b.len() - 1));
        for w in r.path.windows(2) {
            let (di, dj) = (w[1].0 - w[0].0, w[1].1 - w[0].1);
            prop_assert!(matches!((di, dj), (1, 0) | (0, 1) | (1, 1)), "bad step {:?}", w);
        }
        let sum: f64 = r.path.iter().map(|&(i, j)| (a[i] - b[j]).abs()).sum();
        prop_assert_eq!(sum, r.total_cost);
        // K is the length of some optimal path, and within [max(n,m), n+m−1]
        prop_assert!(paths.iter().any(|&(c, k)| c == best && k == r.path_len()));
        prop_assert!(r.path_len() >= a.len().max(b.len()) && r.path_len() < a.len() + b.len());
        prop_assert_eq!(r.normalized(), best / r.path_len() as f64);
    }

    #[test]
    fn dtw_is_symmetric_in_cost_and_bounded_by_mae(
        a in prop::collection::vec(0.0f64..1.0, 1..12),
    ) {
        // For equal lengths the diagonal is one admissible path, so the optimal cost is at
        // most N·MAE; with K ≥ N the normalized DTW is at most the MAE.
        let b: Vec<f64> = a.iter().rev().copied().collect();
        let r = dtw(&a, &b).unwrap();
        let m = mae(&a, &b).unwrap();
        prop_assert!(r.normalized() <= m + 1e-12);
        let back = dtw(&b, &a).unwrap();
        prop_assert!((back.total_cost - r.total_cost).abs() < 1e-12);
    }
}
