//! Tests for `tactus_dsp::flux`: the fast flux against a direct f64 DFT, onset accuracy on
//! click trains and synthetic drum hits (F-measure within ±10 ms), no false onsets on steady
//! signals, hard inputs, chunking invariance, and no allocation after construction.
//!
//! `unsafe` appears once, in the counting global allocator below: `GlobalAlloc` can only be
//! implemented with `unsafe impl`. It forwards to `System` unchanged.
#![deny(unsafe_code)]

use proptest::prelude::*;
use tactus_dsp::flux::{detect_onsets, ln_1p_fast, OnsetConfig, OnsetDetector, OnsetFrame};
use tactus_dsp::HopStage;
use tactus_testkit::Rng;

// ---------------------------------------------------------------------------------------
#[global_allocator]
static GLOBAL: tactus_testkit::Counting = tactus_testkit::Counting;

fn allocs() -> usize {
    tactus_testkit::allocations()
}

// ---------------------------------------------------------------------------------------
// Signals.

const SR: u32 = 44_100;

/// Single-sample clicks of amplitude `amp` at the given times.
fn click_train(times: &[f64], amp: f32, len: usize) -> Vec<f32> {
    let mut x = vec![0.0; len];
    for &t in times {
        let n = (t * SR as f64).round() as usize;
        if n < len {
            x[n] += amp;
        }
    }
    x
}

/// Adds a synthetic drum hit at `t` (s): a noise burst decaying with τ = 25 ms plus a
/// pitched thump, a sine sweeping exponentially from 120 Hz down to 50 Hz, decaying with
/// τ = 80 ms. `level` is the peak amplitude of each part. The hit lasts 1.2 s, until its
/// envelope is below 1e-6 · level: cutting it earlier adds an audible (and detectable) click.
fn add_drum(x: &mut [f32], t: f64, level: f64, rng: &mut Rng) {
    add_drum_at_rate(x, SR, t, level, rng)
}

/// [`add_drum`] at another sample rate.
fn add_drum_at_rate(x: &mut [f32], rate: u32, t: f64, level: f64, rng: &mut Rng) {
    let sr = rate as f64;
    let start = (t * sr).round() as usize;
    let mut phase = 0.0f64;
    for n in 0..(1.2 * sr) as usize {
        let Some(dst) = x.get_mut(start + n) else {
            break;
        };
        let tt = n as f64 / sr;
        let f = 50.0 + 70.0 * (-tt / 0.04).exp();
        phase += 2.0 * std::f64::consts::PI * f / sr;
        let thump = level * (-tt / 0.08).exp() * phase.sin();
        let noise = level * 0.5 * (-tt / 0.025).exp() * rng.normal();
        *dst += (thump + noise) as f32;
    }
}

fn sine(freq: f64, amp: f64, len: usize) -> Vec<f32> {
    (0..len)
        .map(|n| (amp * (2.0 * std::f64::consts::PI * freq * n as f64 / SR as f64).sin()) as f32)
        .collect()
}

/// Harmonic tone: 8 partials with 1/k amplitudes.
fn harmonic(f0: f64, amp: f64, len: usize) -> Vec<f32> {
    (0..len)
        .map(|n| {
            let t = n as f64 / SR as f64;
            let v: f64 = (1..=8)
                .map(|k| (2.0 * std::f64::consts::PI * f0 * k as f64 * t).sin() / k as f64)
                .sum();
            (amp * v / 2.0) as f32
        })
        .collect()
}

fn noise(amp: f64, len: usize, seed: u64) -> Vec<f32> {
    let mut rng = Rng::new(seed);
    (0..len).map(|_| (amp * rng.normal()) as f32).collect()
}

// ---------------------------------------------------------------------------------------
// Running the detector.

/// All hops, feeding `x` in chunks of `chunk` samples.
fn run_chunked(det: &mut OnsetDetector, x: &[f32], chunk: usize) -> Vec<OnsetFrame> {
    let mut out = Vec::new();
    let mut push = |i: usize, f: OnsetFrame| {
        assert_eq!(i, out.len(), "hops must come in order");
        out.push(f)
    };
    for c in x.chunks(chunk.max(1)) {
        det.process(c, &mut push);
    }
    det.finish(&mut push);
    out
}

fn run(cfg: &OnsetConfig, x: &[f32]) -> Vec<OnsetFrame> {
    let mut det = OnsetDetector::new(cfg.clone()).unwrap();
    run_chunked(&mut det, x, x.len().max(1))
}

fn onset_times(cfg: &OnsetConfig, frames: &[OnsetFrame]) -> Vec<f64> {
    frames
        .iter()
        .enumerate()
        .filter(|(_, f)| f.onset)
        .map(|(i, _)| (i * cfg.hop) as f64 / cfg.sample_rate as f64)
        .collect()
}

fn modes() -> [(&'static str, OnsetConfig); 2] {
    [
        ("causal", OnsetConfig::causal(SR)),
        ("lookahead", OnsetConfig::lookahead(SR)),
    ]
}

// ---------------------------------------------------------------------------------------
// F-measure: greedy one-to-one matching, closest pairs first.

struct Score {
    f: f64,
    matched: usize,
    /// Signed errors detection - reference of the matched pairs, in seconds.
    errors: Vec<f64>,
}

fn f_measure(reference: &[f64], detected: &[f64], tol: f64) -> Score {
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for (r, &tr) in reference.iter().enumerate() {
        for (d, &td) in detected.iter().enumerate() {
            if (td - tr).abs() <= tol {
                pairs.push(((td - tr).abs(), r, d));
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut ref_used = vec![false; reference.len()];
    let mut det_used = vec![false; detected.len()];
    let mut errors = Vec::new();
    for (_, r, d) in pairs {
        if !ref_used[r] && !det_used[d] {
            ref_used[r] = true;
            det_used[d] = true;
            errors.push(detected[d] - reference[r]);
        }
    }
    let matched = errors.len();
    let f = if reference.is_empty() && detected.is_empty() {
        1.0
    } else {
        2.0 * matched as f64 / (reference.len() + detected.len()) as f64
    };
    Score { f, matched, errors }
}

#[test]
fn f_measure_helper_counts_correctly() {
    // Two references, one matched within tolerance, one detection too far, one extra.
    let s = f_measure(&[1.0, 2.0], &[1.005, 2.5, 3.0], 0.01);
    assert_eq!(s.matched, 1);
    assert!((s.f - 2.0 / 5.0).abs() < 1e-12);
    // One-to-one: two detections near one reference match only once.
    let s = f_measure(&[1.0], &[0.995, 1.002], 0.01);
    assert_eq!(s.matched, 1);
    assert!((s.errors[0] - 0.002).abs() < 1e-12);
    assert_eq!(f_measure(&[], &[], 0.01).f, 1.0);
}

// ---------------------------------------------------------------------------------------
// Oracle: direct DFT flux in f64.

/// The module's flux, computed the slow obvious way: centred frames, periodic Hann scaled by
/// 1/sqrt(Σw²), O(N²) DFT, optional ln(1 + γ|X|), mean over bins of the rectified rise.
/// Returns the flux of every frame (not yet aligned).
fn oracle_flux(x: &[f32], frame: usize, hop: usize, gamma: Option<f64>) -> Vec<f64> {
    let n = frame;
    let bins = n / 2 + 1;
    let tau = 2.0 * std::f64::consts::PI;
    let w: Vec<f64> = (0..n)
        .map(|i| 0.5 - 0.5 * (tau * i as f64 / n as f64).cos())
        .collect();
    let norm = w.iter().map(|v| v * v).sum::<f64>().sqrt();
    let cos: Vec<f64> = (0..n).map(|i| (tau * i as f64 / n as f64).cos()).collect();
    let sin: Vec<f64> = (0..n).map(|i| (tau * i as f64 / n as f64).sin()).collect();
    let frames = x.len().div_ceil(hop);
    let mut prev = vec![0.0f64; bins];
    let mut out = Vec::with_capacity(frames);
    for j in 0..frames {
        let seg: Vec<f64> = (0..n)
            .map(|m| {
                let idx = (j * hop + m) as isize - (n / 2) as isize;
                let s = if idx >= 0 && (idx as usize) < x.len() {
                    x[idx as usize] as f64
                } else {
                    0.0
                };
                s * w[m] / norm
            })
            .collect();
        let mut cur = vec![0.0f64; bins];
        for (k, c) in cur.iter_mut().enumerate() {
            let (mut re, mut im) = (0.0, 0.0);
            for (m, &s) in seg.iter().enumerate() {
                let t = (k * m) % n;
                re += s * cos[t];
                im -= s * sin[t];
            }
            let mag = (re * re + im * im).sqrt();
            *c = match gamma {
                Some(g) => (g * mag).ln_1p(),
                None => mag,
            };
        }
        let rise: f64 = cur.iter().zip(&prev).map(|(c, p)| (c - p).max(0.0)).sum();
        // Frames reaching into the padding after the end carry no flux (module docs).
        let tail = j * hop + (n - n / 2) > x.len();
        out.push(if tail { 0.0 } else { rise / bins as f64 });
        prev = cur;
    }
    out
}

/// Seeded random noise, a harmonic tone with a drum hit, and clicks.
fn oracle_signals(len: usize) -> Vec<(&'static str, Vec<f32>)> {
    let mut rng = Rng::new(7);
    let mut drums = harmonic(220.0, 0.3, len);
    add_drum(&mut drums, 0.02, 0.5, &mut rng);
    vec![
        ("noise", noise(0.2, len, 11)),
        ("tone+drum", drums),
        ("clicks", click_train(&[0.004, 0.019, 0.031], 0.9, len)),
    ]
}

#[test]
fn flux_matches_direct_dft_oracle() {
    // Small frames keep the O(N²) oracle cheap; the default frame is checked too.
    let shapes = [
        (256usize, 64usize, Some(1000.0f32)),
        (256, 100, None),
        (1024, 220, Some(1000.0)),
        (512, 512, Some(10.0)),
    ];
    for (frame, hop, gamma) in shapes {
        let cfg = OnsetConfig {
            frame,
            hop,
            log_compression: gamma,
            ..OnsetConfig::causal(SR)
        };
        for (name, x) in oracle_signals(2400) {
            let want = oracle_flux(&x, frame, hop, gamma.map(f64::from));
            let mut det = OnsetDetector::new(cfg.clone()).unwrap();
            let s = det.compensation_hops();
            let got = run_chunked(&mut det, &x, 333);
            assert_eq!(got.len(), want.len());
            for g in got.iter().take(s) {
                assert_eq!(
                    g.flux, 0.0,
                    "hops before the first aligned frame carry no flux"
                );
            }
            let scale = want.iter().cloned().fold(0.0f64, f64::max);
            let mut worst = 0.0f64;
            for (i, g) in got.iter().enumerate().skip(s) {
                let r = want[i - s];
                worst = worst.max((g.flux as f64 - r).abs() / scale);
                // f32 FFT: magnitude errors ~ few eps·log2(N) of the frame's RMS magnitude;
                // ln(1+γm) amplifies absolute errors by ≤ γ in near-empty bins, but these are
                // averaged over N/2+1 bins. Measured: ≤ 7e-7 of the signal's largest flux.
                // 1e-5 of it (plus 1e-7 absolute) leaves 15x headroom and is still 4 orders
                // of magnitude below the onset threshold delta (0.15).
                let tol = 1e-5 * scale + 1e-7;
                assert!(
                    (g.flux as f64 - r).abs() <= tol,
                    "{name} f{frame} h{hop} g{gamma:?} hop {i}: fast {} oracle {r} (tol {tol})",
                    g.flux
                );
            }
            eprintln!(
                "oracle {name} f{frame} h{hop} g{gamma:?}: worst error {worst:.2e} of max flux"
            );
        }
    }
}

#[test]
fn fast_log_matches_f64() {
    let mut x = 0.0f32;
    while x < 1e30 {
        let want = (x as f64).ln_1p();
        let got = ln_1p_fast(x) as f64;
        // Relative 2e-7 of the result, plus the rounding of 1 + x to f32 (≤ 6e-8 absolute).
        assert!(
            (got - want).abs() <= 2e-7 * want + 6e-8,
            "x {x}: {got} vs {want}"
        );
        x = if x == 0.0 { 1e-12 } else { x * 1.037 };
    }
}

// ---------------------------------------------------------------------------------------
// Accuracy.

const TOL: f64 = 0.010;

fn assert_perfect(name: &str, mode: &str, reference: &[f64], detected: &[f64]) {
    let s = f_measure(reference, detected, TOL);
    let mean = s.errors.iter().sum::<f64>() / s.errors.len().max(1) as f64;
    let worst = s.errors.iter().fold(0.0f64, |a, e| a.max(e.abs()));
    eprintln!(
        "{name} {mode}: F {:.3}, {} ref, {} det, mean err {:+.2} ms, worst {:.2} ms",
        s.f,
        reference.len(),
        detected.len(),
        mean * 1e3,
        worst * 1e3
    );
    assert!(
        s.f == 1.0,
        "{name} ({mode}): F = {} ({} of {} refs, {} detections)\nref {reference:?}\ndet {detected:?}",
        s.f,
        s.matched,
        reference.len(),
        detected.len()
    );
}

#[test]
fn click_trains_at_several_tempi() {
    // Intervals from 500 ms (120 BPM) down to 60 ms; odd start offsets so clicks fall
    // between hops.
    for &(interval, amp) in &[
        (0.5, 0.9),
        (0.25, 0.5),
        (0.125, 0.2),
        (0.0831, 0.9),
        (0.06, 0.7),
        (0.06, 0.05),
    ] {
        let times: Vec<f64> = (0..20).map(|k| 0.1037 + k as f64 * interval).collect();
        let len = ((times[19] + 0.3) * SR as f64) as usize;
        let x = click_train(&times, amp, len);
        for (mode, cfg) in modes() {
            let det = onset_times(&cfg, &run(&cfg, &x));
            assert_perfect(&format!("clicks {interval}s amp {amp}"), mode, &times, &det);
        }
    }
}

#[test]
fn drum_hits_loud_and_soft_in_one_track() {
    for rate in [44_100, 22_050, 48_000, 96_000] {
        drum_track_at_rate(rate);
    }
}

/// Drum track at `rate`, scored with that rate's default configurations.
fn drum_track_at_rate(rate: u32) {
    let mut rng = Rng::new(42);
    let len = 8 * rate as usize;
    let mut x = vec![0.0f32; len];
    let mut times = Vec::new();
    // Alternating loud (0.8) and soft (0.08, -20 dB) hits, plus a -30 dB one, with
    // irregular spacing between 150 and 400 ms.
    let mut t = 0.2;
    let mut k = 0;
    while t < 7.5 {
        let level = match k % 4 {
            0 => 0.8,
            1 => 0.08,
            2 => 0.4,
            _ => 0.025,
        };
        add_drum_at_rate(&mut x, rate, t, level, &mut rng);
        times.push(t);
        t += 0.15 + 0.25 * rng.uniform();
        k += 1;
    }
    for (mode, cfg) in [
        ("causal", OnsetConfig::causal(rate)),
        ("lookahead", OnsetConfig::lookahead(rate)),
    ] {
        let det = onset_times(&cfg, &run(&cfg, &x));
        assert_perfect(&format!("drums {rate} Hz"), mode, &times, &det);
    }
}

// ---------------------------------------------------------------------------------------
// No false onsets.

/// A stream is taken to be preceded by silence, so a signal that starts at full level at
/// sample 0 *is* an onset: at most one is allowed, and only within the first 30 ms. After
/// that a steady signal must produce none.
fn assert_steady(name: &str, x: &[f32]) {
    for (mode, cfg) in modes() {
        let det = onset_times(&cfg, &run(&cfg, x));
        let after_start: Vec<f64> = det.iter().cloned().filter(|&t| t > 0.03).collect();
        assert!(
            det.len() <= 1 && after_start.is_empty(),
            "{name} ({mode}): onsets at {det:?}"
        );
    }
}

#[test]
fn no_onsets_in_steady_tones() {
    let len = 3 * SR as usize;
    for f in [41.2, 55.0, 110.0, 440.0, 1000.0, 3520.0, 9000.0] {
        for amp in [0.9, 0.01] {
            assert_steady(&format!("sine {f} Hz amp {amp}"), &sine(f, amp, len));
        }
    }
    for f0 in [55.0, 98.0, 220.0, 330.0] {
        assert_steady(&format!("harmonic {f0} Hz"), &harmonic(f0, 0.8, len));
    }
    for (seed, amp) in [(1u64, 0.5), (2, 0.05), (3, 1e-3)] {
        assert_steady(&format!("noise amp {amp}"), &noise(amp, len, seed));
    }
    // The start onset itself is found: a loud tone starting at 0 gives exactly one.
    let cfg = OnsetConfig::causal(SR);
    assert_eq!(
        onset_times(&cfg, &run(&cfg, &sine(440.0, 0.5, len))).len(),
        1
    );
}

#[test]
fn no_onsets_in_silence_or_faint_signals() {
    let len = 2 * SR as usize;
    for (mode, cfg) in modes() {
        for (name, x) in [
            ("silence", vec![0.0f32; len]),
            ("1e-38 noise", noise(1e-38, len, 5)),
            ("1e-7 noise", noise(1e-7, len, 6)),
            ("1e-6 clicks", click_train(&[0.3, 0.8, 1.3], 1e-6, len)),
        ] {
            let frames = run(&cfg, &x);
            assert!(frames.iter().all(|f| !f.onset), "{name} ({mode})");
            if name == "silence" {
                assert!(
                    frames.iter().all(|f| f.flux == 0.0),
                    "silence has zero flux"
                );
            }
        }
    }
}

#[test]
fn minimum_interval_is_respected() {
    // Clicks every 35 ms (each frame sees at most one; denser trains are a buzz tone):
    // closer than allowed. Onsets must be ≥ 50 ms apart, and the detector must still fire
    // regularly (every other click, 70 ms): at least 80% of 2 s / 70 ms.
    let times: Vec<f64> = (0..58).map(|k| 0.05 + k as f64 * 0.035).collect();
    let x = click_train(&times, 0.8, (2.3 * SR as f64) as usize);
    for (mode, cfg) in modes() {
        let frames = run(&cfg, &x);
        let on: Vec<usize> = frames
            .iter()
            .enumerate()
            .filter(|(_, f)| f.onset)
            .map(|(i, _)| i)
            .collect();
        for w in on.windows(2) {
            let gap_s = ((w[1] - w[0]) * cfg.hop) as f64 / SR as f64;
            assert!(gap_s >= 0.05, "{mode}: onsets {gap_s} s apart");
        }
        assert!(
            on.len() >= 23,
            "{mode}: only {} onsets in 2 s of 50 Hz clicks",
            on.len()
        );
    }
}

// ---------------------------------------------------------------------------------------
// Hard inputs.

#[test]
fn hard_inputs_never_panic_or_produce_nan() {
    let len = SR as usize / 2;
    let mut nan_inf = sine(300.0, 0.5, len);
    for (k, v) in nan_inf.iter_mut().enumerate() {
        match k % 97 {
            0 => *v = f32::NAN,
            1 => *v = f32::INFINITY,
            2 => *v = f32::NEG_INFINITY,
            _ => {}
        }
    }
    let square: Vec<f32> = (0..len)
        .map(|k| if (k / 50) % 2 == 0 { 8.0 } else { -8.0 })
        .collect();
    let inputs: Vec<(&str, Vec<f32>)> = vec![
        ("empty", vec![]),
        ("one sample", vec![0.7]),
        ("one NaN", vec![f32::NAN]),
        ("silence", vec![0.0; len]),
        ("DC", vec![0.5; len]),
        ("+-8 square", square),
        ("1e-38", vec![1e-38; len]),
        ("all NaN", vec![f32::NAN; len]),
        ("all +Inf", vec![f32::INFINITY; len]),
        ("NaN/Inf sprinkled", nan_inf),
        ("f32::MAX", vec![f32::MAX; 3000]),
    ];
    let mut extreme = OnsetConfig::causal(SR);
    extreme.log_compression = None;
    let mut tiny = OnsetConfig::lookahead(SR);
    tiny.frame = 2;
    tiny.hop = 1;
    tiny.mean_before_hops = 0;
    let cfgs = [
        OnsetConfig::causal(SR),
        OnsetConfig::lookahead(SR),
        extreme,
        tiny,
    ];
    for cfg in &cfgs {
        for (name, x) in &inputs {
            let frames = run(cfg, x);
            assert_eq!(frames.len(), x.len().div_ceil(cfg.hop), "{name}");
            assert!(
                frames.iter().all(|f| f.flux.is_finite() && f.flux >= 0.0),
                "{name} {cfg:?}"
            );
        }
    }
    // All-NaN/Inf input is sanitized to silence: no onsets.
    let frames = run(&cfgs[0], &vec![f32::NAN; len]);
    assert!(frames.iter().all(|f| !f.onset && f.flux == 0.0));
    // DC is a step at sample 0 (one start onset at most), then steady.
    assert!(onset_times(&cfgs[0], &run(&cfgs[0], &vec![0.5; len])).len() <= 1);
}

#[test]
fn invalid_configs_are_rejected() {
    let ok = OnsetConfig::causal(SR);
    let bad = [
        OnsetConfig {
            sample_rate: 0,
            ..ok.clone()
        },
        OnsetConfig {
            frame: 1,
            ..ok.clone()
        },
        OnsetConfig {
            hop: 0,
            ..ok.clone()
        },
        OnsetConfig {
            log_compression: Some(0.0),
            ..ok.clone()
        },
        OnsetConfig {
            log_compression: Some(f32::NAN),
            ..ok.clone()
        },
        OnsetConfig {
            delta: 0.0,
            ..ok.clone()
        },
        OnsetConfig {
            delta: f32::INFINITY,
            ..ok.clone()
        },
        OnsetConfig {
            min_interval_s: -1.0,
            ..ok.clone()
        },
        OnsetConfig {
            mean_before_hops: usize::MAX,
            ..ok.clone()
        },
        OnsetConfig {
            lookahead_hops: usize::MAX,
            ..ok.clone()
        },
    ];
    for cfg in bad {
        assert!(OnsetDetector::new(cfg.clone()).is_err(), "{cfg:?}");
        assert!(detect_onsets(&[0.0; 100], &cfg).is_empty());
    }
    assert!(OnsetDetector::new(ok).is_ok());
}

#[test]
fn defaults_match_the_documentation() {
    let c = OnsetConfig::causal(SR);
    assert_eq!(
        (c.frame, c.hop, c.mean_before_hops, c.lookahead_hops),
        (1024, 220, 20, 0)
    );
    assert_eq!(c.min_interval_s, 0.05);
    let l = OnsetConfig::lookahead(SR);
    assert_eq!(l.lookahead_hops, 3);
    let dc = OnsetDetector::new(c).unwrap();
    let dl = OnsetDetector::new(l).unwrap();
    assert_eq!((dc.compensation_hops(), dc.latency_samples()), (2, 72));
    assert_eq!((dl.compensation_hops(), dl.latency_samples()), (1, 952));
}

// ---------------------------------------------------------------------------------------
// Streaming contract.

#[test]
fn latency_is_exact() {
    // Feed one sample at a time: hop i must come out exactly when input sample
    // i * hop + latency - 1 arrives (never later, and not earlier: it could not know).
    let x = noise(0.3, 6000, 9);
    let mut shapes = vec![OnsetConfig::causal(SR), OnsetConfig::lookahead(SR)];
    shapes.push(OnsetConfig {
        frame: 256,
        hop: 100,
        lookahead_hops: 5,
        ..OnsetConfig::causal(SR)
    });
    shapes.push(OnsetConfig {
        frame: 64,
        hop: 100,
        ..OnsetConfig::causal(SR)
    });
    for cfg in shapes {
        let mut det = OnsetDetector::new(cfg.clone()).unwrap();
        let lat = det.latency_samples();
        let mut emitted = 0usize;
        for (n, s) in x.iter().enumerate() {
            let mut got = Vec::new();
            det.process(std::slice::from_ref(s), &mut |i, _| got.push(i));
            for i in got {
                assert_eq!(i, emitted);
                // The first `compensation_hops` hops carry no frame and come out as soon as
                // they exist; every later one exactly at the stated latency.
                if i >= det.compensation_hops() {
                    assert_eq!(
                        n + 1,
                        i * cfg.hop + lat,
                        "{cfg:?}: hop {i} after sample {n}"
                    );
                } else {
                    assert!(n < i * cfg.hop + lat);
                }
                emitted += 1;
            }
        }
        assert!(emitted > 0);
    }
}

#[test]
fn detect_onsets_matches_streaming() {
    let mut rng = Rng::new(3);
    let mut x = vec![0.0f32; 3 * SR as usize];
    for k in 0..8 {
        add_drum(&mut x, 0.1 + 0.33 * k as f64, 0.5, &mut rng);
    }
    for (_, cfg) in modes() {
        let streamed = onset_times(&cfg, &run(&cfg, &x));
        assert_eq!(streamed.len(), 8);
        assert_eq!(detect_onsets(&x, &cfg), streamed);
    }
}

/// A signal with onsets, tones and silence, for the chunking properties.
fn mixed_signal(seed: u64, len: usize) -> Vec<f32> {
    let mut rng = Rng::new(seed);
    let mut x = harmonic(110.0 + (seed % 200) as f64, 0.2, len);
    for v in x[len / 2..len * 3 / 4].iter_mut() {
        *v = 0.0;
    }
    let mut t = 0.01;
    while t * (SR as f64) < len as f64 {
        add_drum(&mut x, t, 0.05 + 0.5 * rng.uniform(), &mut rng);
        t += 0.06 + 0.1 * rng.uniform();
    }
    x
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn chunking_and_reset_do_not_change_output(
        seed in 0u64..1000,
        len in 0usize..12_000,
        chunks in proptest::collection::vec(0usize..1500, 1..40),
        lookahead in 0usize..5,
        hop in prop_oneof![Just(64usize), Just(220), Just(333)],
    ) {
        let cfg = OnsetConfig { hop, frame: 512, lookahead_hops: lookahead, ..OnsetConfig::causal(SR) };
        let x = mixed_signal(seed, len);
        let mut det = OnsetDetector::new(cfg.clone()).unwrap();
        let whole = run_chunked(&mut det, &x, x.len().max(1));
        prop_assert_eq!(whole.len(), len.div_ceil(hop));
        // Random chunk sizes (0 included), cycling through the list.
        det.reset();
        let mut out = Vec::new();
        let mut pos = 0;
        let mut k = 0;
        while pos < x.len() {
            // The last entry of each pass through the list takes at least one sample, so a
            // list of zeros (which proptest does draw) still reaches the end of the input.
            let step = chunks[k % chunks.len()];
            let step = if k % chunks.len() == chunks.len() - 1 { step.max(1) } else { step };
            let n = step.min(x.len() - pos);
            det.process(&x[pos..pos + n], &mut |i, f| { assert_eq!(i, out.len()); out.push(f) });
            pos += n;
            k += 1;
        }
        det.finish(&mut |i, f| { assert_eq!(i, out.len()); out.push(f) });
        prop_assert_eq!(&out, &whole);
        // Reset after a partial stream reproduces the whole-block output.
        det.reset();
        det.process(&x[..x.len() / 3], &mut |_, _| {});
        det.reset();
        prop_assert_eq!(run_chunked(&mut det, &x, 777), whole);
    }
}

// ---------------------------------------------------------------------------------------
// Flux scale.

#[test]
fn flux_scale_does_not_depend_on_frame_size() {
    // Linear magnitude, hop = frame: frame 2 is silence, frame 3 is the first all-noise
    // frame. Its flux is the mean over bins of |X|, which for noise of RMS σ is the
    // Rayleigh mean sqrt(π)/2 · σ in every bin, whatever the frame size (the module's
    // normalisation). Spread of a mean over ≥ 513 correlated bins: ~4%; allow 10%.
    // (Summing over bins instead would differ 4x between 1024 and 4096.)
    let sigma = 0.1;
    let want = std::f64::consts::PI.sqrt() / 2.0 * sigma;
    for frame in [1024usize, 2048, 4096] {
        let cfg = OnsetConfig {
            frame,
            hop: frame,
            log_compression: None,
            ..OnsetConfig::causal(SR)
        };
        let mut x = vec![0.0f32; 2 * frame + frame / 2];
        x.extend(noise(sigma, 3 * frame, frame as u64));
        let mut det = OnsetDetector::new(cfg).unwrap();
        let s = det.compensation_hops();
        let frames = run_chunked(&mut det, &x, 4096);
        assert_eq!(frames[2 + s].flux, 0.0);
        let got = frames[3 + s].flux as f64;
        assert!(
            (got / want - 1.0).abs() < 0.10,
            "frame {frame}: {got} vs {want}"
        );
    }
}

// ---------------------------------------------------------------------------------------
// No allocation after construction.

#[test]
fn processing_does_not_allocate() {
    let x = mixed_signal(5, 40_000);
    for (_, cfg) in modes() {
        let mut det = OnsetDetector::new(cfg).unwrap();
        let mut count = 0usize;
        let before = allocs();
        for c in x.chunks(300) {
            det.process(c, &mut |_, f| count += f.onset as usize);
        }
        det.finish(&mut |_, f| count += f.onset as usize);
        det.reset();
        det.process(&x[..5000], &mut |_, f| count += f.onset as usize);
        let after = allocs();
        assert_eq!(after - before, 0, "allocations while processing");
        assert!(count > 0);
    }
    // The counter works: allocating is seen.
    let before = allocs();
    let v: Vec<u8> = std::hint::black_box(Vec::with_capacity(10));
    assert!(allocs() > before && v.capacity() >= 10);
}
