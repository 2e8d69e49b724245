//! Ground-truth metrics: onset matching against a brute-force maximum matching, melody
//! scores on hand cases, levels, SDR.
use proptest::prelude::*;
use tactus_eval::levels::{bin_pitch, discretize, level_accuracy};
use tactus_eval::melody::{hz_to_cents, melody_scores, resample_nearest};
use tactus_eval::onset::{match_count, onset_scores};
use tactus_eval::sdr::sdr_db;

/// Largest matching by trying every assignment (exponential; sizes ≤ 7).
fn brute_force_matching(r: &[f64], e: &[f64], w: f64) -> usize {
    fn go(r: &[f64], e: &[f64], w: f64, k: usize, used: &mut Vec<bool>) -> usize {
        if k == e.len() {
            return 0;
        }
        let mut best = go(r, e, w, k + 1, used); // leave e[k] unmatched
        for i in 0..r.len() {
            if !used[i] && r[i] >= e[k] - w && r[i] <= e[k] + w {
                used[i] = true;
                best = best.max(1 + go(r, e, w, k + 1, used));
                used[i] = false;
            }
        }
        best
    }
    go(r, e, w, 0, &mut vec![false; r.len()])
}

proptest! {
    #[test]
    fn matching_is_maximum(
        r in prop::collection::vec(0u16..40, 0..7),
        e in prop::collection::vec(0u16..40, 0..7),
    ) {
        // times on a 10 ms grid within 0.4 s: dense, many conflicts, unsorted input
        let r: Vec<f64> = r.into_iter().map(|x| f64::from(x) * 0.01).collect();
        let e: Vec<f64> = e.into_iter().map(|x| f64::from(x) * 0.01).collect();
        prop_assert_eq!(match_count(&r, &e, 0.05), brute_force_matching(&r, &e, 0.05));
    }
}

#[test]
fn greedy_nearest_is_not_enough() {
    // e0 = 0.05 is nearest to r1 = 0.06; taking it would leave e1 = 0.11 without a partner
    // (|0.11 − 0.00| > 0.05). The maximum matching pairs e0–r0 and e1–r1.
    let r = [0.0, 0.06];
    let e = [0.05, 0.11];
    assert_eq!(match_count(&r, &e, 0.05), 2);
    let s = onset_scores(&r, &e, 0.05).unwrap();
    assert_eq!((s.precision, s.recall, s.f_measure), (1.0, 1.0, 1.0));
}

#[test]
fn onset_scores_hand_case() {
    // 3 references, 4 estimates, 2 within ±50 ms: P = 2/4, R = 2/3, F = 2PR/(P+R) = 4/7
    let s = onset_scores(&[1.0, 2.0, 3.0], &[1.02, 1.9, 2.97, 5.0], 0.05).unwrap();
    assert_eq!(s.matched, 2);
    assert_eq!(s.precision, 0.5);
    assert!((s.recall - 2.0 / 3.0).abs() < 1e-15);
    assert!((s.f_measure - 4.0 / 7.0).abs() < 1e-15);
    assert_eq!(onset_scores(&[], &[1.0], 0.05).unwrap().f_measure, 0.0);
}

#[test]
fn melody_hand_case() {
    // ref: 4 voiced, 2 unvoiced. est frame by frame:
    //  0: 440 vs 440 ok          1: 452 vs 440 (+46.6 c) ok
    //  2: 880 vs 440 octave: chroma only   3: 0 (unvoiced) vs 440: miss, voicing miss
    //  4: 300 on unvoiced ref: false alarm  5: 0 on unvoiced ref
    let r = [440.0, 440.0, 440.0, 440.0, 0.0, 0.0];
    let e = [440.0, 452.0, 880.0, 0.0, 300.0, 0.0];
    let s = melody_scores(&r, &e, 50.0).unwrap();
    assert_eq!(s.raw_pitch_accuracy, 0.5);
    assert_eq!(s.raw_chroma_accuracy, 0.75);
    assert_eq!(s.voicing_recall, 0.75);
    assert_eq!(s.voicing_false_alarm, 0.5);
    assert!((hz_to_cents(20.0) - 1200.0).abs() < 1e-9);
    // a shorter estimate is padded with unvoiced frames
    let short = melody_scores(&r, &e[..2], 50.0).unwrap();
    assert_eq!(short.raw_pitch_accuracy, 0.5);
    assert_eq!(short.voicing_recall, 0.5);
}

#[test]
fn resampling_picks_nearest_frame() {
    // 20 ms hops onto 10 ms: frame k takes source round(k / 2)
    let v = resample_nearest(&[1.0, 2.0, 3.0], 0.02, 0.01, 7).unwrap();
    assert_eq!(v, vec![1.0, 2.0, 2.0, 3.0, 3.0, 0.0, 0.0]);
}

#[test]
fn binning_and_levels() {
    // 10 hops per 100 ms bin. Bin 0: 6 voiced of 10 at 110 Hz (voiced, median 110);
    // bin 1: 4 voiced of 10 (unvoiced); bin 2: 5 of 5 at 220 and 440 (lower median 220).
    let mut f0 = vec![0.0; 25];
    f0[..6].iter_mut().for_each(|x| *x = 110.0);
    f0[10..14].iter_mut().for_each(|x| *x = 330.0);
    f0[20..25].copy_from_slice(&[220.0, 440.0, 440.0, 220.0, 220.0]);
    let b = bin_pitch(&f0, 0.01, 0.1).unwrap();
    assert_eq!(b, vec![110.0, 0.0, 220.0]);
    // 8 levels over 110..440 Hz (24 semitones, 3 per level): 110 -> 1, 220 -> 1 + floor(4) = 5,
    // 440 -> top, clamped to 8; 0 stays 0
    let l = discretize(&[110.0, 0.0, 220.0, 440.0, 155.0], 8).unwrap();
    // 155 Hz is 5.94 semitones above 110 -> 1 + floor(1.98) = 2
    assert_eq!(l, vec![1, 0, 5, 8, 2]);
    assert_eq!(
        level_accuracy(&[1, 2, 3, 0], &[1, 3, 5]).unwrap(),
        (0.5, 0.75)
    );
}

#[test]
fn sdr_known_values() {
    let s: Vec<f32> = (0..1000).map(|i| (i as f32 * 0.05).sin()).collect();
    // estimate = 0.9·s: noise is 0.1·s, SDR = 10·log10(1/0.01) = 20 dB
    let e: Vec<f32> = s.iter().map(|x| 0.9 * x).collect();
    assert!((sdr_db(&s, &e).unwrap() - 20.0).abs() < 1e-4);
    assert_eq!(sdr_db(&s, &s).unwrap(), f64::INFINITY);
    assert!(sdr_db(&[], &[]).is_err());
}
