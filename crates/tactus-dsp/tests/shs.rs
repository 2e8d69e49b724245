//! Tests for the harmonic-sum bass tracker ([`tactus_dsp::shs`]): the salience against a
//! direct-DFT f64 oracle, the decoded path against a naive whole-track Viterbi, pitch on
//! harmonic tones with chord tones above them, the stated latency against emission and
//! against a step, chunking and reset invariance, and an allocation guard.
//!
//! `unsafe` appears once in this file: a `GlobalAlloc` impl must be `unsafe impl`. It only
//! forwards to `System` and counts. The library itself stays `#![forbid(unsafe_code)]`.

use tactus_dsp::framer::Framer;
use tactus_dsp::shs::{Shs, ShsConfig};
use tactus_dsp::yin::PitchEstimate;
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

/// The bass chain's rate: 44.1 kHz decimated by 9.
const SR: u32 = 4900;

fn cfg() -> ShsConfig {
    ShsConfig::new(SR, 35.0, 400.0)
}

fn run(s: &mut Shs, x: &[f32], chunks: &[usize]) -> Vec<PitchEstimate> {
    let mut out = Vec::new();
    let mut i = 0;
    let mut k = 0;
    while i < x.len() {
        let n = chunks[k % chunks.len()].max(1).min(x.len() - i);
        s.process(&x[i..i + n], &mut |h, e| {
            assert_eq!(h, out.len());
            out.push(e)
        });
        i += n;
        k += 1;
    }
    s.finish(&mut |h, e| {
        assert_eq!(h, out.len());
        out.push(e)
    });
    out
}

/// The obvious salience: the same preprocessing, a direct DFT in f64 at each FFT bin, the
/// max over each harmonic's bins, the weighted sum; and the voicing evidence.
fn naive_salience(c: &ShsConfig, frame: &[f32]) -> (Vec<f64>, f64) {
    let n = frame.len();
    let mean = frame.iter().map(|&x| x as f64).sum::<f64>() / n as f64;
    let peak = frame
        .iter()
        .map(|&x| (x as f64 - mean).abs())
        .fold(0.0, f64::max);
    let m = c.n_bins().unwrap();
    if peak <= 1e-9 {
        return (vec![0.0; m], 0.02);
    }
    let x: Vec<f64> = (0..n)
        .map(|i| {
            let w = 0.5 - 0.5 * (std::f64::consts::TAU * (i as f64 + 0.5) / n as f64).cos();
            (frame[i] as f64 - mean) / peak * w
        })
        .collect();
    let nyq = c.n_fft / 2;
    let mag: Vec<f64> = (0..=nyq)
        .map(|k| {
            let (mut re, mut im) = (0.0, 0.0);
            for (i, &v) in x.iter().enumerate() {
                let ph = -std::f64::consts::TAU * (k * i) as f64 / c.n_fft as f64;
                re += v * ph.cos();
                im += v * ph.sin();
            }
            (re * re + im * im).sqrt().powf(c.compress as f64)
        })
        .collect();
    let df = c.sample_rate as f64 / c.n_fft as f64;
    let half = 2f64.powf(c.harmonic_width_st as f64 / 12.0);
    let mut s = vec![0.0; m];
    for (ci, sv) in s.iter_mut().enumerate() {
        let f = c.fmin_hz as f64 * (ci as f64 / (12.0 * c.bins_per_semitone as f64)).exp2();
        let tilt = (f / c.fmin_hz as f64).powf(-(c.low_tilt as f64));
        let mut amps = Vec::new(); // (harmonic number, neighbourhood maximum)
        for h in 1..=c.harmonics {
            let xh = f * h as f64;
            let lo = (xh / half / df).round().max(1.0) as usize;
            let hi = ((xh * half / df).round() as usize).min(nyq);
            if lo > hi || xh > c.max_harmonic_hz as f64 {
                continue;
            }
            let mx = mag[lo..=hi].iter().cloned().fold(0.0, f64::max);
            *sv += tilt * (c.harmonic_decay as f64).powi(h as i32 - 1) * mx;
            amps.push((h, mx));
        }
        // Fundamental presence: the fundamental over the strongest summed harmonic.
        let strongest = amps.iter().map(|a| a.1).fold(0.0, f64::max);
        if c.fundamental_ratio > 0.0 && strongest > 0.0 {
            let first = amps.iter().find(|a| a.0 == 1).map_or(0.0, |a| a.1);
            *sv *= (first / (strongest * c.fundamental_ratio as f64)).min(1.0);
        }
    }
    let best = s.iter().cloned().fold(0.0, f64::max);
    let band_lo = ((c.fmin_hz as f64 / df).floor() as usize).max(1);
    let band_hi = ((c.fmax_hz as f64 * c.harmonics as f64 / df).ceil() as usize)
        .min(nyq)
        .max(band_lo);
    let wsum: f64 = (0..c.harmonics)
        .map(|h| (c.harmonic_decay as f64).powi(h as i32))
        .sum();
    let floor = mag[band_lo..=band_hi].iter().sum::<f64>() / (band_hi + 1 - band_lo) as f64 * wsum;
    let z = ((best / floor).ln() - (c.voicing_ratio as f64).ln()) / 0.5;
    (s, (1.0 / (1.0 + (-z).exp())).clamp(0.02, 0.98))
}

/// A walking bass: harmonic notes of `note_s` seconds on `pitches`, with short gaps.
fn bass_line(pitches: &[f64], note_s: f64, seed: u64) -> (Vec<f32>, Vec<f64>) {
    let per = (note_s * SR as f64) as usize;
    let mut x = Vec::new();
    let mut truth = Vec::new();
    for (k, &f) in pitches.iter().enumerate() {
        let tone = harmonic(SR, f, per, &[1.0, 0.6, 0.4, 0.3, 0.2], seed + k as u64);
        let gap = per / 10;
        for (i, v) in tone.into_iter().enumerate() {
            let env = if i < per - gap { 0.5 } else { 0.0 };
            x.push(v * env);
            truth.push(if i < per - gap { f } else { 0.0 });
        }
    }
    (x, truth)
}

#[test]
fn salience_matches_the_direct_dft_oracle() {
    salience_against_oracle(0.0);
}

#[test]
fn salience_with_fundamental_presence_matches_the_oracle() {
    salience_against_oracle(0.1);
    salience_against_oracle(1.0);
}

/// A bass note and a chord tone a fifth above it (f and 1.5·f, no partials): without the
/// fundamental-presence rule the unsounded f/2 collects both (harmonics 2 and 3) and wins;
/// with it, f wins.
#[test]
fn fundamental_presence_removes_the_common_subharmonic() {
    let mut c = cfg();
    let f = 160.0;
    let frame: Vec<f32> = (0..c.frame)
        .map(|i| {
            let t = i as f64 / SR as f64;
            ((std::f64::consts::TAU * f * t).sin()
                + 0.9 * (std::f64::consts::TAU * 1.5 * f * t).sin()) as f32
        })
        .collect();
    let best = |c: &ShsConfig| {
        let (s, _) = Shs::new(c.clone()).unwrap().frame_salience(&frame);
        let k = (0..s.len()).max_by(|&a, &b| s[a].total_cmp(&s[b])).unwrap();
        c.bin_hz(k)
    };
    let off = best(&c);
    assert!(
        (off / (f as f32 / 2.0) - 1.0).abs() < 0.02,
        "without the rule: {off} Hz"
    );
    c.fundamental_ratio = 0.1;
    let on = best(&c);
    assert!((on / f as f32 - 1.0).abs() < 0.02, "with the rule: {on} Hz");
}

fn salience_against_oracle(fundamental_ratio: f32) {
    let mut c = cfg();
    c.frame = 256; // keep the O(N·n_fft) oracle quick
    c.n_fft = 1024;
    c.fundamental_ratio = fundamental_ratio;
    let mut s = Shs::new(c.clone()).unwrap();
    let mut rng = Rng(7);
    for (f0, noise) in [(55.0, 0.0), (98.0, 0.2), (41.2, 0.05), (180.0, 1.0)] {
        let tone = harmonic(SR, f0, c.frame, &[1.0, 0.5, 0.3, 0.2], 3);
        let frame: Vec<f32> = tone
            .iter()
            .map(|&v| v + (noise * rng.white()) as f32 + 0.3)
            .collect();
        let (fast, v_fast) = s.frame_salience(&frame);
        let (slow, v_slow) = naive_salience(&c, &frame);
        let scale = slow.iter().cloned().fold(0.0, f64::max);
        for (k, (a, b)) in fast.iter().zip(&slow).enumerate() {
            assert!(
                ((*a as f64) - b).abs() <= 1e-4 * scale + 1e-6,
                "f0 {f0}, candidate {k}: fast {a}, oracle {b}"
            );
        }
        assert!(
            (v_fast as f64 - v_slow).abs() < 1e-3,
            "voicing {v_fast} vs {v_slow}"
        );
    }
    // Silence and DC are silent.
    assert_eq!(s.frame_salience(&vec![0.25; c.frame]).1, 0.02);
}

/// Naive whole-track Viterbi in f64 over M voiced states + 1 unvoiced, from the oracle's
/// salience of every frame the framer cuts; returns the decoded state per hop.
#[allow(clippy::needless_range_loop)] // the oracle reads like the textbook
fn naive_viterbi(c: &ShsConfig, x: &[f32]) -> Vec<usize> {
    let m = c.n_bins().unwrap();
    let mut framer = Framer::new(c.frame, c.hop).unwrap();
    let mut obs: Vec<(Vec<f64>, f64)> = Vec::new();
    let mut add = |_: usize, fr: &[f32]| {
        let (s, v) = naive_salience(c, fr);
        let peak = s.iter().cloned().fold(0.0, f64::max);
        let o = s
            .iter()
            .map(|&x| {
                if peak > 0.0 {
                    (v * (x / peak).powf(c.sharpness as f64)).max(1e-30).ln()
                } else {
                    (1e-30f64).ln()
                }
            })
            .collect();
        obs.push((o, (1.0 - v).max(1e-30).ln()));
    };
    framer.push(x, &mut add);
    framer.finish(&mut add);
    let j = c.max_jump_bins;
    let sw = c.switch_prob as f64;
    let jump = |d: usize| {
        if d > j {
            f64::NEG_INFINITY
        } else {
            ((j + 1 - d) as f64 / (j + 1) as f64).ln()
        }
    };
    let t_n = obs.len();
    let mut delta: Vec<f64> = obs[0].0.iter().cloned().chain([obs[0].1]).collect();
    let mut bps: Vec<Vec<usize>> = Vec::new();
    for (o, ou) in obs.iter().skip(1) {
        let mut next = vec![0.0; m + 1];
        let mut bp = vec![0usize; m + 1];
        for k in 0..m {
            let (mut best, mut arg) = (f64::NEG_INFINITY, k);
            for src in 0..m {
                let v = delta[src] + jump(src.abs_diff(k)) + (1.0 - sw).ln();
                if v > best {
                    (best, arg) = (v, src);
                }
            }
            let enter = delta[m] + sw.ln();
            if enter > best {
                (best, arg) = (enter, m);
            }
            next[k] = best + o[k];
            bp[k] = arg;
        }
        let (mut best, mut arg) = (delta[m] + (1.0 - sw).ln(), m);
        for src in 0..m {
            if delta[src] + sw.ln() > best {
                (best, arg) = (delta[src] + sw.ln(), src);
            }
        }
        next[m] = best + ou;
        bp[m] = arg;
        delta = next;
        bps.push(bp);
    }
    let mut s = (0..=m).fold(0, |b, k| if delta[k] > delta[b] { k } else { b });
    let mut path = vec![0; t_n];
    for t in (0..t_n).rev() {
        path[t] = s;
        if t > 0 {
            s = bps[t - 1][s];
        }
    }
    path
}

#[test]
fn decoded_path_matches_a_naive_whole_track_viterbi() {
    let mut c = cfg();
    c.frame = 256;
    c.n_fft = 1024;
    c.hop = 98; // 20 ms: fewer frames for the O(T·M²) oracle
    let (x, _) = bass_line(&[55.0, 82.4, 73.4, 110.0], 0.4, 11);
    let c0 = c.clone();
    let state_hz = |k: usize| c0.bin_hz(k) as f64;
    let want = naive_viterbi(&c, &x);
    // Streaming with a lag longer than the track is exactly offline Viterbi.
    c.lag_hops = want.len() + 1;
    let got = run(&mut Shs::new(c.clone()).unwrap(), &x, &[x.len()]);
    assert_eq!(got.len(), want.len());
    let m = c.n_bins().unwrap();
    for (t, (e, &s)) in got.iter().zip(&want).enumerate() {
        if s == m {
            assert_eq!(e.f0_hz, 0.0, "hop {t}: oracle unvoiced");
        } else {
            // Same bin: the refinement moves the f0 by at most half a bin.
            let d = cents(e.f0_hz as f64, state_hz(s)).abs();
            assert!(
                d <= 100.0 / (2.0 * c.bins_per_semitone as f64) + 0.5,
                "hop {t}: {} Hz vs bin {s} ({d} cents)",
                e.f0_hz
            );
        }
    }
}

#[test]
fn tracks_a_bass_line_under_chord_tones() {
    let pitches = [41.2, 55.0, 61.7, 73.4, 98.0, 110.0, 130.8, 82.4];
    let (bass, truth) = bass_line(&pitches, 0.5, 5);
    // A sustained triad an octave and more above (what leaks into a separated bass stem).
    let chord: Vec<f32> = [220.0, 277.2, 329.6]
        .iter()
        .map(|&f| harmonic(SR, f, bass.len(), &[0.25, 0.1], 9))
        .fold(vec![0.0; bass.len()], |acc, v| {
            acc.iter().zip(&v).map(|(a, b)| a + b).collect()
        });
    for (name, x) in [
        ("bass alone", bass.clone()),
        (
            "bass + chord",
            bass.iter()
                .zip(&chord)
                .map(|(a, b)| a + b)
                .collect::<Vec<_>>(),
        ),
    ] {
        let mut s = Shs::new(cfg()).unwrap();
        let est = run(&mut s, &x, &[4096]);
        let hop = cfg().hop;
        let (mut ok, mut n) = (0, 0);
        for (i, e) in est.iter().enumerate() {
            let t = truth.get(i * hop).copied().unwrap_or(0.0);
            // Skip hops within a frame of a note change.
            let near_change = (i * hop).saturating_sub(cfg().frame / 2)
                ..(i * hop + cfg().frame / 2).min(truth.len());
            if t == 0.0 || near_change.clone().any(|k| truth[k] != t) {
                continue;
            }
            n += 1;
            if e.f0_hz > 0.0 && cents(e.f0_hz as f64, t).abs() <= 50.0 {
                ok += 1;
            }
        }
        let rpa = ok as f64 / n as f64;
        assert!(rpa >= 0.95, "{name}: RPA {rpa} over {n} hops");
    }
}

#[test]
fn stated_latency_matches_emission_and_a_step() {
    let c = cfg();
    let (x, _) = bass_line(&[55.0, 110.0], 0.6, 1);
    let mut s = Shs::new(c.clone()).unwrap();
    let (hop, lat) = (s.hop(), s.latency_samples());
    assert_eq!(lat, c.frame - c.frame / 2 + c.lag_hops * c.hop);
    let mut emitted = 0usize;
    for (k, &v) in x.iter().enumerate() {
        s.process(&[v], &mut |i, _| {
            assert_eq!(i, emitted);
            emitted += 1;
        });
        let expect = if k + 1 >= lat {
            (k + 1 - lat) / hop + 1
        } else {
            0
        };
        assert_eq!(emitted, expect.min(x.len().div_ceil(hop)), "sample {k}");
    }
    // A step: silence, then a tone at sample s0. The first voiced hop is centred within
    // half a frame of s0 (the time stamps carry no extra delay) ...
    let s0 = 2 * SR as usize;
    let mut y = vec![0.0f32; s0];
    y.extend(harmonic(SR, 73.4, SR as usize, &[1.0, 0.5, 0.3], 2));
    let mut s = Shs::new(c.clone()).unwrap();
    let mut first: Option<(usize, usize)> = None; // (hop, samples fed when emitted)
    for (k, &v) in y.iter().enumerate() {
        s.process(&[v], &mut |i, e| {
            if first.is_none() && e.f0_hz > 0.0 {
                first = Some((i, k + 1));
            }
        });
    }
    let (h, fed) = first.expect("the tone is found");
    let centre = h * hop;
    assert!(
        centre + c.frame / 2 >= s0 && centre <= s0 + c.frame / 2,
        "first voiced hop {h} (sample {centre}) vs step at {s0}"
    );
    // ... and it is known exactly `latency` samples after its centre.
    assert_eq!(fed, centre + lat, "measured vs stated latency");
}

#[test]
fn chunking_and_reset_do_not_change_the_output() {
    let (x, _) = bass_line(&[49.0, 65.4, 98.0, 87.3, 58.3], 0.35, 21);
    let mut s = Shs::new(cfg()).unwrap();
    let whole = run(&mut s, &x, &[x.len()]);
    for chunks in [vec![1usize, 7, 300], vec![49], vec![4096, 13]] {
        s.reset();
        assert_eq!(run(&mut s, &x, &chunks), whole, "chunks {chunks:?}");
    }
    assert_eq!(whole.len(), x.len().div_ceil(cfg().hop));
}

#[test]
fn invalid_configs_are_rejected() {
    type Edit = Box<dyn Fn(&mut ShsConfig)>;
    let bad: Vec<Edit> = vec![
        Box::new(|c| c.fmin_hz = 0.0),
        Box::new(|c| c.fmax_hz = 3000.0),
        Box::new(|c| c.n_fft = c.frame / 2),
        Box::new(|c| c.hop = 0),
        Box::new(|c| c.harmonics = 0),
        Box::new(|c| c.switch_prob = 1.0),
        Box::new(|c| c.max_jump_bins = 10_000),
        Box::new(|c| c.sharpness = f32::NAN),
        Box::new(|c| c.fundamental_ratio = 1.5),
        Box::new(|c| c.fundamental_ratio = f32::NAN),
    ];
    for (k, f) in bad.iter().enumerate() {
        let mut c = cfg();
        f(&mut c);
        assert!(Shs::new(c).is_err(), "case {k}");
    }
}

#[test]
fn no_allocation_after_construction() {
    let (x, _) = bass_line(&[55.0, 82.4], 0.5, 3);
    let mut s = Shs::new(cfg()).unwrap();
    let mut sink = 0usize;
    let n = count_allocs(|| {
        for ch in x.chunks(333) {
            s.process(ch, &mut |_, e| sink += (e.f0_hz > 0.0) as usize);
        }
        s.finish(&mut |_, e| sink += (e.f0_hz > 0.0) as usize);
        s.reset();
    });
    assert_eq!(n, 0, "allocations in process/finish/reset");
    assert!(sink > 0);
}

/// The melody defaults follow a lead (8 harmonics at 1/h, A3–D5) over a sustained C major
/// triad below it, each chord tone 8 dB under the lead (3 partials), together about as loud
/// as the lead. Lead notes
/// an exact octave above a chord tone are left out: there the chord tone's harmonic sum
/// holds the whole lead and the two readings are equally good. Hops within half a frame of a
/// note change are skipped.
#[test]
fn melody_defaults_track_a_lead_over_chords() {
    const MSR: u32 = 14_700;
    let c = ShsConfig::melody(MSR, 70.0, 1400.0);
    assert_eq!(c.frame, 1024, "about 70 ms at 14.7 kHz");
    let notes = [293.7, 349.2, 440.0, 493.9, 587.3, 440.0, 220.0, 293.7];
    let note_n = (0.4 * MSR as f64) as usize;
    let mut lead = Vec::new();
    let mut truth = Vec::new();
    let amps: Vec<f64> = (1..=8).map(|h| 1.0 / h as f64).collect();
    for (k, &f) in notes.iter().enumerate() {
        lead.extend(harmonic(MSR, f, note_n, &amps, 20 + k as u64));
        truth.extend(std::iter::repeat_n(f, note_n));
    }
    let chord = [130.8, 164.8, 196.0]
        .iter()
        .map(|&f| harmonic(MSR, f, lead.len(), &[0.4, 0.2, 0.1], 31))
        .fold(vec![0.0; lead.len()], |acc, v| {
            acc.iter().zip(&v).map(|(a, b)| a + b).collect()
        });
    let x: Vec<f32> = lead.iter().zip(&chord).map(|(a, b)| a + b).collect();
    let rpa = |c: &ShsConfig| {
        let mut s = Shs::new(c.clone()).unwrap();
        let est = run(&mut s, &x, &[4096]);
        let (mut ok, mut n) = (0, 0);
        for (i, e) in est.iter().enumerate() {
            let at = i * c.hop;
            let Some(&t) = truth.get(at) else { continue };
            let span = at.saturating_sub(c.frame / 2)..(at + c.frame / 2).min(truth.len());
            if span.clone().any(|k| truth[k] != t) {
                continue;
            }
            n += 1;
            if e.f0_hz > 0.0 && cents(e.f0_hz as f64, t).abs() <= 50.0 {
                ok += 1;
            }
        }
        assert!(n > 100, "{n} hops scored");
        ok as f64 / n as f64
    };
    let melody = rpa(&c);
    // The bass defaults over the same range (harmonics only below 320 Hz) cannot see the
    // lead's upper partials: the test can tell the two apart.
    let bass = rpa(&ShsConfig::new(MSR, 70.0, 1400.0));
    eprintln!("lead RPA: melody defaults {melody:.3}, bass defaults {bass:.3}");
    assert!(melody >= 0.95, "melody defaults: RPA {melody}");
    assert!(bass < melody - 0.2, "bass defaults: RPA {bass}");
}
