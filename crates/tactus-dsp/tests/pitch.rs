//! Tests for YIN and pYIN: a naive f64 YIN oracle, pitch accuracy across sample rates,
//! vibrato, weak fundamentals (octave errors), hard inputs, chunking invariance,
//! streaming-vs-offline pYIN, and an allocation guard.
//!
//! `unsafe` appears once in this file: a `GlobalAlloc` impl must be `unsafe impl`. It only
//! forwards to `System` and counts. The library itself stays `#![forbid(unsafe_code)]`.

use proptest::prelude::*;
use tactus_dsp::pyin::{pyin_offline, Pyin, PyinConfig};
use tactus_dsp::yin::{PitchEstimate, Yin, YinConfig};
use tactus_dsp::HopStage;

// ---------------------------------------------------------------------------------------
#[global_allocator]
static GLOBAL: tactus_testkit::Counting = tactus_testkit::Counting;

/// Runs `f` and returns how many allocations the current thread made inside it.
fn count_allocs(f: impl FnOnce()) -> usize {
    tactus_testkit::allocations_during(f)
}

// ---------------------------------------------------------------------------------------
// Signals.

/// SplitMix64: a tiny seeded generator, so the tests need no extra crate.
struct Rng(u64);
impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_10EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in [-1, 1).
    fn white(&mut self) -> f64 {
        2.0 * self.uniform() - 1.0
    }
}

fn sine(sr: u32, f0: f64, n: usize, amp: f64) -> Vec<f32> {
    (0..n)
        .map(|i| (amp * (2.0 * std::f64::consts::PI * f0 * i as f64 / sr as f64).sin()) as f32)
        .collect()
}

/// Harmonic tone with amplitudes `amps[h-1]` for harmonic h (harmonics at or above 0.45·sr
/// are dropped) and fixed random phases.
fn harmonic(sr: u32, f0: f64, n: usize, amps: &[f64], seed: u64) -> Vec<f32> {
    let mut rng = Rng(seed);
    let parts: Vec<(f64, f64, f64)> = amps
        .iter()
        .enumerate()
        .map(|(h, &a)| {
            (
                (h + 1) as f64 * f0,
                a,
                rng.uniform() * std::f64::consts::TAU,
            )
        })
        .filter(|&(f, _, _)| f < 0.45 * sr as f64)
        .collect();
    (0..n)
        .map(|i| {
            let t = i as f64 / sr as f64;
            parts
                .iter()
                .map(|&(f, a, ph)| a * (std::f64::consts::TAU * f * t + ph).sin())
                .sum::<f64>() as f32
        })
        .collect()
}

fn cents(est: f64, truth: f64) -> f64 {
    1200.0 * (est / truth).log2()
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    if v.is_empty() {
        return f64::NAN;
    }
    v[v.len() / 2]
}

fn run_stage<S: HopStage<Out = PitchEstimate>>(
    stage: &mut S,
    x: &[f32],
    chunks: &[usize],
) -> Vec<PitchEstimate> {
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
        stage.process(&rest[..c], &mut |i, e| {
            assert_eq!(i, out.len(), "hops emitted in order");
            out.push(e)
        });
        rest = &rest[c..];
        k += 1;
    }
    stage.finish(&mut |i, e| {
        assert_eq!(i, out.len(), "hops emitted in order");
        out.push(e)
    });
    out
}

// ---------------------------------------------------------------------------------------
// The oracle: naive O(N²) YIN in f64.

struct Naive {
    cmnd: Vec<f64>,
    lag: usize,
    f0: f64,
}

fn naive_yin(
    frame: &[f32],
    sr: u32,
    start: usize,
    w: usize,
    tau_min: usize,
    tau_max: usize,
    thr: f64,
) -> Naive {
    let x: Vec<f64> = (0..w + tau_max + 2)
        .map(|j| frame.get(start + j).copied().unwrap_or(0.0) as f64)
        .collect();
    let mut cmnd = vec![1.0; tau_max + 2];
    let mut diff = vec![0.0; tau_max + 2];
    let mut cum = 0.0;
    for tau in 1..=tau_max + 1 {
        let d: f64 = (0..w).map(|j| (x[j] - x[j + tau]).powi(2)).sum();
        diff[tau] = d;
        cum += d;
        cmnd[tau] = if cum > 0.0 { d * tau as f64 / cum } else { 1.0 };
    }
    let mut lag = None;
    let mut tau = tau_min;
    while tau <= tau_max {
        if cmnd[tau] < thr {
            while tau < tau_max && cmnd[tau + 1] < cmnd[tau] {
                tau += 1;
            }
            lag = Some(tau);
            break;
        }
        tau += 1;
    }
    let lag = lag.unwrap_or_else(|| {
        (tau_min..=tau_max).fold(tau_min, |b, t| if cmnd[t] < cmnd[b] { t } else { b })
    });
    // Interpolate on the raw difference function, as the paper's step 5 does.
    let (a, b, c) = (diff[lag - 1], diff[lag], diff[lag + 1]);
    let den = a - 2.0 * b + c;
    let shift = if den > 0.0 {
        (0.5 * (a - c) / den).clamp(-1.0, 1.0)
    } else {
        0.0
    };
    Naive {
        f0: sr as f64 / (lag as f64 + shift),
        cmnd,
        lag,
    }
}

#[test]
fn fast_yin_matches_naive_oracle() {
    let mut worst_cmnd = 0.0f64;
    let mut worst_f0_rel = 0.0f64;
    let (mut compared, mut ambiguous) = (0, 0);
    for &(sr, fmin, fmax) in &[
        (44100u32, 50.0f32, 1000.0f32),
        (16000, 70.0, 800.0),
        (8000, 60.0, 2000.0),
    ] {
        let cfg = YinConfig::new(sr, fmin, fmax);
        let mut yin = Yin::new(cfg.clone()).unwrap();
        let (start, w) = yin.analysis_window();
        let (tmin, tmax) = yin.lag_range();
        let n = cfg.frame;
        let mut rng = Rng(sr as u64);
        for case in 0..24 {
            let frame: Vec<f32> = match case % 4 {
                // white noise
                0 => (0..n).map(|_| rng.white() as f32).collect(),
                // harmonic tone + noise
                1 | 2 => {
                    let f0 = fmin as f64 * (fmax as f64 / fmin as f64).powf(rng.uniform()) * 0.9;
                    let amps: Vec<f64> = (1..=6).map(|_| rng.uniform()).collect();
                    let noise = 0.05 * rng.uniform();
                    harmonic(sr, f0.max(fmin as f64 * 1.1), n, &amps, rng.next_u64())
                        .into_iter()
                        .map(|v| v + (noise * rng.white()) as f32)
                        .collect()
                }
                // a sine on a DC offset, with a decaying envelope
                _ => {
                    let f0 = 100.0 + 300.0 * rng.uniform();
                    sine(sr, f0, n, 0.3)
                        .into_iter()
                        .enumerate()
                        .map(|(i, v)| 0.5 + v * (-(i as f32) / n as f32).exp())
                        .collect()
                }
            };
            let fast = yin.estimate_frame(&frame);
            let fast_cmnd = yin.cmnd().to_vec();
            let naive = naive_yin(&frame, sr, start, w, tmin, tmax, cfg.threshold as f64);
            for (f, n) in fast_cmnd.iter().zip(&naive.cmnd).skip(1) {
                worst_cmnd = worst_cmnd.max((*f as f64 - n).abs());
            }
            compared += 1;
            let ap = naive.cmnd[naive.lag].clamp(0.0, 1.0);
            let naive_f0 = if ap <= cfg.voicing_ceiling as f64 {
                naive.f0
            } else {
                0.0
            };
            let rel = (fast.f0_hz as f64 - naive_f0).abs() / naive_f0.max(1.0);
            if rel < 1e-4 && (fast.aperiodicity as f64 - ap).abs() < 1e-3 {
                worst_f0_rel = worst_f0_rel.max(rel);
                continue;
            }
            // The lag choice is discontinuous. A different choice is accepted only where the
            // oracle's decision has no margin over f32 rounding (1e-3 of CMND): a CMND value
            // at the threshold before the chosen lag, a near-tie between troughs, or a value
            // at the voicing ceiling.
            let near = |v: f64, t: f32| (v - t as f64).abs() < 1e-3;
            let near_thr = (tmin..=naive.lag).any(|t| near(naive.cmnd[t], cfg.threshold));
            let fast_lag = ((sr as f32 / fast.f0_hz.max(1.0)).round() as usize).clamp(tmin, tmax);
            let tie = (naive.cmnd[fast_lag] - naive.cmnd[naive.lag]).abs() < 1e-3;
            let ceiling = near(ap, cfg.voicing_ceiling);
            assert!(
                near_thr || tie || ceiling,
                "sr {sr} case {case}: fast {fast:?} vs naive f0 {naive_f0} (ap {ap})"
            );
            ambiguous += 1;
        }
    }
    println!("oracle: {compared} frames, {ambiguous} ambiguous, max |ΔCMND| {worst_cmnd:.2e}, max rel Δf0 {worst_f0_rel:.2e}");
    // f32 FFT on unit-peak frames: CMND errors stay near 1e-5; 1e-3 leaves room but would
    // still catch any wrong term in the difference function (those give errors ~0.1 or more).
    assert!(
        worst_cmnd < 1e-3,
        "CMND differs from the oracle by {worst_cmnd}"
    );
    assert!(
        ambiguous * 10 <= compared,
        "too many ambiguous frames: {ambiguous}/{compared}"
    );
}

// ---------------------------------------------------------------------------------------
// Accuracy on sines and harmonic tones.

#[test]
fn pitch_accuracy_across_sample_rates() {
    // 12 log-spaced f0s from 35 Hz to 4 kHz.
    let f0s: Vec<f64> = (0..12)
        .map(|k| 35.0 * (4000.0f64 / 35.0).powf(k as f64 / 11.0))
        .collect();
    let mut skipped = Vec::new();
    let mut worst: f64 = 0.0;
    for &sr in &[8000u32, 22050, 44100, 48000, 96000, 192000] {
        let fmax = (sr as f32 / 2.0 - 1.0).min(4500.0);
        let cfg = YinConfig::new(sr, 30.0, fmax);
        let mut yin = Yin::new(cfg.clone()).unwrap();
        for &f0 in &f0s {
            for (kind, amps) in [
                ("sine", vec![1.0]),
                ("harmonic", vec![1.0, 0.6, 0.4, 0.3, 0.2]),
            ] {
                // Representable: a period of at least 8 samples for sines and 16 for harmonic
                // tones (f0 ≤ sr/8, sr/16). Shorter periods are sampled too coarsely: the
                // dip of d(τ) is a few samples wide, parabolic interpolation is biased by
                // 7–15 cents, and at 2–5 samples per period the integer-lag CMND can miss
                // the dip at T and pick 2T (measured: 8 kHz 714 Hz harmonic 7 cents,
                // 22.05 kHz 4 kHz sine an octave low). Frames hold ≥ 2 periods of 30 Hz.
                let min_period = if kind == "sine" { 8.0 } else { 16.0 };
                if f0 > sr as f64 / min_period {
                    skipped.push((sr, kind, f0.round()));
                    continue;
                }
                let step = cfg.frame / 3 + 17;
                let x = harmonic(sr, f0, cfg.frame + 6 * step, &amps, 7);
                let mut errs: Vec<f64> = (0..7)
                    .map(|k| {
                        let e = yin.estimate_frame(&x[k * step..k * step + cfg.frame]);
                        if e.f0_hz > 0.0 {
                            cents(e.f0_hz as f64, f0).abs()
                        } else {
                            f64::INFINITY
                        }
                    })
                    .collect();
                let med = median(&mut errs);
                worst = worst.max(med);
                assert!(
                    med <= 5.0,
                    "sr {sr} f0 {f0:.1} {kind}: median error {med:.2} cents"
                );
            }
        }
    }
    println!("accuracy: worst median error {worst:.3} cents; skipped (sr, f0): {skipped:?}");
}

#[test]
fn vibrato_is_tracked() {
    // 220 Hz ± 50 cents at 6 Hz. The instantaneous f0 changes by up to 2π·6·50 ≈ 1900
    // cents/s. YIN reports roughly the mean f0 over its region (W + τ ≈ 1224 samples ≈ 28 ms
    // at 44.1 kHz), which differs from the value at the centre by at most
    // 50·(π·6·0.028)²/6 ≈ 2.3 cents, plus the residual centring offset (≤ 3.4 ms, ≤ 6.5
    // cents). Bound: median ≤ 3 cents, max ≤ 10 cents.
    let sr = 44100u32;
    let cfg = YinConfig::new(sr, 70.0, 1400.0);
    let hop = cfg.hop;
    let n = sr as usize; // 1 s
    let inst = |t: f64| 220.0 * 2f64.powf(50.0 / 1200.0 * (std::f64::consts::TAU * 6.0 * t).sin());
    let mut phase = 0.0f64;
    let x: Vec<f32> = (0..n)
        .map(|i| {
            let t = i as f64 / sr as f64;
            phase += std::f64::consts::TAU * inst(t) / sr as f64;
            (0.5 * phase.sin() + 0.25 * (2.0 * phase).sin()) as f32
        })
        .collect();
    let mut yin = Yin::new(cfg.clone()).unwrap();
    let est = run_stage(&mut yin, &x, &[]);
    let mut errs = Vec::new();
    // Skip hops whose frame reaches into the zero padding.
    for (i, e) in est.iter().enumerate() {
        let c = i * hop;
        if c < cfg.frame || c + cfg.frame > n {
            continue;
        }
        assert!(e.f0_hz > 0.0, "hop {i} unvoiced");
        errs.push(cents(e.f0_hz as f64, inst(c as f64 / sr as f64)).abs());
    }
    let max = errs.iter().cloned().fold(0.0, f64::max);
    let med = median(&mut errs);
    println!(
        "vibrato: {} hops, median {med:.2} cents, max {max:.2} cents",
        errs.len()
    );
    assert!(
        med <= 3.0 && max <= 10.0,
        "median {med:.2}, max {max:.2} cents"
    );
}

// ---------------------------------------------------------------------------------------
// Weak fundamental: octave errors on bass.

/// A bass line like a sampled bassoon or bass guitar: notes with f0 in 55–110 Hz, 8
/// harmonics with a 1/h^0.8 rolloff from the 2nd, the fundamental 24 dB below the 2nd,
/// slight inharmonicity (stiff string, B = 2e-4) and a few cents of random detune per
/// harmonic, a body formant, 10 ms attack and exponential decay, notes that ring into the
/// next one, and white noise 10 dB below the mean signal power (separated stems carry
/// bleed). Nothing here is chosen to trip YIN: on this signal plain YIN makes few octave
/// errors (measured 0.2%; 0% at 30 dB SNR, 5% at 5 dB SNR), unlike the ~22% measured on a
/// sampled bassoon (NOTES.md), whose spectrum a few sinusoids do not capture. Returns the signal and the true f0 per
/// sample (0 where no note has sounded for 30 ms: attacks are not scored).
const FORMANT_HZ: f64 = 500.0;
const FORMANT_BW: f64 = 250.0;
const N_HARM: usize = 12;

fn bass_line(sr: u32, seconds: f64, seed: u64) -> (Vec<f32>, Vec<f64>) {
    let n = (sr as f64 * seconds) as usize;
    let mut rng = Rng(seed);
    let mut x = vec![0.0f64; n];
    let mut truth = vec![0.0f64; n];
    let mut start = 0usize;
    while start < n {
        let semis = (rng.uniform() * 12.0).floor();
        let f0 = 55.0 * 2f64.powf(semis / 12.0);
        let dur = ((0.25 + 0.35 * rng.uniform()) * sr as f64) as usize;
        let end = (start + dur).min(n);
        let ring = ((end - start) + (sr as usize / 10)).min(n - start); // 100 ms release overlap
        let decay = 1.0 + 2.0 * rng.uniform(); // 1/s
        let amp = 0.3 + 0.5 * rng.uniform();
        // Source: 1/h rolloff; body: one formant (bassoon: ~500 Hz, bandwidth ~250 Hz);
        // then the fundamental is set 24 dB below the 2nd harmonic.
        let formant = |f: f64| {
            let (fc, bw) = (FORMANT_HZ, FORMANT_BW);
            1.0 / (1.0 + ((f * f - fc * fc) / (f * bw)).powi(2)).sqrt()
        };
        let mut amps: Vec<f64> = (1..=N_HARM)
            .map(|h| formant(h as f64 * f0) / h as f64)
            .collect();
        amps[0] = amps[1] * 10f64.powf(-24.0 / 20.0);
        for (h, &a) in amps.iter().enumerate() {
            let h = (h + 1) as f64;
            let detune = 2f64.powf((rng.white() * 3.0) / 1200.0);
            let fh = h * f0 * (1.0 + 2e-4 * h * h).sqrt() * detune;
            let ph = rng.uniform() * std::f64::consts::TAU;
            for i in 0..ring {
                let t = i as f64 / sr as f64;
                let env = (t / 0.01).min(1.0)
                    * (-decay * t).exp()
                    * if start + i >= end {
                        (-(((start + i - end) as f64) / sr as f64) / 0.03).exp()
                    } else {
                        1.0
                    };
                x[start + i] += amp * a * env * (std::f64::consts::TAU * fh * t + ph).sin();
            }
        }
        let settled = (start + (0.03 * sr as f64) as usize).min(end);
        truth[settled..end].fill(f0);
        start = end;
    }
    let power = x.iter().map(|v| v * v).sum::<f64>() / n as f64;
    let noise = (power * 10f64.powf(-10.0 / 10.0) * 3.0).sqrt(); // uniform: var = a²/3
    (
        x.iter()
            .map(|&v| (v + noise * rng.white()) as f32)
            .collect(),
        truth,
    )
}

/// (octave-error rate, voicing recall) over hops whose centre has a true f0 that holds
/// across the whole frame. An octave error is a voiced estimate more than 600 cents off.
fn octave_errors(est: &[PitchEstimate], truth: &[f64], hop: usize, frame: usize) -> (f64, f64) {
    let (mut scored, mut octave, mut voiced) = (0usize, 0usize, 0usize);
    for (i, e) in est.iter().enumerate() {
        let c = i * hop;
        let (lo, hi) = (
            c.saturating_sub(frame / 2),
            (c + frame / 2).min(truth.len() - 1),
        );
        let f = truth[c.min(truth.len() - 1)];
        if f == 0.0 || truth[lo] != f || truth[hi] != f {
            continue;
        }
        scored += 1;
        if e.f0_hz > 0.0 {
            voiced += 1;
            if cents(e.f0_hz as f64, f).abs() > 600.0 {
                octave += 1;
            }
        }
    }
    (octave as f64 / scored as f64, voiced as f64 / scored as f64)
}

#[test]
fn pyin_cuts_octave_errors_on_weak_fundamental() {
    let sr = 22050u32;
    let (x, truth) = bass_line(sr, 20.0, 42);
    let ycfg = YinConfig::new(sr, 35.0, 400.0);
    let mut yin = Yin::new(ycfg.clone()).unwrap();
    let y = run_stage(&mut yin, &x, &[]);
    let pcfg = PyinConfig::new(sr, 35.0, 400.0);
    let p = pyin_offline(&x, &pcfg).unwrap();
    let mut ps = Pyin::new(pcfg.clone()).unwrap();
    let s = run_stage(&mut ps, &x, &[]);
    let (hop, frame) = (ycfg.hop, ycfg.frame);
    let (ye, yv) = octave_errors(&y, &truth, hop, frame);
    let (pe, pv) = octave_errors(&p, &truth, hop, frame);
    let (se, sv) = octave_errors(&s, &truth, hop, frame);
    println!(
        "weak fundamental: octave-error rate YIN {:.1}% (voiced {:.1}%), pYIN offline {:.1}% (voiced {:.1}%), pYIN streaming lag {} {:.1}% (voiced {:.1}%)",
        100.0 * ye, 100.0 * yv, 100.0 * pe, 100.0 * pv, pcfg.lag_hops, 100.0 * se, 100.0 * sv
    );
    assert!(pe <= 0.05, "pYIN offline octave errors {:.1}%", 100.0 * pe);
    assert!(
        se <= 0.05,
        "pYIN streaming octave errors {:.1}%",
        100.0 * se
    );
    // pYIN must not buy its score by calling notes unvoiced.
    assert!(
        pv >= 0.9 && sv >= 0.9,
        "pYIN voicing recall {pv:.3} / {sv:.3}"
    );
}

// ---------------------------------------------------------------------------------------
// Hard inputs: no NaN, no panic.

fn all_finite(est: &[PitchEstimate]) -> bool {
    est.iter().all(|e| {
        e.f0_hz.is_finite()
            && e.f0_hz >= 0.0
            && (0.0..=1.0).contains(&e.aperiodicity)
            && (0.0..=1.0).contains(&e.voiced_prob)
    })
}

fn both(x: &[f32], sr: u32, fmin: f32, fmax: f32) -> (Vec<PitchEstimate>, Vec<PitchEstimate>) {
    let mut yin = Yin::new(YinConfig::new(sr, fmin, fmax)).unwrap();
    let y = run_stage(&mut yin, x, &[]);
    let mut cfg = PyinConfig::new(sr, fmin, fmax);
    cfg.lag_hops = 8;
    let mut p = Pyin::new(cfg.clone()).unwrap();
    let s = run_stage(&mut p, x, &[]);
    let hops = x.len().div_ceil(cfg.yin.hop);
    assert_eq!(y.len(), hops);
    assert_eq!(s.len(), hops);
    assert!(all_finite(&y), "YIN output not finite/in range");
    assert!(all_finite(&s), "pYIN output not finite/in range");
    (y, s)
}

fn voiced_fraction(e: &[PitchEstimate]) -> f64 {
    e.iter().filter(|e| e.f0_hz > 0.0).count() as f64 / e.len().max(1) as f64
}

#[test]
fn hard_inputs() {
    let sr = 22050u32;
    let n = sr as usize / 2;
    // Digital silence: all unvoiced, aperiodicity 1.
    let (y, p) = both(&vec![0.0; n], sr, 35.0, 400.0);
    assert!(
        y.iter().chain(&p).all(|e| *e == PitchEstimate::SILENT),
        "silence must be SILENT"
    );
    // 1e-38 amplitudes (flushed by the framer): silent too.
    let tiny: Vec<f32> = sine(sr, 110.0, n, 1.0).iter().map(|v| v * 1e-38).collect();
    let (y, p) = both(&tiny, sr, 35.0, 400.0);
    assert!(y.iter().chain(&p).all(|e| e.f0_hz == 0.0));
    // DC alone: unvoiced (no periodicity).
    let (y, p) = both(&vec![0.5; n], sr, 35.0, 400.0);
    assert_eq!(voiced_fraction(&y), 0.0, "DC alone is unvoiced (YIN)");
    assert_eq!(voiced_fraction(&p), 0.0, "DC alone is unvoiced (pYIN)");
    // DC under a quiet sine (-34 dB relative to the DC): the sine's pitch.
    let dc_sine: Vec<f32> = sine(sr, 220.0, n, 0.01).iter().map(|v| v + 0.5).collect();
    let (y, p) = both(&dc_sine, sr, 70.0, 1400.0);
    let cfg = YinConfig::new(sr, 70.0, 1400.0);
    let inner = |e: &[PitchEstimate]| -> Vec<f64> {
        e.iter()
            .enumerate()
            .filter(|(i, _)| i * cfg.hop >= cfg.frame && i * cfg.hop + cfg.frame <= n)
            .map(|(_, e)| e.f0_hz as f64)
            .collect()
    };
    for f in inner(&y).into_iter().chain(inner(&p)) {
        assert!(cents(f, 220.0).abs() < 5.0, "DC + sine: {f} Hz");
    }
    // Full-scale clipped square at 55 Hz.
    let square: Vec<f32> = sine(sr, 55.0, n, 4.0)
        .iter()
        .map(|v| v.clamp(-1.0, 1.0))
        .collect();
    let (y, p) = both(&square, sr, 35.0, 400.0);
    let cfg = YinConfig::new(sr, 35.0, 400.0);
    for (i, e) in y.iter().zip(&p).enumerate() {
        if i * cfg.hop >= cfg.frame && i * cfg.hop + cfg.frame <= n {
            assert!(
                cents(e.0.f0_hz as f64, 55.0).abs() < 5.0,
                "square YIN hop {i}: {:?}",
                e.0
            );
            assert!(
                cents(e.1.f0_hz as f64, 55.0).abs() < 5.0,
                "square pYIN hop {i}: {:?}",
                e.1
            );
        }
    }
    // White noise: mostly unvoiced.
    let mut rng = Rng(3);
    let noise: Vec<f32> = (0..n).map(|_| rng.white() as f32).collect();
    let (y, p) = both(&noise, sr, 35.0, 400.0);
    println!(
        "white noise voiced: YIN {:.1}%, pYIN {:.1}%",
        100.0 * voiced_fraction(&y),
        100.0 * voiced_fraction(&p)
    );
    assert!(voiced_fraction(&y) <= 0.1 && voiced_fraction(&p) <= 0.1);
    // ±8.0 samples (a loud square): finite, 55 Hz.
    let loud: Vec<f32> = square.iter().map(|v| v * 8.0).collect();
    let (y, _) = both(&loud, sr, 35.0, 400.0);
    assert!(y.iter().any(|e| cents(e.f0_hz as f64, 55.0).abs() < 5.0));
    // NaN / Inf samples: sanitized; a sine with sparse NaNs keeps its pitch.
    let mut bad = sine(sr, 220.0, n, 0.5);
    for (k, v) in bad.iter_mut().enumerate().step_by(997) {
        *v = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY][k % 3];
    }
    let (y, _) = both(&bad, sr, 70.0, 1400.0);
    assert!(voiced_fraction(&y) > 0.5);
    let (_, _) = both(&vec![f32::NAN; n], sr, 70.0, 1400.0);
    // 1-sample and empty input.
    let (y, p) = both(&[0.3], sr, 70.0, 1400.0);
    assert_eq!((y.len(), p.len()), (1, 1));
    let (y, p) = both(&[], sr, 70.0, 1400.0);
    assert_eq!((y.len(), p.len()), (0, 0));
    // estimate_frame on short / empty / wrong-length frames: no panic.
    let mut yin = Yin::new(YinConfig::new(sr, 70.0, 1400.0)).unwrap();
    assert_eq!(yin.estimate_frame(&[]), PitchEstimate::SILENT);
    assert!(all_finite(&[yin.estimate_frame(&[1.0, -1.0, 0.5])]));
    assert!(all_finite(&[yin.estimate_frame(&noise)]));
}

#[test]
fn invalid_configs_are_rejected() {
    let ok = YinConfig::new(44100, 50.0, 1000.0);
    assert!(Yin::new(ok.clone()).is_ok());
    let bad = [
        YinConfig {
            sample_rate: 0,
            ..ok.clone()
        },
        YinConfig {
            fmin_hz: 0.0,
            ..ok.clone()
        },
        YinConfig {
            fmin_hz: f32::NAN,
            ..ok.clone()
        },
        YinConfig {
            fmax_hz: 40.0,
            ..ok.clone()
        },
        YinConfig {
            fmax_hz: 30000.0,
            ..ok.clone()
        },
        YinConfig {
            frame: 512,
            ..ok.clone()
        }, // cannot hold 50 Hz lags
        YinConfig {
            hop: 0,
            ..ok.clone()
        },
        YinConfig {
            threshold: 0.0,
            ..ok.clone()
        },
        YinConfig {
            threshold: 1.5,
            ..ok.clone()
        },
    ];
    for c in bad {
        assert!(Yin::new(c.clone()).is_err(), "{c:?} accepted");
    }
    let p = PyinConfig::new(44100, 50.0, 1000.0);
    assert!(Pyin::new(p.clone()).is_ok());
    assert!(Pyin::new(PyinConfig {
        switch_prob: 0.0,
        ..p.clone()
    })
    .is_err());
    assert!(Pyin::new(PyinConfig {
        bins_per_semitone: 0,
        ..p.clone()
    })
    .is_err());
    assert!(Pyin::new(PyinConfig {
        prior_mean: 0.9,
        ..p.clone()
    })
    .is_err());
    assert!(Pyin::new(PyinConfig {
        lag_hops: usize::MAX,
        ..p.clone()
    })
    .is_err());
    assert!(pyin_offline(
        &[0.0; 10],
        &PyinConfig {
            yin: YinConfig {
                hop: 0,
                ..p.yin.clone()
            },
            ..p
        }
    )
    .is_err());
}

// ---------------------------------------------------------------------------------------
// Streaming: chunking, reset, latency, streaming vs offline pYIN, allocations.

fn small_signal(seed: u64) -> Vec<f32> {
    // A 0.6 s melody at 8 kHz with a gap and noise, so that voicing changes are exercised.
    let sr = 8000u32;
    let mut rng = Rng(seed);
    let mut x = Vec::new();
    for k in 0..4 {
        let f0 = 100.0 * 2f64.powf(rng.uniform() * 2.0);
        let seg = harmonic(
            sr,
            f0,
            1000 + (rng.uniform() * 400.0) as usize,
            &[1.0, 0.5, 0.3],
            seed + k,
        );
        x.extend(seg);
        if k == 1 {
            x.extend((0..300).map(|_| 0.01 * rng.white() as f32));
        }
    }
    x
}

fn small_pyin_cfg(lag: usize) -> PyinConfig {
    let mut c = PyinConfig::new(8000, 60.0, 1000.0);
    c.lag_hops = lag;
    c
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]
    #[test]
    fn chunking_does_not_change_output(seed in 0u64..1000, chunks in prop::collection::vec(1usize..700, 1..8), lag in 0usize..12) {
        let x = small_signal(seed);
        let ycfg = YinConfig::new(8000, 60.0, 1000.0);
        let mut yin = Yin::new(ycfg.clone()).unwrap();
        let whole = run_stage(&mut yin, &x, &[]);
        prop_assert_eq!(whole.len(), x.len().div_ceil(ycfg.hop));
        yin.reset();
        prop_assert_eq!(&run_stage(&mut yin, &x, &chunks), &whole);
        yin.reset();
        prop_assert_eq!(&run_stage(&mut yin, &x, &[]), &whole, "reset reproduces");

        let mut p = Pyin::new(small_pyin_cfg(lag)).unwrap();
        let whole = run_stage(&mut p, &x, &[]);
        prop_assert_eq!(whole.len(), x.len().div_ceil(ycfg.hop));
        p.reset();
        prop_assert_eq!(&run_stage(&mut p, &x, &chunks), &whole);
        // Reset mid-stream, then the whole signal: same output.
        p.reset();
        p.process(&x[..x.len() / 3], &mut |_, _| {});
        p.reset();
        prop_assert_eq!(&run_stage(&mut p, &x, &chunks), &whole, "reset reproduces");
    }
}

#[test]
fn latency_matches_emission() {
    // Hop i must be emitted exactly once sample i·hop + latency − 1 has arrived.
    let x = small_signal(5);
    for lag in [0usize, 3, 10] {
        let mut p = Pyin::new(small_pyin_cfg(lag)).unwrap();
        let (hop, lat) = (p.hop(), p.latency_samples());
        let mut emitted = 0usize;
        for (k, &v) in x.iter().enumerate() {
            p.process(&[v], &mut |i, _| {
                assert_eq!(i, emitted);
                emitted += 1;
            });
            // Samples 0..=k have arrived.
            let expect = if k + 1 >= lat {
                (k + 1 - lat) / hop + 1
            } else {
                0
            };
            assert_eq!(
                emitted,
                expect.min(x.len().div_ceil(hop)),
                "lag {lag}, sample {k}"
            );
        }
    }
    let mut y = Yin::new(YinConfig::new(8000, 60.0, 1000.0)).unwrap();
    let (hop, lat) = (y.hop(), y.latency_samples());
    let mut emitted = 0usize;
    for (k, &v) in x.iter().enumerate() {
        y.process(&[v], &mut |_, _| emitted += 1);
        let expect = if k + 1 >= lat {
            (k + 1 - lat) / hop + 1
        } else {
            0
        };
        assert_eq!(emitted, expect, "YIN sample {k}");
    }
}

#[test]
fn streaming_pyin_agrees_with_offline() {
    let sr = 22050u32;
    let (x, _) = bass_line(sr, 20.0, 7);
    let cfg = PyinConfig::new(sr, 35.0, 400.0);
    let offline = pyin_offline(&x, &cfg).unwrap();
    let agree = |a: &[PitchEstimate], b: &[PitchEstimate]| {
        let same = a
            .iter()
            .zip(b)
            .filter(|(a, b)| {
                (a.f0_hz == 0.0) == (b.f0_hz == 0.0)
                    && (a.f0_hz == 0.0 || cents(a.f0_hz as f64, b.f0_hz as f64).abs() < 1.0)
            })
            .count();
        same as f64 / a.len() as f64
    };
    let mut report = Vec::new();
    for lag in [0usize, 5, 10, 20, 40] {
        let mut c = cfg.clone();
        c.lag_hops = lag;
        let mut p = Pyin::new(c).unwrap();
        let s = run_stage(&mut p, &x, &[1000]);
        assert_eq!(s.len(), offline.len());
        let a = agree(&s, &offline);
        report.push((lag, a));
        if lag >= 20 {
            assert!(a >= 0.99, "lag {lag}: agreement {:.2}%", 100.0 * a);
        }
    }
    // A lag that covers the whole track is offline Viterbi, exactly.
    let mut c = cfg.clone();
    c.lag_hops = offline.len();
    let mut p = Pyin::new(c).unwrap();
    assert_eq!(run_stage(&mut p, &x, &[777]), offline);
    println!(
        "streaming vs offline pYIN agreement: {}",
        report
            .iter()
            .map(|(l, a)| format!("lag {l}: {:.2}%", 100.0 * a))
            .collect::<Vec<_>>()
            .join(", ")
    );
}

#[test]
fn no_allocation_after_construction() {
    let x = small_signal(11);
    let mut yin = Yin::new(YinConfig::new(8000, 60.0, 1000.0)).unwrap();
    let mut p = Pyin::new(small_pyin_cfg(6)).unwrap();
    let frame = x[..yin.config().frame].to_vec();
    let mut sink = 0.0f32;
    let n = count_allocs(|| {
        for c in x.chunks(97) {
            yin.process(c, &mut |_, e| sink += e.f0_hz);
            p.process(c, &mut |_, e| sink += e.f0_hz);
        }
        yin.finish(&mut |_, e| sink += e.f0_hz);
        p.finish(&mut |_, e| sink += e.f0_hz);
        yin.reset();
        p.reset();
        sink += yin.estimate_frame(&frame).f0_hz;
    });
    assert!(sink.is_finite());
    assert_eq!(n, 0, "allocations in process/finish/reset/estimate_frame");
    // The guard itself works.
    assert!(count_allocs(|| drop(std::hint::black_box(vec![1u8; 16]))) > 0);
}
