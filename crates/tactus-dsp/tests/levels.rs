//! Tests for the "levels that follow the truth" pieces and pitch note onsets: Tukey fences
//! with an IQR floor, the streaming range prior, the quantile range, and note onsets from a
//! pitch track (against an obvious offline oracle, streaming = offline, stated latency).

use tactus_dsp::discretize::{
    agree_mask, held_mask, narrow_range, pitches_agree, range_offline, range_quantiles,
    range_quantiles_held, range_quantiles_kept, range_quantiles_kept_or,
    range_quantiles_kept_or_sure, shadow_mask, HeldRange, PriorRange, QuantileRange, RangePrior,
    MAX_SHADOW_HOPS, SHADOW_TOL_ST,
};
use tactus_dsp::notes::{note_onsets_offline, NoteConfig, NoteOnsets};
use tactus_dsp::tukey::{reject_outliers_offline, reject_outliers_offline_min_iqr, SlidingTukey};
use tactus_dsp::{hz_to_semitones, semitones_to_hz};

#[global_allocator]
static A: tactus_testkit::Counting = tactus_testkit::Counting;

fn hz(st: f32) -> f32 {
    semitones_to_hz(st)
}

#[test]
fn iqr_floor_keeps_a_real_leap_that_the_paper_rule_cuts() {
    // A bass line on two neighbouring notes with a few real octave leaps.
    let mut f: Vec<f32> = (0..200).map(|i| hz(40.0 + (i % 2) as f32)).collect();
    f.extend((0..10).map(|_| hz(52.0)));
    let mut paper = f.clone();
    assert_eq!(
        reject_outliers_offline(&mut paper, 1.5),
        10,
        "paper: IQR 1 → fences ±1.5"
    );
    let mut floored = f.clone();
    assert_eq!(reject_outliers_offline_min_iqr(&mut floored, 1.5, 12.0), 0);
    // A floor of 0 is the paper's rule exactly.
    let mut zero = f.clone();
    reject_outliers_offline_min_iqr(&mut zero, 1.5, 0.0);
    assert_eq!(zero, paper);
    // Streaming: the same decision once the window is warm.
    let mut st = SlidingTukey::new(1000, 1.5, 20).unwrap().with_min_iqr(12.0);
    let out: Vec<f32> = f.iter().map(|&x| st.process(x)).collect();
    assert!(out.iter().all(|&x| x > 0.0));
    let mut st = SlidingTukey::new(1000, 1.5, 20).unwrap();
    let out: Vec<f32> = f.iter().map(|&x| st.process(x)).collect();
    assert!(out[200..].iter().all(|&x| x == 0.0));
}

#[test]
fn prior_range_pads_then_fades() {
    let mut r = PriorRange::new(20.0, 100.0).unwrap();
    assert_eq!(r.update(0.0), None);
    // One note: padded to 20 semitones around it (weight 100/101).
    let (lo, hi) = r.update(hz(40.0)).unwrap();
    let span = hz_to_semitones(hi) - hz_to_semitones(lo);
    assert!((span - 20.0 * 100.0 / 101.0).abs() < 1e-3, "span {span}");
    assert!((hz_to_semitones(lo) + hz_to_semitones(hi) - 80.0).abs() < 1e-3);
    // Many hops later the padding has faded towards the line's own range.
    for i in 0..10_000 {
        r.update(hz(38.0 + (i % 5) as f32));
    }
    let (lo, hi) = r.get().unwrap();
    let span = hz_to_semitones(hi) - hz_to_semitones(lo);
    assert!(span > 4.0 && span < 4.2, "span {span}");
    // A line wider than the prior is not padded.
    let mut r = PriorRange::new(5.0, f32::INFINITY).unwrap();
    r.update(hz(30.0));
    let (lo, hi) = r.update(hz(50.0)).unwrap();
    assert!((hz_to_semitones(lo) - 30.0).abs() < 1e-3 && (hz_to_semitones(hi) - 50.0).abs() < 1e-3);
    r.reset();
    assert_eq!(r.get(), None);
    assert!(PriorRange::new(-1.0, 1.0).is_err() && PriorRange::new(1.0, 0.0).is_err());
}

#[test]
fn quantile_range_ignores_rare_extremes() {
    let mut f: Vec<f32> = (0..1000).map(|i| 40.0 + (i % 7) as f32 * 10.0).collect();
    f.extend([0.0, -1.0, f32::NAN, 5.0, 900.0]);
    assert_eq!(range_quantiles(&f, 0.0), range_offline(&f));
    assert_eq!(range_quantiles(&f, 0.01), Some((40.0, 100.0)));
    assert_eq!(range_quantiles(&[0.0, f32::NAN], 0.01), None);
}

/// A deterministic pitch line with rare octave errors, unvoiced gaps and junk values.
fn wandering_line(n: usize, seed: u64) -> Vec<f32> {
    let mut x = seed | 1;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..n)
        .map(|_| {
            let u = next();
            if u < 0.05 {
                [0.0, f32::NAN, -3.0, f32::INFINITY][(u * 80.0) as usize % 4]
            } else if u < 0.07 {
                hz(60.0 + 12.0 * (next() * 3.0).floor() as f32) // octave errors up
            } else {
                hz(36.0 + (next() * 14.0) as f32 + 0.3 * next() as f32)
            }
        })
        .collect()
}

#[test]
fn running_quantile_range_brackets_the_exact_quantiles_of_the_prefix_within_one_cell() {
    // Oracle: `range_quantiles` on every prefix (sort and index). The running range must
    // contain the exact quantiles and exceed them by less than one 1/8-semitone cell.
    for (seed, p) in [(1u64, 0.01f32), (2, 0.05), (3, 0.0), (4, 0.5)] {
        let f = wandering_line(3000, seed);
        let mut q = QuantileRange::new(p);
        for (i, &x) in f.iter().enumerate() {
            let got = q.update(x);
            let want = range_quantiles(&f[..=i], p);
            match (got, want) {
                (None, None) => {}
                (Some((lo, hi)), Some((wlo, whi))) => {
                    assert!(
                        lo <= wlo && hi >= whi,
                        "hop {i} p {p}: {lo}..{hi} vs {wlo}..{whi}"
                    );
                    let cell = 1.0 / 8.0 + 1e-4;
                    assert!(
                        hz_to_semitones(wlo) - hz_to_semitones(lo) < cell
                            && hz_to_semitones(hi) - hz_to_semitones(whi) < cell,
                        "hop {i} p {p}: {lo}..{hi} vs {wlo}..{whi}"
                    );
                }
                (g, w) => panic!("hop {i}: {g:?} vs {w:?}"),
            }
        }
    }
}

#[test]
fn running_quantile_range_is_the_exact_min_max_until_the_quantile_cuts_and_then_drops_a_rare_octave_error(
) {
    let mut q = QuantileRange::new(0.01);
    assert_eq!(q.update(0.0), None);
    // Fewer than 51 values: k = round((n − 1)·0.01) = 0, the exact min and max.
    let f: Vec<f32> = (0..50).map(|i| 80.0 + i as f32 * 0.37).collect();
    for (i, &x) in f.iter().enumerate() {
        assert_eq!(q.update(x), range_offline(&f[..=i]));
    }
    // One early octave error: kept by the running max, dropped by the quantile once
    // enough of the line has been seen (it is 1 of 400 values).
    q.update(400.0);
    for i in 0..400 {
        q.update(80.0 + (i % 50) as f32 * 0.37);
    }
    let (lo, hi) = q.get().unwrap();
    assert!(lo >= 80.0 * 0.99 && hi < 100.0, "{lo}..{hi}");
    q.reset();
    assert_eq!(q.get(), None);
    // Extremes outside the cells' 16 Hz–16 kHz share the end cells but keep their values.
    let mut q = QuantileRange::new(0.0);
    q.update(3.0);
    assert_eq!(q.update(40_000.0), Some((3.0, 40_000.0)));
}

#[test]
fn prior_range_with_quantile_pads_the_quantile_range() {
    // Same padding rule as the min/max prior, applied to the quantile range: on a line
    // without outliers (fewer than 51 values) the two agree exactly.
    let mut a = PriorRange::new(20.0, 300.0).unwrap();
    let mut b = PriorRange::with_quantile(20.0, 300.0, 0.01).unwrap();
    for i in 0..50 {
        let x = hz(40.0 + (i % 9) as f32);
        assert_eq!(a.update(x), b.update(x));
    }
    // After an octave error and enough of the line, the quantile prior is the line's own
    // 9 semitones padded by (20 − 8)·w/2 with w = 300/851 (2.1 semitones each side); the
    // min/max prior keeps the error (30 semitones, no padding).
    a.update(hz(70.0));
    b.update(hz(70.0));
    for i in 0..500 {
        let x = hz(40.0 + (i % 9) as f32);
        a.update(x);
        b.update(x);
    }
    let (alo, ahi) = a.get().unwrap();
    let (blo, bhi) = b.get().unwrap();
    assert!((hz_to_semitones(ahi) - 70.0).abs() < 1e-3, "{alo}..{ahi}");
    let pad = 12.0 * 300.0 / 851.0 / 2.0;
    assert!(
        (hz_to_semitones(blo) - (40.0 - pad)).abs() < 1e-3
            && (hz_to_semitones(bhi) - (48.0 + pad)).abs() < 1e-3,
        "{blo}..{bhi}"
    );
    b.reset();
    assert_eq!(b.get(), None);
    assert!(PriorRange::with_quantile(20.0, 1.0, 0.6).is_err());
    assert!(PriorRange::with_quantile(20.0, 1.0, f32::NAN).is_err());
}

/// The obvious rule: for every hop, look at the next `stable` hops directly.
fn oracle(f0: &[f32], c: NoteConfig) -> Vec<bool> {
    let st: Vec<Option<f32>> = f0
        .iter()
        .map(|&f| (f > 0.0).then(|| hz_to_semitones(f)))
        .collect();
    let mut out = vec![false; f0.len()];
    let mut cur: Option<f32> = None;
    let mut unv = usize::MAX / 2;
    for j in 0..f0.len() {
        let Some(x) = st[j] else {
            unv = unv.saturating_add(1);
            if unv > c.gap_hops {
                cur = None;
            }
            continue;
        };
        unv = 0;
        if j + c.stable_hops > f0.len() {
            continue;
        }
        let w: Option<Vec<f32>> = st[j..j + c.stable_hops].iter().copied().collect();
        let Some(mut w) = w else { continue };
        w.sort_by(f32::total_cmp);
        let med = w[(w.len() - 1) / 2];
        if w.iter().any(|v| (v - med).abs() > c.tolerance_st) {
            continue;
        }
        match cur {
            Some(c0) if (x - c0).abs() < c.jump_st => cur = Some(c0 + 0.03 * (med - c0)),
            _ => {
                out[j] = true;
                cur = Some(med);
            }
        }
    }
    out
}

/// A melody at 10 ms hops: notes with vibrato and scoops, gaps, a glide and octave leaps.
fn melody() -> (Vec<f32>, Vec<usize>) {
    let mut f = Vec::new();
    let mut starts = Vec::new();
    let notes: [(f32, usize, usize); 7] = [
        (60.0, 30, 0),
        (62.0, 25, 5),
        (62.0, 20, 0),
        (67.0, 40, 3),
        (55.0, 15, 0),
        (67.0, 30, 10),
        (43.0, 8, 2),
    ];
    for (k, &(st, len, gap)) in notes.iter().enumerate() {
        starts.push(f.len());
        for i in 0..len {
            // ±35 cent vibrato at 5.5 Hz from hop 15, a −40 cent scoop over the first 5 hops.
            // As the corpus sings: vibrato from 150 ms into the note.
            let vib = if i >= 15 {
                0.35 * (std::f32::consts::TAU * 5.5 * i as f32 * 0.01 + k as f32).sin()
            } else {
                0.0
            };
            let scoop = if i < 5 {
                -0.4 * (1.0 - i as f32 / 5.0)
            } else {
                0.0
            };
            f.push(hz(st + vib + scoop));
        }
        f.extend(std::iter::repeat_n(0.0, gap));
    }
    (f, starts)
}

#[test]
fn note_onsets_match_the_oracle_and_the_notes() {
    let (f, starts) = melody();
    let c = NoteConfig::pitch_only();
    let got = note_onsets_offline(&f, c).unwrap();
    assert_eq!(got, oracle(&f, c));
    let on: Vec<usize> = (0..f.len()).filter(|&i| got[i]).collect();
    // Every note (the repeated 62 follows a 50 ms gap) starts within 3 hops of its true
    // start, and nothing else fires: vibrato and scoops stay inside their notes.
    let expect = starts;
    assert_eq!(on.len(), expect.len(), "onsets {on:?} vs {expect:?}");
    for (a, b) in on.iter().zip(&expect) {
        assert!(a.abs_diff(*b) <= 3, "onset {a} vs note start {b}");
    }
}

#[test]
fn streaming_note_onsets_equal_offline_with_the_stated_latency() {
    let (f, _) = melody();
    let c = NoteConfig {
        stable_hops: 6,
        ..NoteConfig::pitch_only()
    };
    let want = note_onsets_offline(&f, c).unwrap();
    let mut d = NoteOnsets::new(c).unwrap();
    let mut got = Vec::new();
    for (i, &x) in f.iter().enumerate() {
        d.push(x, &mut |j, o| {
            assert_eq!(j + d_lat(c), i, "hop {j} decided at hop {i}");
            got.push(o);
        });
    }
    d.finish(&mut |_, o| got.push(o));
    assert_eq!(got, want);
    d.reset();
    let mut again = Vec::new();
    for &x in &f {
        d.push(x, &mut |_, o| again.push(o));
    }
    d.finish(&mut |_, o| again.push(o));
    assert_eq!(again, want);
    assert!(NoteOnsets::new(NoteConfig {
        stable_hops: 0,
        ..c
    })
    .is_err());
}

fn d_lat(c: NoteConfig) -> usize {
    c.stable_hops - 1
}

/// Held hops of `f` by the module docs' words, written out: hop `i` is held when hops
/// `i − k ..= i + k` all exist, are voiced and lie within `tol` semitones of hop `i`.
fn held_by_hand(f: &[f32], k: usize, tol: f32) -> Vec<bool> {
    let st = |x: f32| (x.is_finite() && x > 0.0).then(|| hz_to_semitones(x));
    (0..f.len())
        .map(|i| {
            let Some(c) = st(f[i]) else { return false };
            if k == 0 {
                return true;
            }
            if i < k || i + k >= f.len() {
                return false;
            }
            let mut ok = true;
            for x in &f[i - k..=i + k] {
                match st(*x) {
                    Some(v) if (v - c).abs() <= tol => {}
                    _ => ok = false,
                }
            }
            ok
        })
        .collect()
}

/// Runs of tracker errors in a wandering bass line of notes (10–40 hops, 40–53 semitones),
/// with rests and, every `junk_every` hops, the wandering line's junk values.
struct ErrorRuns {
    /// The run comes before its note (a note change) rather than after it.
    before: bool,
    prob: f64,
    min_len: usize,
    span: f64,
    offset_st: f32,
    jitter_st: f32,
    jitter_centre: f32,
    junk_salt: u64,
    junk_every: usize,
    junk_at: usize,
}

fn line_with_error_runs(n: usize, seed: u64, e: &ErrorRuns) -> Vec<f32> {
    let junk = wandering_line(n, seed ^ e.junk_salt);
    let mut x = seed | 1;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut f = Vec::with_capacity(n);
    let run =
        |f: &mut Vec<f32>, note: f32, next: &mut dyn FnMut() -> f64| {
            if next() < e.prob {
                let len = e.min_len + (next() * e.span) as usize;
                f.extend((0..len).map(|_| {
                    hz(note + e.offset_st + e.jitter_st * (next() as f32 - e.jitter_centre))
                }));
            }
        };
    while f.len() < n {
        let note = 40.0 + (next() * 14.0).floor() as f32;
        if e.before {
            run(&mut f, note, &mut next);
        }
        let len = 10 + (next() * 30.0) as usize;
        f.extend((0..len).map(|_| hz(note + 0.4 * (next() as f32 - 0.5))));
        if !e.before {
            run(&mut f, note, &mut next);
        }
        if next() < 0.3 {
            f.extend(std::iter::repeat_n(0.0, (next() * 10.0) as usize));
        }
    }
    f.truncate(n);
    for (i, v) in f.iter_mut().enumerate() {
        if i % e.junk_every == e.junk_at {
            *v = junk[i];
        }
    }
    f
}

/// A bass line whose changes carry, now and then, a run of 4–12 hops at the common
/// subharmonic (19 semitones below) as the harmonic-sum tracker reports it.
fn line_with_transition_errors(n: usize, seed: u64) -> Vec<f32> {
    let e = ErrorRuns {
        before: true,
        prob: 0.4,
        min_len: 4,
        span: 9.0,
        offset_st: -19.0,
        jitter_st: 0.3,
        jitter_centre: 0.0,
        junk_salt: 0x5eed,
        junk_every: 37,
        junk_at: 5,
    };
    line_with_error_runs(n, seed, &e)
}

#[test]
fn held_mask_and_the_offline_held_range_follow_the_definition() {
    for seed in 1..6u64 {
        let f = line_with_transition_errors(2000, seed);
        for (k, tol) in [(0usize, 1.0f32), (1, 0.5), (5, 1.0), (16, 2.0)] {
            let want = held_by_hand(&f, k, tol);
            assert_eq!(held_mask(&f, k, tol), want, "seed {seed} k {k}");
            for (share, min_hops) in [(0.25f32, 300u64), (0.99, 1), (0.0, 5000)] {
                let (held, _, use_held) = held_rule_by_hand(&f, &want, share, min_hops);
                let want = if use_held {
                    range_quantiles(&held, 0.01)
                } else {
                    range_quantiles(&f, 0.01)
                };
                assert_eq!(
                    range_quantiles_held(&f, 0.01, k, tol, share, min_hops),
                    want,
                    "seed {seed} k {k} share {share} min {min_hops}"
                );
            }
        }
    }
}

/// The prior's padding by its definition (module docs), in semitones: the exact range `r`
/// after `n` voiced hops, with the weight `w = fade / (fade + n)`.
fn padded_by_hand(
    prior: RangePrior,
    fade: f32,
    r: Option<(f32, f32)>,
    n: usize,
) -> Option<(f64, f64)> {
    r.map(|(lo, hi)| {
        let (lo, hi) = (hz_to_semitones(lo) as f64, hz_to_semitones(hi) as f64);
        let w = fade as f64 / (fade as f64 + n as f64);
        match prior {
            RangePrior::Span(span) => {
                let pad = (span as f64 - (hi - lo)).max(0.0) * w / 2.0;
                (lo - pad, hi + pad)
            }
            RangePrior::Register(rlo, rhi) => {
                let (rlo, rhi) = (hz_to_semitones(rlo) as f64, hz_to_semitones(rhi) as f64);
                (lo - w * (lo - rlo).max(0.0), hi + w * (rhi - hi).max(0.0))
            }
        }
    })
}

#[test]
fn streaming_held_range_is_the_padded_quantile_range_of_the_held_prefix_within_one_cell() {
    // Oracle at every hop j: the held hops of the prefix (their windows inside it), their
    // exact quantiles, padded by the prior's formula with n = the prefix's voiced hops; the
    // plain quantiles of every voiced hop when the held ones are fewer than `min_hops` or
    // `share` of the voiced. The running range is within one 1/8-semitone cell of it. Both
    // priors: the span, and a register that the line crosses at the top (46–53 of 21–54
    // semitones), so that one end is pulled and the other is kept.
    for prior in [
        RangePrior::Span(20.0),
        RangePrior::Register(hz(30.0), hz(50.0)),
    ] {
        check_held_range(prior);
    }
}

fn check_held_range(prior: RangePrior) {
    let (fade, p) = (300.0f32, 0.01f32);
    let padded = |r: Option<(f32, f32)>, n: usize| padded_by_hand(prior, fade, r, n);
    for seed in 1..5u64 {
        let f = line_with_transition_errors(1500, seed);
        for (k, tol, share, min_hops) in [
            (5usize, 1.0f32, 0.25f32, 300u64),
            (2, 0.5, 0.5, 1),
            (0, 1.0, 0.25, 300),
        ] {
            let mut r = HeldRange::with_prior(prior, fade, p, k, tol, share, min_hops).unwrap();
            let mut plain = PriorRange::with_prior(prior, fade, p).unwrap();
            let mut used_held = false;
            for j in 0..f.len() {
                let got = r.update(f[j]);
                let pl = plain.update(f[j]);
                if k == 0 {
                    assert_eq!(got, pl, "k = 0 is the plain prior range");
                    continue;
                }
                let pre = &f[..=j];
                let m = held_by_hand(pre, k, tol);
                let (held, voiced, use_held) = held_rule_by_hand(pre, &m, share, min_hops);
                used_held |= use_held;
                let want = padded(
                    range_quantiles(if use_held { &held } else { pre }, p),
                    voiced,
                );
                assert_within_a_cell(got, want, &format!("{prior:?} seed {seed} k {k} hop {j}"));
            }
            if k > 0 {
                assert!(
                    used_held,
                    "seed {seed} k {k}: the held range was never used"
                );
            }
        }
    }
}

#[test]
fn held_range_ignores_the_subharmonic_at_note_changes_without_allocating() {
    // The line spans 40–53 semitones; every change starts with 8 hops 19 semitones low (the
    // common subharmonic of the two notes): 8 of 38 hops, far beyond the 1 % quantile.
    let mut f = Vec::new();
    for i in 0..60 {
        let note = 40.0 + [0.0, 7.0, 13.0, 5.0][i % 4];
        f.extend(std::iter::repeat_n(hz(note - 19.0), 8));
        f.extend(std::iter::repeat_n(hz(note), 30));
    }
    let (lo, _) = range_quantiles(&f, 0.01).unwrap();
    assert!(
        (hz_to_semitones(lo) - 21.0).abs() < 0.01,
        "the plain range reaches the errors"
    );
    let (lo, hi) = range_quantiles_held(&f, 0.01, 5, 1.0, 0.25, 300).unwrap();
    assert!(
        (hz_to_semitones(lo) - 40.0).abs() < 0.01 && (hz_to_semitones(hi) - 53.0).abs() < 0.01,
        "{lo}..{hi}"
    );
    let mut r = HeldRange::new(20.0, 1.0, 0.01, 5, 1.0, 0.25, 300).unwrap();
    let mut last = None;
    let allocs = tactus_testkit::allocations_during(|| {
        for &x in &f {
            last = r.update(x);
        }
    });
    assert_eq!(allocs, 0);
    let (lo, hi) = last.unwrap();
    assert!(
        (hz_to_semitones(lo) - 40.0).abs() < 0.2 && (hz_to_semitones(hi) - 53.0).abs() < 0.2,
        "{lo}..{hi}"
    );
    r.reset();
    assert_eq!(r.update(0.0), None);
    assert!(HeldRange::new(20.0, 1.0, 0.01, 17, 1.0, 0.25, 1).is_err());
    assert!(HeldRange::new(20.0, 1.0, 0.01, 5, -1.0, 0.25, 1).is_err());
    assert!(HeldRange::new(20.0, 1.0, 0.01, 5, 1.0, 1.5, 1).is_err());
}

#[test]
fn register_prior_starts_at_the_register_and_gives_way_to_the_line() {
    // A bass line that opens on its lowest note (E2, 40) and climbs to C4 (60) after 400
    // voiced hops, inside the register E1–D4 (28–62). Fade 100.
    let (rlo, rhi, fade) = (28.0f32, 62.0f32, 100.0f32);
    let mut r = PriorRange::with_prior(RangePrior::Register(hz(rlo), hz(rhi)), fade, 0.01).unwrap();
    assert_eq!(r.update(0.0), None);
    // One note: w = 100/101 of the way from the note to each edge.
    let (lo, hi) = r.update(hz(40.0)).unwrap();
    let w = 100.0 / 101.0;
    assert!(
        (hz_to_semitones(lo) - (40.0 - w * 12.0)).abs() < 1e-3,
        "{lo}"
    );
    assert!(
        (hz_to_semitones(hi) - (40.0 + w * 22.0)).abs() < 1e-3,
        "{hi}"
    );
    // The first note sits low in the register (level 2 of 8), where a span prior centred on
    // it puts it in the middle.
    let d = tactus_dsp::discretize::Discretizer::default();
    assert_eq!(d.level(hz(40.0), (lo, hi)), 3);
    let mut s = PriorRange::with_prior(RangePrior::Span(20.0), fade, 0.01).unwrap();
    assert_eq!(d.level(hz(40.0), s.update(hz(40.0)).unwrap()), 5);
    for _ in 0..399 {
        r.update(hz(40.0));
    }
    // 400 voiced hops: a fifth of the way left.
    let (_, hi) = r.get().unwrap();
    assert!(
        (hz_to_semitones(hi) - (40.0 + 22.0 * 0.2)).abs() < 1e-3,
        "{hi}"
    );
    // An end beyond the register is kept: a low B0 (23) and a high F4 (65), each more than
    // the 1 % that the quantile cuts.
    for _ in 0..10 {
        r.update(hz(23.0));
    }
    for _ in 0..100 {
        r.update(hz(65.0));
    }
    let (lo, hi) = r.get().unwrap();
    assert!(
        (hz_to_semitones(lo) - 23.0).abs() < 1e-3 && (hz_to_semitones(hi) - 65.0).abs() < 1e-3,
        "{lo}..{hi}"
    );
    // The prior fades to the line's own range, which it never narrows.
    let mut r = PriorRange::with_prior(RangePrior::Register(hz(rlo), hz(rhi)), fade, 0.0).unwrap();
    let f = wandering_line(20_000, 7);
    for (i, &x) in f.iter().enumerate() {
        let (lo, hi) = r.update(x).unwrap_or((f32::NAN, f32::NAN));
        if let Some((wlo, whi)) = range_offline(&f[..=i]) {
            assert!(
                lo <= wlo * 1.000_001 && hi >= whi * 0.999_999,
                "hop {i}: {lo}..{hi} vs {wlo}..{whi}"
            );
        }
    }
    let ((lo, hi), (wlo, whi)) = (r.get().unwrap(), range_offline(&f).unwrap());
    assert!(
        hz_to_semitones(wlo) - hz_to_semitones(lo) < 0.1
            && hz_to_semitones(hi) - hz_to_semitones(whi) < 0.1
    );
    r.reset();
    assert_eq!(r.get(), None);
    for bad in [
        (0.0, 100.0),
        (100.0, 100.0),
        (200.0, 100.0),
        (f32::NAN, 100.0),
        (40.0, f32::INFINITY),
    ] {
        assert!(
            PriorRange::with_prior(RangePrior::Register(bad.0, bad.1), 1.0, 0.01).is_err(),
            "{bad:?}"
        );
        assert!(HeldRange::with_prior(
            RangePrior::Register(bad.0, bad.1),
            1.0,
            0.01,
            5,
            1.0,
            0.25,
            1
        )
        .is_err());
    }
    // The span prior through `with_prior` is `with_quantile`.
    let mut a = PriorRange::with_prior(RangePrior::Span(20.0), 300.0, 0.01).unwrap();
    let mut b = PriorRange::with_quantile(20.0, 300.0, 0.01).unwrap();
    for &x in &f[..3000] {
        assert_eq!(a.update(x), b.update(x));
    }
}

/// The held-range rule by hand: the hops of `f` inside held notes (`mask`), the voiced hop
/// count, and whether the held hops decide the range (at least `min_hops` of them and at
/// least `share` of the voiced hops).
fn held_rule_by_hand(
    f: &[f32],
    mask: &[bool],
    share: f32,
    min_hops: u64,
) -> (Vec<f32>, usize, bool) {
    let held: Vec<f32> = f
        .iter()
        .zip(mask)
        .filter(|(_, &m)| m)
        .map(|(&x, _)| x)
        .collect();
    let voiced = f.iter().filter(|x| x.is_finite() && **x > 0.0).count();
    let use_held = !held.is_empty()
        && held.len() as u64 >= min_hops
        && held.len() as f32 >= share * voiced as f32;
    (held, voiced, use_held)
}

/// Octave shadows written out: hop `i` is one when it is voiced and some voiced hop `j` with
/// `|j − i| ≤ w` lies within a semitone of its pitch + 12 (nested loops, f64).
fn shadow_by_hand(f: &[f32], w: usize) -> Vec<bool> {
    let st = |x: f32| (x.is_finite() && x > 0.0).then(|| hz_to_semitones(x) as f64);
    (0..f.len())
        .map(|i| {
            let Some(c) = st(f[i]) else { return false };
            let mut found = false;
            for (j, &y) in f.iter().enumerate() {
                if i.abs_diff(j) <= w {
                    if let Some(x) = st(y) {
                        found |= (x - (c + 12.0)).abs() <= SHADOW_TOL_ST as f64;
                    }
                }
            }
            found
        })
        .collect()
}

/// A bass line that now and then carries a run of 5–30 hops of the same note an octave low,
/// where a kick under the note gives the tracker a subharmonic.
fn line_with_octave_shadows(n: usize, seed: u64) -> Vec<f32> {
    let e = ErrorRuns {
        before: false,
        prob: 0.15,
        min_len: 5,
        span: 26.0,
        offset_st: -12.0,
        jitter_st: 0.6,
        jitter_centre: 0.5,
        junk_salt: 0xbeef,
        junk_every: 41,
        junk_at: 7,
    };
    line_with_error_runs(n, seed, &e)
}

#[test]
fn shadow_mask_is_the_definition_written_out() {
    for seed in 1..6u64 {
        let f = line_with_octave_shadows(1200, seed);
        for w in [0usize, 1, 5, 25, MAX_SHADOW_HOPS] {
            let got = shadow_mask(&f, w);
            let want = shadow_by_hand(&f, w);
            assert_eq!(got, want, "seed {seed} w {w}");
            if w >= 5 {
                assert!(got.iter().any(|&s| s), "seed {seed} w {w}: no shadow found");
            }
        }
    }
    assert!(shadow_mask(&[], 25).is_empty());
    assert_eq!(shadow_mask(&[0.0, f32::NAN, -1.0], 25), vec![false; 3]);
}

#[test]
fn range_without_octave_shadows_drops_the_octave_errors_and_keeps_a_real_low_note() {
    // 40–53 with 5 % of its hops an octave under its own notes: the plain 1 % quantile
    // reaches them, the range without shadows does not.
    let mut f = Vec::new();
    for i in 0..60 {
        let note = 40.0 + [0.0, 7.0, 13.0, 5.0][i % 4];
        f.extend(std::iter::repeat_n(hz(note), 38));
        if i % 4 == 0 {
            f.extend(std::iter::repeat_n(hz(note - 12.0), 8));
        }
    }
    let (lo, _) = range_quantiles(&f, 0.01).unwrap();
    assert!(
        (hz_to_semitones(lo) - 28.0).abs() < 0.01,
        "the plain range reaches the errors"
    );
    let (lo, hi) = range_quantiles_kept(&f, 0.01, 0, 1.0, 25, 0.25, 300).unwrap();
    assert!(
        (hz_to_semitones(lo) - 40.0).abs() < 0.01 && (hz_to_semitones(hi) - 53.0).abs() < 0.01,
        "{lo}..{hi}"
    );
    // w = 0 is the held rule; k = 0 and w = 0 every voiced hop.
    assert_eq!(
        range_quantiles_kept(&f, 0.01, 5, 1.0, 0, 0.25, 300),
        range_quantiles_held(&f, 0.01, 5, 1.0, 0.25, 300)
    );
    assert_eq!(
        range_quantiles_kept(&f, 0.01, 0, 1.0, 0, 0.25, 300),
        range_quantiles(&f, 0.01)
    );
    // A real low note, 40 hops with no octave above it within 25 hops: kept.
    let mut g = f.clone();
    g.extend(std::iter::repeat_n(0.0, 30));
    g.extend(std::iter::repeat_n(hz(26.0), 40));
    let (lo, _) = range_quantiles_kept(&g, 0.01, 0, 1.0, 25, 0.25, 300).unwrap();
    assert!((hz_to_semitones(lo) - 26.0).abs() < 0.01, "{lo}");
    // A line that alternates root and octave throughout: almost every low hop is a shadow,
    // the kept hops are under a quarter of the voiced ones, and every hop counts.
    let octaves: Vec<f32> = (0..2000)
        .map(|i| hz(if (i / 10) % 2 == 0 { 36.0 } else { 48.0 }) + (i % 3) as f32 * 0.01)
        .collect();
    let kept = range_quantiles_kept(&octaves, 0.01, 0, 1.0, 25, 0.6, 300);
    assert_eq!(kept, range_quantiles(&octaves, 0.01));
    assert!((hz_to_semitones(kept.unwrap().0) - 36.0).abs() < 0.01);
}

#[test]
fn streaming_shadow_range_is_the_padded_quantile_range_of_the_kept_prefix_within_one_cell() {
    for prior in [
        RangePrior::Span(20.0),
        RangePrior::Register(hz(30.0), hz(50.0)),
    ] {
        for seed in 1..4u64 {
            let f = line_with_octave_shadows(1500, seed);
            check_streaming_kept_range(
                prior,
                &f,
                None,
                None,
                &[
                    (0, 25, 0.25, 300),
                    (0, 3, 0.5, 1),
                    (5, 10, 0.25, 50),
                    (5, 2, 0.25, 50),
                ],
                &format!("{prior:?} seed {seed}"),
            );
        }
    }
}

/// The streaming kept range against its oracle at every hop j: the hops i of the prefix with
/// max(k, w) ≤ i and i + max(k, w) < j + 1 that are held (k), or, with `trusted`, voiced and
/// trusted, and not shadows (w), all by hand on the prefix; then the held-range rule and
/// padding as in `check_held_range`, within one cell. `trusted = None` feeds
/// `HeldRange::update`, else `HeldRange::update_trusted`; with `sure`,
/// `HeldRange::update_sure`, and only sure hops are kept. `HeldRange::holds` must say at
/// every hop whether the kept range is used. Each `(k, w, share, min_hops)` must use the
/// kept range at some hop.
fn check_streaming_kept_range(
    prior: RangePrior,
    f: &[f32],
    trusted: Option<&[bool]>,
    sure: Option<&[bool]>,
    configs: &[(usize, usize, f32, u64)],
    what: &str,
) {
    let (fade, p) = (300.0f32, 0.01f32);
    for &(k, w, share, min_hops) in configs {
        let mut r = HeldRange::with_prior(prior, fade, p, k, 1.0, share, min_hops)
            .unwrap()
            .with_shadow(w)
            .unwrap();
        let m = k.max(w);
        let mut used = false;
        for j in 0..f.len() {
            let got = match (trusted, sure) {
                (t, Some(s)) => r.update_sure(f[j], t.is_some_and(|t| t[j]), s[j]),
                (None, None) => r.update(f[j]),
                (Some(t), None) => r.update_trusted(f[j], t[j]),
            };
            let pre = &f[..=j];
            let held = held_by_hand(pre, k, 1.0);
            let shadow = shadow_by_hand(pre, w);
            let mask: Vec<bool> = (0..pre.len())
                .map(|i| {
                    let agreed = trusted.is_some_and(|t| t[i] && pre[i] > 0.0);
                    let is_sure = sure.is_none_or(|s| s[i]);
                    i >= m && i + m < pre.len() && (held[i] || agreed) && is_sure && !shadow[i]
                })
                .collect();
            let (kept, voiced, use_kept) = held_rule_by_hand(pre, &mask, share, min_hops);
            used |= use_kept;
            assert_eq!(r.holds(), use_kept, "{what} k {k} w {w} hop {j}: holds");
            let kept_or_all = if use_kept { &kept[..] } else { pre };
            let want = padded_by_hand(prior, fade, range_quantiles(kept_or_all, p), voiced);
            assert_within_a_cell(got, want, &format!("{what} k {k} w {w} hop {j}"));
        }
        assert!(used, "{what} k {k} w {w}: the kept range was never used");
    }
}

#[test]
fn shadow_range_streams_without_allocating_and_refuses_a_long_window() {
    let f = line_with_octave_shadows(3000, 9);
    let mut r = HeldRange::new(20.0, 1.0, 0.01, 0, 1.0, 0.25, 300)
        .unwrap()
        .with_shadow(25)
        .unwrap();
    let mut last = None;
    let allocs = tactus_testkit::allocations_during(|| {
        for &x in &f {
            last = r.update(x);
        }
    });
    assert_eq!(allocs, 0);
    // Fade 1: the padding is gone; the running range is within a cell of the offline one of
    // the same kept hops (the stream's first and last 25 hops excepted, which these are not).
    let (lo, hi) = last.unwrap();
    let (wlo, whi) = range_quantiles_kept(&f, 0.01, 0, 1.0, 25, 0.25, 300).unwrap();
    assert!(
        (hz_to_semitones(lo) - hz_to_semitones(wlo)).abs() < 0.2
            && (hz_to_semitones(hi) - hz_to_semitones(whi)).abs() < 0.2,
        "{lo}..{hi} vs {wlo}..{whi}"
    );
    r.reset();
    assert_eq!(r.update(0.0), None);
    let fresh = HeldRange::new(20.0, 1.0, 0.01, 0, 1.0, 0.25, 300).unwrap();
    assert!(fresh.clone().with_shadow(MAX_SHADOW_HOPS).is_ok());
    assert!(fresh.with_shadow(MAX_SHADOW_HOPS + 1).is_err());
}

/// A running range (Hz) within one 1/8-semitone cell of the oracle's (semitones), or both
/// absent.
fn assert_within_a_cell(got: Option<(f32, f32)>, want: Option<(f64, f64)>, what: &str) {
    match (got, want) {
        (None, None) => {}
        (Some((lo, hi)), Some((wlo, whi))) => {
            let (lo, hi) = (hz_to_semitones(lo) as f64, hz_to_semitones(hi) as f64);
            let cell = 1.0 / 8.0 + 1e-3;
            assert!(
                (lo - wlo).abs() < cell && (hi - whi).abs() < cell,
                "{what}: {lo}..{hi} vs {wlo}..{whi}"
            );
        }
        (g, w) => panic!("{what}: {g:?} vs {w:?}"),
    }
}

/// A second tracker beside `f`: the same pitch plus a little noise on most hops, another
/// pitch (2–9 semitones away) on runs of hops, unvoiced on some.
fn second_tracker(f: &[f32], seed: u64) -> Vec<f32> {
    let mut x = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut off = 0.0f32;
    let mut left = 0usize;
    f.iter()
        .map(|&v| {
            if left == 0 {
                let r = next();
                off = if r < 0.6 {
                    0.8 * (next() as f32 - 0.5)
                } else if r < 0.85 {
                    (2.0 + 7.0 * next() as f32) * if next() < 0.5 { -1.0 } else { 1.0 }
                } else {
                    f32::NAN
                };
                left = 1 + (next() * 20.0) as usize;
            }
            left -= 1;
            if off.is_nan() || !(v.is_finite() && v > 0.0) {
                0.0
            } else {
                hz(hz_to_semitones(v) + off)
            }
        })
        .collect()
}

/// Agreement written out: both voiced (finite, > 0), pitches within `tol` semitones (f64).
fn agree_by_hand(f: &[f32], g: &[f32], tol: f32) -> Vec<bool> {
    let st = |x: f32| (x.is_finite() && x > 0.0).then(|| hz_to_semitones(x) as f64);
    (0..f.len())
        .map(|i| match (st(f[i]), g.get(i).and_then(|&y| st(y))) {
            (Some(a), Some(b)) => (a - b).abs() <= tol as f64,
            _ => false,
        })
        .collect()
}

#[test]
fn agree_mask_is_the_definition_written_out() {
    for seed in 1..6u64 {
        let f = line_with_octave_shadows(1500, seed);
        let g = second_tracker(&f, seed);
        for tol in [0.25f32, 1.0, 3.0] {
            let want = agree_by_hand(&f, &g, tol);
            assert_eq!(agree_mask(&f, &g, tol), want, "seed {seed} tol {tol}");
            let n = want.iter().filter(|&&a| a).count();
            assert!(
                n > 100 && n < f.len() - 100,
                "seed {seed} tol {tol}: {n} agree"
            );
        }
        // A shorter second track: the hops beyond it do not agree.
        let short = agree_mask(&f, &g[..700], 1.0);
        assert!(short[700..].iter().all(|&a| !a));
        assert_eq!(short[..700], agree_by_hand(&f[..700], &g[..700], 1.0)[..]);
    }
    assert!(!pitches_agree(0.0, 0.0, 1.0));
    assert!(!pitches_agree(f32::NAN, 220.0, 1.0));
    assert!(pitches_agree(220.0, 220.0, 0.0));
}

#[test]
fn range_from_held_or_agreed_hops_keeps_a_fast_lines_extremes_and_drops_foreign_runs() {
    // A lead in 60–72 whose lowest (58) and highest (75) notes are eighths of 12 hops, too
    // short to hold 8 hops on each side; the pair's other tracker agrees with them. Every
    // fifth bar the pitch tracker follows another instrument for 14 hops at 84, where the
    // other tracker says 72: neither held (too short) nor agreed.
    let (mut f, mut g) = (Vec::new(), Vec::new());
    for bar in 0..40 {
        for (note, len) in [(60.0, 40), (58.0, 12), (64.0, 40), (75.0, 12), (72.0, 40)] {
            f.extend(std::iter::repeat_n(hz(note), len));
            g.extend(std::iter::repeat_n(hz(note + 0.1), len));
        }
        if bar % 5 == 0 {
            f.extend(std::iter::repeat_n(hz(84.0), 14));
            g.extend(std::iter::repeat_n(hz(72.0), 14));
        }
    }
    let st = |r: Option<(f32, f32)>| {
        let (lo, hi) = r.unwrap();
        (hz_to_semitones(lo), hz_to_semitones(hi))
    };
    let close = |a: (f32, f32), b: (f32, f32)| (a.0 - b.0).abs() < 0.01 && (a.1 - b.1).abs() < 0.01;
    // Every voiced hop: the foreign runs (112 of 5,912 hops, 1.9 %) set the top.
    assert!(close(st(range_quantiles(&f, 0.01)), (58.0, 84.0)));
    // Held notes alone: the eighths are gone, and so are the true extremes.
    assert!(close(
        st(range_quantiles_kept(&f, 0.01, 8, 1.0, 0, 0.25, 300)),
        (60.0, 72.0)
    ));
    // Held or agreed: the line's own extremes, without the foreign runs.
    let trusted = agree_mask(&f, &g, 1.0);
    let r = range_quantiles_kept_or(&f, &trusted, 0.01, 8, 1.0, 0, 0.25, 300);
    assert!(close(st(r), (58.0, 75.0)), "{:?}", st(r));
    // No trusted hops is the held rule; every hop trusted is the plain range.
    assert_eq!(
        range_quantiles_kept_or(&f, &[], 0.01, 8, 1.0, 0, 0.25, 300),
        range_quantiles_kept(&f, 0.01, 8, 1.0, 0, 0.25, 300)
    );
    assert_eq!(
        range_quantiles_kept_or(&f, &vec![true; f.len()], 0.01, 8, 1.0, 0, 0.25, 300),
        range_quantiles(&f, 0.01)
    );
}

#[test]
fn offline_held_or_agreed_range_is_the_rule_written_out() {
    for seed in 1..5u64 {
        let f = line_with_octave_shadows(1500, seed);
        let g = second_tracker(&f, seed);
        let trusted = agree_by_hand(&f, &g, 1.0);
        for (k, w, share, min_hops) in [
            (8usize, 0usize, 0.25f32, 300u64),
            (5, 25, 0.25, 50),
            (0, 25, 0.5, 1),
            (16, 0, 0.9, 1),
        ] {
            let held = held_by_hand(&f, k, 1.0);
            let shadow = shadow_by_hand(&f, w);
            let voiced = |x: f32| x.is_finite() && x > 0.0;
            let mask: Vec<bool> = (0..f.len())
                .map(|i| (held[i] || (trusted[i] && voiced(f[i]))) && !(w > 0 && shadow[i]))
                .collect();
            let (kept, _, use_kept) = held_rule_by_hand(&f, &mask, share, min_hops);
            let want = range_quantiles(if use_kept { &kept[..] } else { &f[..] }, 0.01);
            assert_eq!(
                range_quantiles_kept_or(&f, &trusted, 0.01, k, 1.0, w, share, min_hops),
                want,
                "seed {seed} k {k} w {w}"
            );
        }
    }
}

/// Sure in runs of 40 hops (one run in three unsure) and unsure on one hop in seven besides,
/// as a tracker unsure of a stretch and of single hops.
fn sure_mask(n: usize, seed: u64) -> Vec<bool> {
    let mut x = seed.wrapping_mul(0x2545_f491_4f6c_dd1d) | 1;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    let runs: Vec<bool> = (0..n / 40 + 1).map(|_| next() % 3 != 0).collect();
    (0..n).map(|i| runs[i / 40] && next() % 7 != 0).collect()
}

#[test]
fn streaming_range_of_sure_held_or_agreed_hops_is_the_padded_quantile_range_of_the_kept_prefix_within_one_cell(
) {
    // `HeldRange::update_sure`: the oracle of the held-or-agreed range with only the sure
    // hops kept; the held test still reads every hop. With and without a second tracker.
    let prior = RangePrior::Register(hz(30.0), hz(50.0));
    for seed in 1..3u64 {
        let f = line_with_octave_shadows(1200, seed);
        let trusted = agree_by_hand(&f, &second_tracker(&f, seed), 1.0);
        let sure = sure_mask(f.len(), seed);
        check_streaming_kept_range(
            prior,
            &f,
            Some(&trusted),
            Some(&sure),
            &[(8, 0, 0.25, 300), (3, 25, 0.25, 100)],
            &format!("sure, agreed, seed {seed}"),
        );
        check_streaming_kept_range(
            prior,
            &f,
            None,
            Some(&sure),
            &[(3, 25, 0.25, 100)],
            &format!("sure, seed {seed}"),
        );
    }
    // Every hop sure is `update_trusted`, bit for bit; sure hops stream without allocating.
    let f = line_with_octave_shadows(2000, 7);
    let trusted = agree_by_hand(&f, &second_tracker(&f, 7), 1.0);
    let sure = sure_mask(f.len(), 7);
    let mk = || HeldRange::new(20.0, 300.0, 0.01, 8, 1.0, 0.25, 300).unwrap();
    let (mut a, mut b, mut c) = (mk(), mk(), mk());
    let mut differ = 0;
    for j in 0..f.len() {
        let x = a.update_trusted(f[j], trusted[j]);
        assert_eq!(b.update_sure(f[j], trusted[j], true), x, "hop {j}");
        let allocs = tactus_testkit::allocations_during(|| {
            differ +=
                usize::from(std::hint::black_box(c.update_sure(f[j], trusted[j], sure[j])) != x);
        });
        assert_eq!(allocs, 0);
    }
    assert!(differ > 0, "the sure mask never mattered");
}

#[test]
fn offline_range_of_sure_held_or_agreed_hops_is_the_rule_written_out() {
    // `range_quantiles_kept_or_sure`: the held mask is judged on every voiced hop, then a hop
    // counts when it is (held or trusted) and sure and not a shadow; the fallbacks read the
    // kept count as before. Against the rule written out, for sure masks that leave out
    // runs of hops (as a tracker unsure of a stretch does) and single hops.
    for seed in 1..5u64 {
        let f = line_with_octave_shadows(1500, seed);
        let g = second_tracker(&f, seed);
        let trusted = agree_by_hand(&f, &g, 1.0);
        let sure = sure_mask(f.len(), seed);
        let mut moved = 0;
        for (k, w, share, min_hops) in [
            (8usize, 0usize, 0.25f32, 300u64),
            (5, 25, 0.25, 50),
            (0, 25, 0.5, 1),
            (16, 0, 0.9, 1),
        ] {
            let held = held_by_hand(&f, k, 1.0);
            let shadow = shadow_by_hand(&f, w);
            let voiced = |x: f32| x.is_finite() && x > 0.0;
            let mask: Vec<bool> = (0..f.len())
                .map(|i| {
                    (held[i] || (trusted[i] && voiced(f[i]))) && sure[i] && !(w > 0 && shadow[i])
                })
                .collect();
            let (kept, _, use_kept) = held_rule_by_hand(&f, &mask, share, min_hops);
            for p in [0.01f32, 0.02] {
                let want = range_quantiles(if use_kept { &kept[..] } else { &f[..] }, p);
                let got = range_quantiles_kept_or_sure(
                    &f, &trusted, &sure, p, k, 1.0, w, share, min_hops,
                );
                assert_eq!(got, want, "seed {seed} k {k} w {w} p {p}");
                moved += usize::from(
                    got != range_quantiles_kept_or(&f, &trusted, p, k, 1.0, w, share, min_hops),
                );
            }
            // No sure mask, or every hop sure, is `range_quantiles_kept_or`.
            let plain = range_quantiles_kept_or(&f, &trusted, 0.01, k, 1.0, w, share, min_hops);
            assert_eq!(
                range_quantiles_kept_or_sure(&f, &trusted, &[], 0.01, k, 1.0, w, share, min_hops),
                plain
            );
            assert_eq!(
                range_quantiles_kept_or_sure(
                    &f,
                    &trusted,
                    &vec![true; f.len()],
                    0.01,
                    k,
                    1.0,
                    w,
                    share,
                    min_hops
                ),
                plain
            );
        }
        assert!(moved > 0, "seed {seed}: the sure mask never mattered");
    }
}

#[test]
fn a_range_narrowed_to_its_sure_hops_keeps_at_most_the_margin_beyond_them() {
    let r = |a: f32, b: f32| Some((hz(a), hz(b)));
    let st = |x: Option<(f32, f32)>| {
        let (a, b) = x.unwrap();
        (hz_to_semitones(a), hz_to_semitones(b))
    };
    let close = |a: (f32, f32), b: (f32, f32)| (a.0 - b.0).abs() < 1e-3 && (a.1 - b.1).abs() < 1e-3;
    // Unsure hops stretched the range 12 semitones down and 5 up: a semitone is left of each.
    assert!(close(
        st(narrow_range(r(48.0, 77.0), r(60.0, 72.0), 1.0, 1.0)),
        (59.0, 73.0)
    ));
    // Within the margin nothing moves; a margin of 0 is the sure range inside the range.
    assert!(close(
        st(narrow_range(r(59.5, 72.5), r(60.0, 72.0), 1.0, 1.0)),
        (59.5, 72.5)
    ));
    assert!(close(
        st(narrow_range(r(48.0, 77.0), r(60.0, 72.0), 0.0, 0.0)),
        (60.0, 72.0)
    ));
    // Each end its own margin; an infinite one leaves that end alone (a bass line's bottom
    // only).
    assert!(close(
        st(narrow_range(r(48.0, 77.0), r(60.0, 72.0), 1.0, 3.0)),
        (59.0, 75.0)
    ));
    assert!(close(
        st(narrow_range(
            r(28.0, 55.0),
            r(40.0, 48.0),
            1.0,
            f32::INFINITY
        )),
        (39.0, 55.0)
    ));
    // Never wider than the range itself, whatever the sure hops say.
    assert!(close(
        st(narrow_range(r(60.0, 72.0), r(50.0, 80.0), 1.0, 1.0)),
        (60.0, 72.0)
    ));
    // No sure range, no range, or an empty result: the range as it was.
    assert_eq!(narrow_range(r(48.0, 77.0), None, 1.0, 1.0), r(48.0, 77.0));
    assert_eq!(narrow_range(None, r(60.0, 72.0), 1.0, 1.0), None);
    assert_eq!(
        narrow_range(r(48.0, 55.0), r(70.0, 72.0), 1.0, 1.0),
        r(48.0, 55.0)
    );
}

#[test]
fn streaming_held_or_agreed_range_is_the_padded_quantile_range_of_the_kept_prefix_within_one_cell()
{
    // As the shadow range's oracle, a hop i of the prefix also kept when it is voiced and
    // trusted (judged at the same lag, max(k, w) hops).
    let prior = RangePrior::Register(hz(30.0), hz(50.0));
    for seed in 1..4u64 {
        let f = line_with_octave_shadows(1500, seed);
        let trusted = agree_by_hand(&f, &second_tracker(&f, seed), 1.0);
        check_streaming_kept_range(
            prior,
            &f,
            Some(&trusted),
            None,
            &[(8, 0, 0.25, 300), (5, 10, 0.25, 50), (0, 3, 0.5, 1)],
            &format!("seed {seed}"),
        );
    }
    // Streaming the agreed range allocates nothing.
    let f = line_with_octave_shadows(3000, 9);
    let trusted = agree_by_hand(&f, &second_tracker(&f, 9), 1.0);
    let mut r = HeldRange::new(20.0, 1.0, 0.01, 8, 1.0, 0.25, 300).unwrap();
    let allocs = tactus_testkit::allocations_during(|| {
        for (&x, &t) in f.iter().zip(&trusted) {
            std::hint::black_box(r.update_trusted(x, t));
        }
    });
    assert_eq!(allocs, 0);
}
