//! The learned low-band drum mask (`tactus_separate::lowband`) against a slow, obvious f64
//! reference built from the same weight file: features per frame, the context of past and
//! future frames, the network. Also the weight file's parser on damaged files.
mod common;

use common::Lcg;
use tactus_separate::lowband::{LowBand, LowBandModel, PAD, WEIGHTS};
use tactus_separate::stft::{StftAnalysis, StftConfig};

const SR: u32 = 44_100;
const N_FFT: usize = 2048;
const HOP: usize = 1024;

/// Kicks, a bass line, hats (noise bursts) and silence gaps: every feature moves.
fn signal(seconds: f32) -> Vec<f32> {
    let n = (seconds * SR as f32) as usize;
    let tau = std::f32::consts::TAU;
    let mut rng = Lcg(5);
    let mut x = vec![0.0f32; n];
    let beat = (0.5 * SR as f32) as usize;
    for (i, v) in x.iter_mut().enumerate() {
        let t = i as f32 / SR as f32;
        let since = (i % beat) as f32 / SR as f32;
        let kick = 0.7
            * (-since / 0.1).exp()
            * (tau * (50.0 + 40.0 * (-since / 0.02).exp()) * since).sin();
        let f0 = [82.4, 110.0, 98.0, 73.4][(t / 1.0) as usize % 4];
        let bass = 0.25 * ((tau * f0 * t).sin() + 0.4 * (tau * 2.0 * f0 * t).sin());
        let hat_since = ((i + beat / 2) % (beat / 2)) as f32 / SR as f32;
        let hat = 0.1 * (-hat_since / 0.02).exp() * rng.next();
        let gap = if (2.0..2.4).contains(&t) { 0.0 } else { 1.0 };
        *v = gap * (kick + bass + hat);
    }
    x
}

/// f64 reference of one frame's features (before the running reference is subtracted):
/// `ln(|X_k| + ε)` for the low bins, `ln(mean |X_k| + ε)` per band, `ε` = 1e-3 times the
/// strongest low bin + 1e-6.
fn raw_features(m: &LowBandModel, spec: &[realfft::num_complex::Complex<f32>]) -> Vec<f64> {
    let bin_hz = SR as f64 / N_FFT as f64;
    let mag = |k: usize| (spec[k].re as f64).hypot(spec[k].im as f64);
    let peak = (0..m.low).map(mag).fold(0.0, f64::max);
    let eps = 1e-3 * peak + 1e-6;
    let mut f: Vec<f64> = (0..m.low).map(|k| (mag(k) + eps).ln()).collect();
    for e in m.edges.windows(2) {
        // Bins whose centre frequency lies in [lo, hi).
        let ks: Vec<usize> = (0..spec.len())
            .filter(|&k| {
                k as f64 * bin_hz >= e[0] as f64 - 1e-9 && (k as f64 * bin_hz) < e[1] as f64 - 1e-9
            })
            .collect();
        let mean = if ks.is_empty() {
            0.0
        } else {
            ks.iter().map(|&k| mag(k)).sum::<f64>() / ks.len() as f64
        };
        f.push((mean + eps).ln());
    }
    f
}

/// How far a low bin's level may move over the context and still count as held (the
/// module's 0.25 nats).
const STEADY_NATS: f64 = 0.25;

/// Per frame and low output bin, the spread (max − min) of `ln(|X_k| + ε)` over the frame's
/// context (frames before the start skipped, frames after the end repeating the last): a
/// bin that spreads less than [`STEADY_NATS`] keeps its bass share.
fn held_spread(
    m: &LowBandModel,
    frames: &[Vec<realfft::num_complex::Complex<f32>>],
) -> Vec<Vec<f64>> {
    let raw: Vec<Vec<f64>> = frames.iter().map(|s| raw_features(m, s)).collect();
    (0..frames.len())
        .map(|t| {
            (0..m.out.min(m.low))
                .map(|k| {
                    let vals = (0..m.past + 1 + m.future).filter_map(|j| {
                        let u = t as i64 - m.past as i64 + j as i64;
                        (u >= 0).then(|| raw[(u as usize).min(frames.len() - 1)][k])
                    });
                    let (lo, hi) = vals.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                        (lo.min(v), hi.max(v))
                    });
                    hi - lo
                })
                .collect()
        })
        .collect()
}

fn reference(
    m: &LowBandModel,
    frames: &[Vec<realfft::num_complex::Complex<f32>>],
) -> Vec<Vec<f64>> {
    let spread = held_spread(m, frames);
    // Normalised features of every frame.
    let a = HOP as f64 / (2.0 * SR as f64);
    let b = HOP as f64 / (1.0 * SR as f64);
    let mut r = 0.0f64;
    let mut slow = vec![0.0f64; m.slow];
    let feats: Vec<Vec<f64>> = frames
        .iter()
        .enumerate()
        .map(|(t, s)| {
            let raw = raw_features(m, s);
            let mean = raw[..m.low].iter().sum::<f64>() / m.low as f64;
            let w = a.max(1.0 / (t + 1) as f64);
            r += w * (mean - r);
            let mut f: Vec<f64> = raw.iter().map(|v| v - r).collect();
            let ws = b.max(1.0 / (t + 1) as f64);
            for k in 0..m.slow {
                slow[k] += ws * (f[k] - slow[k]);
                f.push(f[k] - slow[k]);
            }
            f
        })
        .collect();
    let per = m.per_frame();
    let n_in = m.inputs();
    (0..frames.len())
        .map(|t| {
            let mut x = Vec::with_capacity(n_in);
            for j in 0..m.past + 1 + m.future {
                let u = t as i64 - m.past as i64 + j as i64;
                if u < 0 {
                    x.extend(std::iter::repeat_n(PAD as f64, per));
                } else {
                    x.extend(&feats[(u as usize).min(frames.len() - 1)]);
                }
            }
            let h: Vec<f64> = (0..m.hidden)
                .map(|j| {
                    let z = m.b1[j] as f64
                        + (0..n_in)
                            .map(|i| x[i] * m.w1[i * m.hidden + j] as f64)
                            .sum::<f64>();
                    z.max(0.0)
                })
                .collect();
            (0..m.out)
                .map(|k| {
                    if spread[t].get(k).is_some_and(|&s| s < STEADY_NATS) {
                        return 0.0;
                    }
                    let z = m.b2[k] as f64
                        + (0..m.hidden)
                            .map(|j| h[j] * m.w2[j * m.out + k] as f64)
                            .sum::<f64>();
                    1.0 / (1.0 + (-z).exp())
                })
                .collect()
        })
        .collect()
}

/// The separator's analysis frames of `x` (all of them, the stream ended).
fn frames_of(x: &[f32]) -> Vec<Vec<realfft::num_complex::Complex<f32>>> {
    let cfg = StftConfig {
        n_fft: N_FFT,
        hop: HOP,
    };
    let mut an = StftAnalysis::new(cfg, 1).unwrap();
    let mut frames = Vec::new();
    an.push(&[x], |_, s| frames.push(s[0].clone()));
    an.finish(|_, s| frames.push(s[0].clone()));
    frames
}

#[test]
fn streaming_mask_equals_the_f64_reference() {
    let frames = frames_of(&signal(4.0));
    let mut lb = LowBand::new(SR, N_FFT, HOP).expect("model for 44.1 kHz / 2048");
    let m = lb.model().clone();
    let want = reference(&m, &frames);
    // Streaming: push frames; after frame t the share is for frame t - future; the stream
    // ends with `future` frames after the end (`None`, which repeat the last frame).
    let mut got = Vec::new();
    let mut share = vec![0.0f32; lb.out_bins()];
    for t in 0..frames.len() + m.future {
        lb.push(frames.get(t).map(|s| s.as_slice()));
        if t >= m.future {
            lb.drum_share(&mut share);
            got.push(share.clone());
        }
    }
    assert_eq!(got.len(), want.len());
    let held = held_spread(&m, &frames);
    let mut worst = 0.0f64;
    let mut spread = (1.0f64, 0.0f64);
    let (mut n_held, mut n_edge) = (0, 0);
    for ((g, w), h) in got.iter().zip(&want).zip(&held) {
        for (k, (a, b)) in g.iter().zip(w).enumerate() {
            // A spread within f32 round-off of the threshold may fall either way.
            if h.get(k).is_some_and(|s| (s - STEADY_NATS).abs() < 1e-4) {
                n_edge += 1;
                continue;
            }
            if h.get(k).is_some_and(|&s| s < STEADY_NATS) {
                n_held += 1;
            }
            worst = worst.max((*a as f64 - b).abs());
            spread = (spread.0.min(*b), spread.1.max(*b));
        }
    }
    // The silent gap holds every bin; the rest of the signal moves.
    assert!(
        n_held > 0 && n_edge < 5,
        "held {n_held}, at the edge {n_edge}"
    );
    println!(
        "{} frames, max |f32 − f64| = {worst:.2e}, shares span {:.3}–{:.3}",
        got.len(),
        spread.0,
        spread.1
    );
    // f32 features (logs of magnitudes, a running mean) and 261·128 + 128·15 f32 products:
    // about 1e-6 relative each; on a sigmoid output 1e-4 absolute is generous yet far below
    // any effect of a misaligned frame or feature (which moves shares by 0.1 or more).
    assert!(worst < 1e-4, "max error {worst}");
    // The signal must exercise the network (not a constant output).
    assert!(spread.1 - spread.0 > 0.3, "shares span only {spread:?}");
}

#[test]
fn reset_reproduces_the_first_run() {
    let frames = frames_of(&signal(2.0));
    let mut lb = LowBand::new(SR, N_FFT, HOP).unwrap();
    let run = |lb: &mut LowBand| {
        let mut out = Vec::new();
        let mut share = vec![0.0f32; lb.out_bins()];
        for f in &frames {
            lb.push(Some(f));
            lb.drum_share(&mut share);
            out.extend_from_slice(&share);
        }
        out
    };
    let first = run(&mut lb);
    lb.reset();
    assert_eq!(first, run(&mut lb));
}

#[test]
fn other_bin_widths_turn_the_mask_off() {
    assert!(LowBand::new(SR, N_FFT, HOP).is_some());
    assert!(LowBand::new(48_000, N_FFT, HOP).is_none());
    assert!(LowBand::new(SR, 4096, HOP).is_none());
    assert!(LowBand::new(SR, 16, 8).is_none());
}

#[test]
fn damaged_weight_files_are_errors() {
    assert!(LowBandModel::parse(WEIGHTS).is_ok());
    assert!(LowBandModel::parse(&[]).is_err());
    assert!(LowBandModel::parse(&WEIGHTS[..WEIGHTS.len() - 4]).is_err());
    let mut bad = WEIGHTS.to_vec();
    bad[0] = b'X';
    assert!(LowBandModel::parse(&bad).is_err());
    let mut bad = WEIGHTS.to_vec();
    bad[4] = 3; // version
    assert!(LowBandModel::parse(&bad).is_err());
    let mut bad = WEIGHTS.to_vec();
    let last = bad.len() - 4;
    bad[last..].copy_from_slice(&f32::NAN.to_le_bytes());
    assert!(LowBandModel::parse(&bad).is_err());
    let mut bad = WEIGHTS.to_vec();
    bad[8..12].copy_from_slice(&u32::MAX.to_le_bytes()); // low bins
    assert!(LowBandModel::parse(&bad).is_err());
}

/// A held sub-bass tone is not a drum body: once the context holds nothing but the tone,
/// its energy keeps its bass share (docs/decisions/0052-kit-mask-spares-held-tones.md).
/// Energy-weighted: far from the tone, where its two spectral images interfere, a bin's
/// level swings from frame to frame, and what the mask does with it moves nothing.
#[test]
fn a_held_sub_bass_tone_keeps_its_bass_share() {
    for f0 in [41.2f32, 55.0] {
        let x: Vec<f32> = (0..2 * SR as usize)
            .map(|i| 0.5 * (std::f32::consts::TAU * f0 * i as f32 / SR as f32).sin())
            .collect();
        let frames = frames_of(&x);
        let mut lb = LowBand::new(SR, N_FFT, HOP).unwrap();
        let mut share = vec![0.0f32; lb.out_bins()];
        let ctx = lb.model().past + 1 + lb.future();
        let mut worst = 0.0f32;
        for (t, s) in frames.iter().enumerate() {
            lb.push(Some(s));
            // The share of frame t − future; from the second context on, a steady tone.
            if t >= lb.future() + ctx && t + 2 < frames.len() {
                lb.drum_share(&mut share);
                let spec = &frames[t - lb.future()];
                let e: Vec<f32> = spec[..share.len()].iter().map(|c| c.norm_sqr()).collect();
                let moved: f32 = share.iter().zip(&e).map(|(p, e)| p * e).sum();
                worst = worst.max(moved / e.iter().sum::<f32>());
            }
        }
        // Without the held rule the network moves all of it (1.0 at 41 Hz).
        assert!(worst < 1e-3, "{f0} Hz: drum share of the energy {worst}");
    }
}
