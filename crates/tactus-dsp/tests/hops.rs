//! Tests for the per-hop stages: RMS + gate, Tukey fences, discretizer, binners.
//!
//! Every fast stage is compared with a slow, obvious oracle written here from the definition.
//!
//! `unsafe` exception: the counting `#[global_allocator]` below must implement the `unsafe`
//! trait `GlobalAlloc`; it only forwards to `System` and bumps a thread-local counter. The
//! library itself stays `#![forbid(unsafe_code)]`.

use std::collections::VecDeque;

use proptest::prelude::*;
use tactus_dsp::binner::{bin_beats, bin_levels, BeatBinner, LevelBinner};
use tactus_dsp::discretize::{range_offline, Discretizer, RunningRange, Scale};
use tactus_dsp::hz_to_semitones;
use tactus_dsp::rms::{
    frame_rms_db, gate_offline, Rms, StreamingGate, DEFAULT_FLOOR_DB, GATE_BELOW_DB, SILENCE_DB,
};
use tactus_dsp::tukey::{fences, quartiles, reject_outliers_offline, SlidingTukey, TUKEY_K};
use tactus_dsp::HopStage;

// ---------------------------------------------------------------------------------------------
#[global_allocator]
static GLOBAL: tactus_testkit::Counting = tactus_testkit::Counting;

/// Allocations made by this thread while `f` runs.
fn allocs_during(f: impl FnOnce()) -> usize {
    tactus_testkit::allocations_during(f)
}

// ---------------------------------------------------------------------------------------------
// Helpers and oracles
// ---------------------------------------------------------------------------------------------

/// Deterministic xorshift noise in [-1, 1).
fn noise(n: usize, seed: u64) -> Vec<f32> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            ((s >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
        })
        .collect()
}

/// Naive RMS oracle: pad `frame / 2` zeros, slice each centred frame, sanitize each sample the
/// documented way (non-finite → 0, |x| < 1e-30 → 0), sum squares sequentially in f64.
fn naive_rms_db(x: &[f32], frame: usize, hop: usize) -> Vec<f32> {
    let pad = frame / 2;
    let mut p = vec![0.0f32; pad];
    p.extend(x.iter().map(|&v| {
        if !v.is_finite() || v.abs() < 1e-30 {
            0.0
        } else {
            v
        }
    }));
    p.resize(pad + x.len() + frame + hop, 0.0);
    (0..x.len().div_ceil(hop))
        .map(|i| {
            let fr = &p[i * hop..i * hop + frame];
            let ms: f64 =
                fr.iter().map(|&v| f64::from(v) * f64::from(v)).sum::<f64>() / frame as f64;
            if ms > 0.0 {
                ((10.0 * ms.log10()) as f32).max(-200.0)
            } else {
                -200.0
            }
        })
        .collect()
}

fn run_rms(x: &[f32], frame: usize, hop: usize, chunks: &[usize]) -> Vec<f32> {
    let mut r = Rms::new(frame, hop).unwrap();
    let mut out = Vec::new();
    let mut rest = x;
    let mut k = 0;
    while !rest.is_empty() {
        let c = if chunks.is_empty() {
            rest.len()
        } else {
            chunks[k % chunks.len()].max(1)
        };
        let c = c.min(rest.len());
        r.process(&rest[..c], &mut |i, v| {
            assert_eq!(i, out.len());
            out.push(v)
        });
        rest = &rest[c..];
        k += 1;
    }
    r.finish(&mut |i, v| {
        assert_eq!(i, out.len());
        out.push(v)
    });
    out
}

/// numpy's linear quantile, written plainly in f64 from the definition.
fn np_quantile(values: &[f32], q: f64) -> f64 {
    let mut v: Vec<f64> = values.iter().map(|&x| f64::from(x)).collect();
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let h = q * (v.len() - 1) as f64;
    let lo = h.floor() as usize;
    let hi = (lo + 1).min(v.len() - 1);
    v[lo] + (v[hi] - v[lo]) * (h - lo as f64)
}

fn oracle_fences(st: &[f32], k: f64) -> (f64, f64) {
    let q1 = np_quantile(st, 0.25);
    let q3 = np_quantile(st, 0.75);
    (q1 - k * (q3 - q1), q3 + k * (q3 - q1))
}

/// Distance from `s` to the nearer fence.
fn fence_gap(s: f64, (lo, hi): (f64, f64)) -> f64 {
    (s - lo).abs().min((s - hi).abs())
}

// ---------------------------------------------------------------------------------------------
// RMS
// ---------------------------------------------------------------------------------------------

#[test]
fn rms_matches_naive_oracle() {
    // Tolerance 1e-4 dB: both sum in f64 (relative error ~1e-15, i.e. ~1e-14 dB); the only
    // visible difference is the final cast to f32 (≤ 200 dB · 6e-8 ≈ 1.2e-5 dB).
    let mut signals: Vec<(&str, Vec<f32>)> = vec![
        ("noise", noise(5000, 1)),
        ("silence", vec![0.0; 3000]),
        (
            "+-8",
            (0..3000)
                .map(|i| if i % 2 == 0 { 8.0 } else { -8.0 })
                .collect(),
        ),
        ("tiny 1e-38", vec![1e-38; 3000]),
        (
            "sine",
            (0..4000).map(|i| (i as f32 * 0.05).sin() * 0.3).collect(),
        ),
    ];
    let mut bad = noise(4000, 2);
    for i in (0..4000).step_by(97) {
        bad[i] = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY][i % 3];
    }
    signals.push(("nan/inf", bad));
    for (name, x) in &signals {
        for &(frame, hop) in &[(2048, 441), (256, 64), (64, 100), (1, 1), (7, 3)] {
            let got = run_rms(x, frame, hop, &[]);
            let want = naive_rms_db(x, frame, hop);
            assert_eq!(got.len(), want.len());
            for (i, (g, w)) in got.iter().zip(&want).enumerate() {
                assert!(g.is_finite(), "{name} f{frame} h{hop} hop {i}: {g}");
                assert!(
                    (g - w).abs() <= 1e-4,
                    "{name} f{frame} h{hop} hop {i}: {g} vs {w}"
                );
            }
        }
    }
}

#[test]
fn rms_known_levels_and_floor() {
    // Interior frames of ±8 are exactly 20·log10(8) = 18.0618 dBFS; silence and 1e-38 (flushed
    // by sanitize) give the floor; a frame of NaN/Inf is treated as silence.
    let eight: Vec<f32> = (0..4096)
        .map(|i| if i % 2 == 0 { 8.0 } else { -8.0 })
        .collect();
    let v = run_rms(&eight, 256, 128, &[]);
    for &d in &v[2..v.len() - 2] {
        assert!((d - 18.061_8).abs() < 1e-3, "{d}");
    }
    assert!(run_rms(&vec![0.0; 1000], 64, 32, &[])
        .iter()
        .all(|&d| d == SILENCE_DB));
    assert!(run_rms(&vec![1e-38; 1000], 64, 32, &[])
        .iter()
        .all(|&d| d == SILENCE_DB));
    let mut r = Rms::new(64, 32).unwrap();
    let mut out = Vec::new();
    r.process(
        &[f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::NAN],
        &mut |_, d| out.push(d),
    );
    r.finish(&mut |_, d| out.push(d));
    assert_eq!(out, vec![SILENCE_DB]);
    assert_eq!(r.non_finite_samples(), 4);
    r.reset();
    assert_eq!(r.non_finite_samples(), 0);
    // Full-scale sine over whole periods: −3.0103 dBFS.
    let sine: Vec<f32> = (0..64)
        .map(|i| (i as f32 * std::f32::consts::TAU / 16.0).sin())
        .collect();
    assert!((frame_rms_db(&sine) + 3.0103).abs() < 1e-3);
    assert_eq!(frame_rms_db(&[]), SILENCE_DB);
}

#[test]
fn rms_rejects_bad_config_and_reports_latency() {
    assert!(Rms::new(0, 10).is_err());
    assert!(Rms::new(10, 0).is_err());
    let r = Rms::new(2048, 441).unwrap();
    assert_eq!(r.latency_samples(), 1024);
    assert_eq!(r.hop(), 441);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn rms_chunking_is_invariant(
        len in 0usize..3000,
        frame in 1usize..300,
        hop in 1usize..200,
        chunks in proptest::collection::vec(1usize..500, 1..8),
        seed in any::<u64>(),
    ) {
        let x = noise(len, seed);
        let whole = run_rms(&x, frame, hop, &[]);
        let chunked = run_rms(&x, frame, hop, &chunks);
        prop_assert_eq!(whole.len(), len.div_ceil(hop));
        prop_assert_eq!(&whole, &chunked);
        // reset() reproduces
        let mut r = Rms::new(frame, hop).unwrap();
        r.process(&x[..len / 2], &mut |_, _| {});
        r.reset();
        let mut again = Vec::new();
        r.process(&x, &mut |_, v| again.push(v));
        r.finish(&mut |_, v| again.push(v));
        prop_assert_eq!(&whole, &again);
    }
}

// ---------------------------------------------------------------------------------------------
// Gate
// ---------------------------------------------------------------------------------------------

#[test]
fn offline_gate_on_level_profile() {
    // 1 s each of a ±1 square (0 dBFS), ±0.1 (−20 dBFS), ±0.01 (−40 dBFS) at 44.1 kHz;
    // frame 2048, hop 441. Hops whose frame lies inside one section: 0 and −20 dB open
    // (≤ 35 dB below the 0 dB max), −40 dB closed.
    let sec = 44_100;
    let (frame, hop) = (2048usize, 441usize);
    let mut x = Vec::new();
    for amp in [1.0f32, 0.1, 0.01] {
        x.extend((0..sec).map(|i| if i % 2 == 0 { amp } else { -amp }));
    }
    let db = run_rms(&x, frame, hop, &[]);
    let mut open = vec![true; db.len()];
    let reference = gate_offline(&db, GATE_BELOW_DB, &mut open);
    assert!(reference.abs() < 1e-3, "reference {reference}");
    let mut checked = [0usize; 3];
    for (i, &o) in open.iter().enumerate() {
        let (start, end) = ((i * hop) as isize - 1024, (i * hop) as isize + 1024);
        let section = (start.max(0) as usize) / sec;
        if start < 0 || section != (end as usize - 1) / sec || section > 2 {
            continue; // frame straddles a boundary or the padding
        }
        assert_eq!(o, section < 2, "hop {i} section {section} db {}", db[i]);
        checked[section] += 1;
    }
    assert!(checked.iter().all(|&c| c > 90), "{checked:?}");

    // Digital silence: everything closed, reference at the floor.
    let sil = run_rms(&vec![0.0; 10_000], frame, hop, &[]);
    let mut open = vec![true; sil.len()];
    assert_eq!(gate_offline(&sil, GATE_BELOW_DB, &mut open), SILENCE_DB);
    assert!(open.iter().all(|&o| !o));

    // NaN entries are closed and ignored; extra `open` entries are cleared.
    let mut open = [true; 5];
    let r = gate_offline(&[-10.0, f32::NAN, -40.0, -50.0], 35.0, &mut open);
    assert_eq!(r, -10.0);
    assert_eq!(open, [true, false, true, false, false]);
}

#[test]
fn streaming_gate_follows_decaying_reference() {
    // Loud (0 dB) for 200 hops, then −45 dB. With decay d = 3 dB/s and hop_s = 0.01, at quiet hop
    // j the reference is max(0 − 0.03·(j+1), −45); the hop opens when −45 ≥ ref − 35, i.e. when
    // 0.03·(j+1) ≥ 10: first open at j* = ⌈10 / 0.03⌉ − 1 = 333.
    let (decay, hop_s, loud, quiet) = (3.0f32, 0.01f32, 0.0f32, -45.0f32);
    let j_star = ((f64::from(loud - quiet) - 35.0) / (f64::from(decay) * f64::from(hop_s))).ceil()
        as usize
        - 1;
    assert_eq!(j_star, 333);
    let mut g = StreamingGate::new(GATE_BELOW_DB, decay, hop_s).unwrap();
    let run = |g: &mut StreamingGate| -> Vec<bool> {
        let mut v: Vec<bool> = (0..200).map(|_| g.process(loud)).collect();
        v.extend((0..1000).map(|_| g.process(quiet)));
        v
    };
    let a = run(&mut g);
    assert!(a[..200].iter().all(|&o| o));
    for (j, &o) in a[200..].iter().enumerate() {
        assert_eq!(o, j >= j_star, "quiet hop {j}, reference");
    }
    g.reset();
    assert_eq!(run(&mut g), a, "reset reproduces");

    // A passage within 35 dB is open at once; one under the absolute floor never opens.
    let mut g = StreamingGate::new(GATE_BELOW_DB, decay, hop_s).unwrap();
    g.process(0.0);
    assert!(g.process(-30.0));
    let mut g = StreamingGate::new(GATE_BELOW_DB, decay, hop_s).unwrap();
    assert!((0..10_000).all(|_| !g.process(DEFAULT_FLOOR_DB - 5.0)));
    assert!(!g.process(f32::NAN) && !g.process(f32::NEG_INFINITY) && !g.process(f32::INFINITY));
    assert!(g.reference_db().is_finite());
    // A custom floor is honoured.
    let mut g = StreamingGate::new(GATE_BELOW_DB, decay, hop_s)
        .unwrap()
        .with_floor_db(-120.0)
        .unwrap();
    assert!(g.process(DEFAULT_FLOOR_DB - 5.0));
    assert!(StreamingGate::new(-1.0, 3.0, 0.01).is_err());
    assert!(StreamingGate::new(35.0, f32::NAN, 0.01).is_err());
    assert!(StreamingGate::new(35.0, 3.0, 0.0).is_err());
}

// ---------------------------------------------------------------------------------------------
// Tukey
// ---------------------------------------------------------------------------------------------

#[test]
fn quartiles_match_numpy_documented_values() {
    // np.percentile([1, 2, 3, 4], [25, 75]) -> [1.75, 3.25]
    assert_eq!(quartiles(&mut [4.0, 1.0, 3.0, 2.0]), Some((1.75, 3.25)));
    // np.percentile([10, 7, 4, 3, 2, 1], [25, 75]) -> [2.25, 6.25]
    assert_eq!(
        quartiles(&mut [10.0, 7.0, 4.0, 3.0, 2.0, 1.0]),
        Some((2.25, 6.25))
    );
    // np.percentile([1, 2], [25, 75]) -> [1.25, 1.75]; a single value is both quartiles.
    assert_eq!(quartiles(&mut [2.0, 1.0]), Some((1.25, 1.75)));
    assert_eq!(quartiles(&mut [5.0]), Some((5.0, 5.0)));
    // Non-finite values are ignored; none left -> None.
    assert_eq!(
        quartiles(&mut [f32::NAN, 4.0, 1.0, f32::INFINITY, 3.0, 2.0]),
        Some((1.75, 3.25))
    );
    assert_eq!(quartiles(&mut []), None);
    assert_eq!(quartiles(&mut [f32::NAN]), None);
    // Fences of [1, 2, 3, 4]: IQR 1.5 -> (1.75 - 2.25, 3.25 + 2.25).
    assert_eq!(fences(&[1.0, 2.0, 3.0, 4.0], 1.5), Some((-0.5, 5.5)));
    assert_eq!(fences(&[], 1.5), None);
    assert_eq!(fences(&[1.0], f32::NAN), None);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn quartiles_match_sort_oracle(v in proptest::collection::vec(-100.0f32..100.0, 1..400)) {
        let (q1, q3) = quartiles(&mut v.clone()).unwrap();
        // Both interpolate in f64 and differ at most by lerp rounding; 1e-4 covers the f32
        // rounding of values up to 100 (ulp 7.6e-6).
        prop_assert!((f64::from(q1) - np_quantile(&v, 0.25)).abs() < 1e-4);
        prop_assert!((f64::from(q3) - np_quantile(&v, 0.75)).abs() < 1e-4);
    }

    #[test]
    fn offline_rejection_matches_oracle(
        v in proptest::collection::vec(prop_oneof![Just(0.0f32), 30.0f32..2000.0], 0..300),
        k in prop_oneof![Just(0.0f32), Just(0.5f32), Just(1.5f32), Just(3.0f32)],
    ) {
        let st: Vec<f32> = v.iter().filter(|&&f| f > 0.0).map(|&f| hz_to_semitones(f)).collect();
        let mut got = v.clone();
        let n = reject_outliers_offline(&mut got, k);
        if !st.is_empty() {
            let fe = oracle_fences(&st, f64::from(k));
            for (g, &f) in got.iter().zip(&v) {
                if f == 0.0 {
                    prop_assert_eq!(*g, 0.0);
                    continue;
                }
                let s = f64::from(hz_to_semitones(f));
                let outlier = s < fe.0 || s > fe.1;
                if (*g == 0.0) != outlier {
                    prop_assert!(fence_gap(s, fe) < 1e-6, "{} vs fences {:?}", s, fe);
                } else {
                    prop_assert_eq!(*g, if outlier { 0.0 } else { f });
                }
            }
            let zeroed = got.iter().zip(&v).filter(|(g, f)| **f > 0.0 && **g == 0.0).count();
            prop_assert_eq!(n, zeroed);
        } else {
            prop_assert_eq!(n, 0);
        }
    }
}

#[test]
fn offline_rejection_removes_octave_jumps() {
    // A melody of 25-hop notes (MIDI 60 62 64 65 67 65 64 62) with 5 unvoiced hops between notes,
    // 5 times: quartiles ≈ 62 and 65, fences ≈ 57.5 and 69.5. Octave errors (×2 on the low notes:
    // ≥ 72; ×½ on the high notes: ≤ 55) lie outside; every real note lies inside.
    let notes = [60.0f32, 62.0, 64.0, 65.0, 67.0, 65.0, 64.0, 62.0];
    let mut f0 = Vec::new();
    for _ in 0..5 {
        for &n in &notes {
            f0.extend(std::iter::repeat_n(tactus_dsp::semitones_to_hz(n), 25));
            f0.extend(std::iter::repeat_n(0.0, 5));
        }
    }
    let clean = f0.clone();
    let mut outliers = Vec::new();
    for (i, f) in f0.iter_mut().enumerate() {
        if *f > 0.0 && i % 53 == 7 {
            let st = hz_to_semitones(*f);
            *f *= if st < 64.0 { 2.0 } else { 0.5 };
            outliers.push(i);
        }
    }
    assert!(outliers.len() >= 15, "{}", outliers.len());
    let mut got = f0.clone();
    let n = reject_outliers_offline(&mut got, TUKEY_K);
    assert_eq!(n, outliers.len());
    for (i, (&g, &c)) in got.iter().zip(&clean).enumerate() {
        let want = if outliers.contains(&i) { 0.0 } else { c };
        assert_eq!(g, want, "hop {i}");
    }
    // NaN / negative become unvoiced without counting as rejected.
    let mut odd = [f32::NAN, -3.0, 220.0, 0.0];
    assert_eq!(reject_outliers_offline(&mut odd, TUKEY_K), 0);
    assert_eq!(odd, [0.0, 0.0, 220.0, 0.0]);
}

#[test]
fn values_on_a_fence_are_kept() {
    // With k = 0 the fences are the quartiles themselves; here Q1 and Q3 are attained values
    // (four copies each of MIDI 60 and 62, so h = 1.75 and 5.25 fall between equal neighbours):
    // every value sits exactly on a fence and must survive; a value just outside must not.
    let (a, b) = (
        tactus_dsp::semitones_to_hz(60.0),
        tactus_dsp::semitones_to_hz(62.0),
    );
    let mut f0 = vec![a, a, a, a, b, b, b, b];
    assert_eq!(reject_outliers_offline(&mut f0, 0.0), 0);
    assert_eq!(f0, vec![a, a, a, a, b, b, b, b]);
    let mut t = SlidingTukey::new(8, 0.0, 8).unwrap();
    let out: Vec<f32> = [a, a, a, a, b, b, b, b, a, b]
        .iter()
        .map(|&f| t.process(f))
        .collect();
    assert_eq!(out[7..], [b, a, b]);
    let mut f0 = vec![a, a, a, a, b, b, b, b, b * 1.001];
    assert_eq!(reject_outliers_offline(&mut f0, 0.0), 1);
}

/// Naive sliding Tukey: keep the last W voiced semitone values, sort, numpy quartiles.
fn naive_sliding(input: &[f32], w: usize, k: f32, min_count: usize) -> Vec<(f32, Option<f64>)> {
    let mut win: VecDeque<f32> = VecDeque::new();
    input
        .iter()
        .map(|&f| {
            if !(f.is_finite() && f > 0.0) {
                return (0.0, None);
            }
            let s = hz_to_semitones(f);
            if win.len() == w {
                win.pop_front();
            }
            win.push_back(s);
            if win.len() < min_count {
                return (f, None);
            }
            let v: Vec<f32> = win.iter().copied().collect();
            let fe = oracle_fences(&v, f64::from(k));
            let s = f64::from(s);
            let out = if s < fe.0 || s > fe.1 { 0.0 } else { f };
            (out, Some(fence_gap(s, fe)))
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    #[test]
    fn sliding_tukey_matches_naive_window(
        input in proptest::collection::vec(
            prop_oneof![
                3 => 100.0f32..400.0,
                1 => 400.0f32..1600.0,
                1 => Just(0.0f32),
                1 => Just(f32::NAN),
                1 => Just(-1.0f32),
            ],
            0..400),
        w in 1usize..60,
        min_frac in 0.0f64..=1.0,
        k in prop_oneof![Just(0.0f32), Just(0.5f32), Just(1.5f32), Just(3.0f32)],
    ) {
        let min_count = ((w as f64) * min_frac) as usize;
        let mut t = SlidingTukey::new(w, k, min_count).unwrap();
        let want = naive_sliding(&input, w, k, min_count);
        let got: Vec<f32> = input.iter().map(|&f| t.process(f)).collect();
        for (i, (g, (wv, gap))) in got.iter().zip(&want).enumerate() {
            if g.to_bits() != wv.to_bits() {
                // Only a value sitting on a fence (within rounding) may be decided differently.
                prop_assert!(gap.is_some_and(|d| d < 1e-6), "hop {}: {} vs {}", i, g, wv);
            }
        }
        t.reset();
        let again: Vec<f32> = input.iter().map(|&f| t.process(f)).collect();
        prop_assert_eq!(
            got.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            again.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
    }
}

#[test]
fn sliding_tukey_rejects_octave_jump_after_warmup() {
    // Hops alternating 220 / 247 Hz (2 semitones apart: IQR ≈ 2, fences ≈ 54 .. 62) then one
    // 880 Hz hop (+24 semitones): rejected. Before `min_count` voiced hops it passes through.
    let mut t = SlidingTukey::new(100, TUKEY_K, 20).unwrap();
    let alt = |i: usize| if i.is_multiple_of(2) { 220.0 } else { 247.0 };
    for i in 0..18 {
        assert_eq!(t.process(alt(i)), alt(i));
    }
    assert_eq!(
        t.process(880.0),
        880.0,
        "19th voiced value: still warming up"
    );
    assert!(t.fences().is_none());
    t.process(220.0);
    assert!(t.fences().is_some());
    for i in 0..200 {
        assert_eq!(t.process(alt(i)), alt(i));
    }
    assert_eq!(t.process(880.0), 0.0);
    assert_eq!(t.process(0.0), 0.0);
    assert_eq!(t.count(), 100);
    assert!(SlidingTukey::new(0, 1.5, 0).is_err());
    assert!(SlidingTukey::new(10, 1.5, 11).is_err());
    assert!(SlidingTukey::new(10, -1.0, 1).is_err());
}

// ---------------------------------------------------------------------------------------------
// Discretizer
// ---------------------------------------------------------------------------------------------

#[test]
fn discretizer_semitones_by_hand() {
    // 100–400 Hz = 24 semitones; 8 levels of 3 semitones each.
    let d = Discretizer::new(8, Scale::Semitones).unwrap();
    let r = (100.0, 400.0);
    assert_eq!(d.level(100.0, r), 1);
    assert_eq!(d.level(399.0, r), 8);
    assert_eq!(d.level(400.0, r), 8);
    // 141.42 Hz = 100·2^(6/12) is the edge between levels 2 and 3 (half-open: edge goes up).
    assert_eq!(d.level(141.40, r), 2);
    assert_eq!(d.level(141.44, r), 3);
    assert_eq!(
        d.level(200.0, r),
        5,
        "exactly 12 semitones = t 0.5 -> lower edge of level 5"
    );
    // Every level's centre, 100·2^((3j + 1.5)/12), lands in level j + 1.
    for j in 0..8 {
        let f = 100.0 * 2f32.powf((3.0 * j as f32 + 1.5) / 12.0);
        assert_eq!(d.level(f, r), j as u8 + 1, "{f}");
    }
    // Clamped outside the range; the range may come reversed.
    assert_eq!(d.level(50.0, r), 1);
    assert_eq!(d.level(1000.0, r), 8);
    assert_eq!(d.level(399.0, (400.0, 100.0)), 8);
    // Unvoiced and NaN -> 0.
    for f in [0.0, -5.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        assert_eq!(d.level(f, r), 0, "{f}");
    }
    // lo == hi (and other degenerate ranges): every voiced pitch is level 1.
    for f in [100.0, 200.0, 300.0] {
        assert_eq!(d.level(f, (200.0, 200.0)), 1);
        assert_eq!(d.level(f, (f32::NAN, 200.0)), 1);
        assert_eq!(d.level(f, (0.0, 200.0)), 1);
    }
    assert_eq!(d.level(0.0, (200.0, 200.0)), 0);
    assert_eq!(Discretizer::default(), d);
}

#[test]
fn discretizer_linear_hz_and_level_counts() {
    // 100–400 Hz linear, 8 levels of 37.5 Hz.
    let d = Discretizer::new(8, Scale::LinearHz).unwrap();
    let r = (100.0, 400.0);
    assert_eq!(d.level(100.0, r), 1);
    assert_eq!(d.level(137.4, r), 1);
    assert_eq!(d.level(137.6, r), 2);
    assert_eq!(d.level(250.0, r), 5);
    assert_eq!(d.level(399.0, r), 8);
    assert_eq!(d.level(141.44, r), 2, "differs from the semitone scale's 3");
    assert_eq!(d.level(0.0, r), 0);
    // Linear mode accepts a range starting at 0 Hz.
    assert_eq!(d.level(399.0, (0.0, 400.0)), 8);
    assert!(Discretizer::new(0, Scale::Semitones).is_err());
    let one = Discretizer::new(1, Scale::Semitones).unwrap();
    assert!([100.0f32, 250.0, 400.0]
        .iter()
        .all(|&f| one.level(f, r) == 1));
    let many = Discretizer::new(255, Scale::Semitones).unwrap();
    assert_eq!(many.level(399.99, r), 255);
    assert_eq!(many.level(100.0, r), 1);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn discretizer_matches_edge_counting_oracle(
        f in 20.0f32..3000.0,
        lo in 30.0f32..500.0,
        span in 0.01f32..2000.0,
        levels in 1u8..=16,
        linear in any::<bool>(),
    ) {
        let hi = lo + span;
        let scale = if linear { Scale::LinearHz } else { Scale::Semitones };
        let d = Discretizer::new(levels, scale).unwrap();
        // Oracle: 1 + the number of inner edges at or below f, edges spaced equally in the scale.
        let (lo64, hi64, f64v) = (f64::from(lo), f64::from(hi), f64::from(f));
        let mut want = 1u8;
        let mut near_edge = false;
        for j in 1..levels {
            let frac = f64::from(j) / f64::from(levels);
            let edge = if linear { lo64 + (hi64 - lo64) * frac } else { lo64 * (hi64 / lo64).powf(frac) };
            if f64v >= edge { want += 1; }
            near_edge |= (f64v - edge).abs() < 1e-9 * edge;
        }
        if !near_edge {
            prop_assert_eq!(d.level(f, (lo, hi)), want);
        }
    }
}

#[test]
fn ranges_offline_and_running() {
    let f0 = [0.0, 200.0, f32::NAN, 100.0, -1.0, 300.0, 0.0, f32::INFINITY];
    assert_eq!(range_offline(&f0), Some((100.0, 300.0)));
    assert_eq!(range_offline(&[0.0, f32::NAN]), None);
    assert_eq!(range_offline(&[]), None);
    let mut r = RunningRange::new();
    let seen: Vec<_> = f0.iter().map(|&f| r.update(f)).collect();
    assert_eq!(
        seen,
        vec![
            None,
            Some((200.0, 200.0)),
            Some((200.0, 200.0)),
            Some((100.0, 200.0)),
            Some((100.0, 200.0)),
            Some((100.0, 300.0)),
            Some((100.0, 300.0)),
            Some((100.0, 300.0)),
        ]
    );
    r.reset();
    assert_eq!(r.get(), None);
}

// ---------------------------------------------------------------------------------------------
// Binners
// ---------------------------------------------------------------------------------------------

/// Naive level binning: group hops 0..n by (i·hop)/bin, majority voicing, lower median.
/// `levels[i] = None` marks a skipped hop (unvoiced).
fn naive_bins(levels: &[Option<u8>], hop: usize, bin: usize) -> Vec<u8> {
    let n = levels.len();
    if n == 0 {
        return vec![];
    }
    let nbins = (n - 1) * hop / bin + 1;
    (0..nbins)
        .map(|b| {
            let members: Vec<u8> = (0..n)
                .filter(|&i| i * hop / bin == b)
                .map(|i| levels[i].unwrap_or(0))
                .collect();
            let mut voiced: Vec<u8> = members.iter().copied().filter(|&l| l > 0).collect();
            if voiced.len() * 2 > members.len() {
                voiced.sort();
                voiced[(voiced.len() - 1) / 2]
            } else {
                0
            }
        })
        .collect()
}

fn naive_beats(onsets: &[Option<bool>], hop: usize, bin: usize) -> Vec<bool> {
    let n = onsets.len();
    if n == 0 {
        return vec![];
    }
    let nbins = (n - 1) * hop / bin + 1;
    (0..nbins)
        .map(|b| (0..n).any(|i| i * hop / bin == b && onsets[i] == Some(true)))
        .collect()
}

/// Pushes the non-skipped hops (the last hop is always pushed) and checks order and timing.
fn stream_levels(b: &mut LevelBinner, levels: &[Option<u8>], hop: usize, bin: usize) -> Vec<u8> {
    let mut out: Vec<u8> = Vec::new();
    for (i, l) in levels.iter().enumerate() {
        let Some(l) = *l else { continue };
        let mut emitted = Vec::new();
        b.push(i, l, &mut |bi, v| emitted.push((bi, v)));
        for (bi, v) in emitted {
            assert_eq!(bi, out.len(), "bins in order, each once");
            out.push(v);
        }
        // Causality and promptness: after hop i, every earlier bin is out, and bin(i) is out
        // exactly when hop i is its last hop.
        let bi = i * hop / bin;
        let last_of_bin = (i + 1) * hop / bin > bi;
        assert_eq!(out.len(), bi + last_of_bin as usize, "after hop {i}");
    }
    b.finish(&mut |bi, v| {
        assert_eq!(bi, out.len());
        out.push(v)
    });
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn level_binner_matches_naive(
        raw in proptest::collection::vec((0u8..=8, 0u8..10), 0..300),
        hop in 1usize..60,
        bin in 1usize..200,
    ) {
        // 20% skipped hops, then a mix of voiced and unvoiced levels; the last hop is pushed.
        let mut levels: Vec<Option<u8>> =
            raw.iter().map(|&(l, s)| if s < 2 { None } else { Some(if s < 5 { 0 } else { l }) }).collect();
        if let Some(last) = levels.last_mut() {
            last.get_or_insert(0);
        }
        let want = naive_bins(&levels, hop, bin);
        let mut b = LevelBinner::new(hop, bin).unwrap();
        let got = stream_levels(&mut b, &levels, hop, bin);
        prop_assert_eq!(&got, &want);
        // reset() reproduces, also after a partial run.
        b.reset();
        for (i, l) in levels.iter().enumerate().take(levels.len() / 2) {
            if let Some(l) = l { b.push(i, *l, &mut |_, _| {}); }
        }
        b.reset();
        prop_assert_eq!(&stream_levels(&mut b, &levels, hop, bin), &want);
        // Offline convenience (no skips).
        let dense: Vec<u8> = levels.iter().map(|l| l.unwrap_or(0)).collect();
        prop_assert_eq!(bin_levels(&dense, hop, bin), want);
    }

    #[test]
    fn beat_binner_matches_naive(
        raw in proptest::collection::vec(0u8..10, 0..300),
        hop in 1usize..60,
        bin in 1usize..200,
        chunk in 1usize..50,
    ) {
        let mut onsets: Vec<Option<bool>> =
            raw.iter().map(|&s| if s < 2 { None } else { Some(s == 9) }).collect();
        if let Some(last) = onsets.last_mut() {
            last.get_or_insert(false);
        }
        let want = naive_beats(&onsets, hop, bin);
        let mut b = BeatBinner::new(hop, bin).unwrap();
        let mut got = Vec::new();
        // The engine pushes hops in chunks as blocks of audio complete them.
        let idx: Vec<usize> = (0..onsets.len()).filter(|&i| onsets[i].is_some()).collect();
        for c in idx.chunks(chunk) {
            for &i in c {
                b.push(i, onsets[i].unwrap(), &mut |bi, v| { assert_eq!(bi, got.len()); got.push(v) });
            }
        }
        b.finish(&mut |bi, v| { assert_eq!(bi, got.len()); got.push(v) });
        prop_assert_eq!(&got, &want);
        let dense: Vec<bool> = onsets.iter().map(|o| o.unwrap_or(false)).collect();
        prop_assert_eq!(bin_beats(&dense, hop, bin), want);
    }
}

#[test]
fn binner_by_hand() {
    // 10 ms hops, 100 ms bins at 44.1 kHz: 10 hops per bin.
    let levels = [
        3, 3, 5, 5, 0, 7, 5, 0, 3, 3, /* bin 1: 4 voiced of 10 */ 1, 0, 2, 0, 3, 0, 4, 0, 0,
        0, /* partial: 2 of 3 */ 6, 2, 0,
    ];
    // bin 0: voiced [3,3,5,5,7,5,3,3] (8 > 5) sorted 3,3,3,3,5,5,5,7 -> lower median 3
    assert_eq!(bin_levels(&levels, 441, 4410), vec![3, 0, 2]);
    // Bin not a multiple of the hop: hop 3, bin 4 -> bin of hop i is i*3/4: 0,0,1,2,3,3.
    // bins: [1, 2] -> 1, [3] -> 3, [4] -> 4, [0, 6] -> 1 of 2 voiced is not a majority -> 0.
    assert_eq!(bin_levels(&[1, 2, 3, 4, 0, 6], 3, 4), vec![1, 3, 4, 0]);
    // Hop longer than the bin: empty bins are 0 / false.
    assert_eq!(bin_levels(&[4, 5], 10, 4), vec![4, 0, 5]);
    assert_eq!(
        bin_beats(&[true, false, true], 10, 4),
        vec![true, false, false, false, false, true]
    );
    assert_eq!(bin_levels(&[], 441, 4410), Vec::<u8>::new());
    assert_eq!(bin_levels(&[1], 0, 4410), Vec::<u8>::new());
    assert!(LevelBinner::new(0, 1).is_err() && BeatBinner::new(1, 0).is_err());
    // i·hop overflowing u64 still bins exactly (2^30 · 2^40 = 2^70).
    let big = LevelBinner::new(1 << 40, 3 << 20).unwrap();
    assert_eq!(big.bin_of(1 << 30), (1usize << 50) / 3);
    assert_eq!(big.bin_of(7), (7usize << 40) / (3 << 20));
    // A repeated or backward index is ignored.
    let mut b = LevelBinner::new(1, 2).unwrap();
    let mut out = Vec::new();
    for (i, l) in [(0, 4), (0, 1), (1, 4), (1, 1)] {
        b.push(i, l, &mut |bi, v| out.push((bi, v)));
    }
    assert_eq!(out, vec![(0, 4)]);
}

// ---------------------------------------------------------------------------------------------
// No allocation after construction
// ---------------------------------------------------------------------------------------------

#[test]
fn no_allocation_in_hot_paths() {
    // The counter works: a Vec allocates.
    assert!(allocs_during(|| drop(std::hint::black_box(vec![1u8; 10]))) >= 1);

    let x = noise(44_100, 7);
    let mut rms = Rms::new(2048, 441).unwrap();
    let mut gate = StreamingGate::new(GATE_BELOW_DB, 3.0, 0.01).unwrap();
    let mut tukey = SlidingTukey::new(300, TUKEY_K, 50).unwrap();
    let disc = Discretizer::default();
    let mut range = RunningRange::new();
    let mut lb = LevelBinner::new(441, 4410).unwrap();
    let mut bb = BeatBinner::new(441, 4410).unwrap();
    let mut bins = [0u8; 64];
    let mut beats = [false; 64];
    let mut hops = 0usize;
    let n = allocs_during(|| {
        let mut per_hop = |i: usize, db: f32| {
            let open = gate.process(db);
            let f0 = if open {
                100.0 + (i % 37) as f32 * 10.0
            } else {
                0.0
            };
            let f0 = tukey.process(if i.is_multiple_of(29) { f0 * 4.0 } else { f0 });
            let r = range.update(f0).unwrap_or((0.0, 0.0));
            let level = disc.level(f0, r);
            lb.push(i, level, &mut |b, v| bins[b % 64] = v);
            bb.push(i, i.is_multiple_of(13) && open, &mut |b, v| {
                beats[b % 64] = v
            });
            hops += 1;
        };
        for c in x.chunks(300) {
            rms.process(c, &mut per_hop);
        }
        rms.finish(&mut per_hop);
        lb.finish(&mut |b, v| bins[b % 64] = v);
        bb.finish(&mut |b, v| beats[b % 64] = v);
        rms.reset();
        gate.reset();
        tukey.reset();
        lb.reset();
        bb.reset();
    });
    assert_eq!(n, 0, "allocations in process/push/finish/reset");
    assert_eq!(hops, 100);
    assert!(bins.iter().any(|&b| b > 0) && beats.iter().any(|&b| b));
}
