//! Tests for the learned bass salience ([`tactus_dsp::bassnet`]) and the harmonic-sum
//! tracker in its learned mode ([`tactus_dsp::shs::ShsConfig::learned`]): the embedded
//! model's file against a separate f64 reader and forward pass, the front end against a
//! direct DFT, bad files, the stated latency against emission and a step, chunking and
//! reset invariance, no allocation after construction, and a bass line on clean tones.
//!
//! `unsafe` appears once in this file: a `GlobalAlloc` impl must be `unsafe impl`.

mod common;

use tactus_dsp::bassnet::{BassFront, BassNet, BANDS, BINS_PER_SEMITONE, LOW_HZ, RANGE_DB};
use tactus_dsp::shs::{Shs, ShsConfig, WithDecoded};
use tactus_dsp::HopStage;
use tactus_testkit::Rng;

#[global_allocator]
static GLOBAL: tactus_testkit::Counting = tactus_testkit::Counting;

/// Uniform in `[0, 1)` from the shared seeded generator.
fn uniform(rng: &mut Rng) -> f64 {
    (f64::from(rng.next_f32()) + 1.0) / 2.0
}

/// The bass chain's rate (44.1 kHz decimated by 9).
const SR: u32 = 4900;

fn cfg() -> ShsConfig {
    let mut c = ShsConfig::new(SR, 35.0, 400.0);
    c.learned = true;
    c
}

const WEIGHTS: &[u8] = include_bytes!("../weights/bassnet.bin");

/// The weight file read by hand, in f64: offsets and `(n_in, n_out, w[n_out][n_in], b)`.
struct Oracle {
    offsets: Vec<i32>,
    layers: Vec<(usize, usize, Vec<f64>, Vec<f64>)>,
}

fn oracle() -> Oracle {
    oracle_of(WEIGHTS, BANDS, LOW_HZ)
}

/// The lead model's file (`BassNet::embedded_lead`).
const LEAD_WEIGHTS: &[u8] = include_bytes!("../weights/leadnet.bin");

fn oracle_of(b: &[u8], bands: usize, low_hz: f32) -> Oracle {
    let u32_at = |o: usize| u32::from_le_bytes(b[o..o + 4].try_into().unwrap());
    let f32_at = |o: usize| f32::from_le_bytes(b[o..o + 4].try_into().unwrap()) as f64;
    assert_eq!(&b[..8], b"TACTUSBN");
    assert_eq!(u32_at(8), 1);
    assert_eq!(u32_at(12) as usize, bands);
    assert_eq!(u32_at(16), BINS_PER_SEMITONE);
    assert_eq!(f32_at(20) as f32, low_hz);
    assert_eq!(f32_at(24) as f32, RANGE_DB);
    let n_off = u32_at(28) as usize;
    let mut o = 32;
    let offsets = (0..n_off)
        .map(|k| i32::from_le_bytes(b[o + 4 * k..o + 4 * k + 4].try_into().unwrap()))
        .collect();
    o += 4 * n_off + 8; // candidates, cand_fmin
    let n_layers = u32_at(o) as usize;
    o += 4;
    let mut layers = Vec::new();
    for _ in 0..n_layers {
        let (n_in, n_out) = (u32_at(o) as usize, u32_at(o + 4) as usize);
        o += 8;
        let w = (0..n_in * n_out).map(|k| f32_at(o + 4 * k)).collect();
        o += 4 * n_in * n_out;
        let bias = (0..n_out).map(|k| f32_at(o + 4 * k)).collect();
        o += 4 * n_out;
        layers.push((n_in, n_out, w, bias));
    }
    assert_eq!(o, b.len());
    Oracle { offsets, layers }
}

fn oracle_forward(or: &Oracle, x: &[f64]) -> Vec<f64> {
    let mut h = x.to_vec();
    let last = or.layers.len() - 1;
    for (li, (n_in, n_out, w, b)) in or.layers.iter().enumerate() {
        h = (0..*n_out)
            .map(|r| {
                let s: f64 = (0..*n_in).map(|c| w[r * n_in + c] * h[c]).sum::<f64>() + b[r];
                if li == last {
                    s
                } else {
                    s.max(0.0)
                }
            })
            .collect();
    }
    let mx = h.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let lse = mx + h.iter().map(|v| (v - mx).exp()).sum::<f64>().ln();
    h.iter().map(|v| v - lse).collect()
}

/// `n` random values like the front end's: in [0, 1], 30 % of them 0 (bands 60 dB down).
fn front_like_input(rng: &mut Rng, n: usize) -> Vec<f32> {
    (0..n)
        .map(|_| {
            let u = uniform(rng);
            if u < 0.3 {
                0.0
            } else {
                u as f32
            }
        })
        .collect()
}

/// `trials` random inputs like the front end's (in [0, 1], many at 0: bands 60 dB down)
/// through `net` and through the f64 reader `or`: the log-probabilities agree within 1e-3
/// (f32 sums of ~1,100 products against f64) and the probabilities sum to 1.
fn check_against_oracle(net: &BassNet, or: &Oracle, seed: u64, trials: usize) {
    let mut rng = Rng::new(seed);
    let w = net.width().max(net.input_len());
    let (mut a, mut b) = (vec![0.0f32; w], vec![0.0f32; w]);
    let mut out = vec![0.0f32; net.candidates() + 1];
    for trial in 0..trials {
        let x = front_like_input(&mut rng, net.input_len());
        net.forward(&x, &mut a, &mut b, &mut out);
        let want = oracle_forward(or, &x.iter().map(|&v| v as f64).collect::<Vec<_>>());
        for (k, (&g, &e)) in out.iter().zip(&want).enumerate() {
            assert!(
                (g as f64 - e).abs() < 1e-3,
                "trial {trial} class {k}: {g} vs {e}"
            );
        }
        let total: f64 = out.iter().map(|&v| (v as f64).exp()).sum();
        assert!((total - 1.0).abs() < 1e-4, "probabilities sum to {total}");
    }
}

#[test]
fn embedded_model_matches_a_separate_f64_reader() {
    let net = BassNet::embedded();
    let or = oracle();
    assert_eq!(net.offsets(), &or.offsets[..]);
    assert_eq!(
        net.candidates(),
        ShsConfig::new(SR, 35.0, 400.0).n_bins().unwrap()
    );
    assert_eq!(net.input_len(), or.offsets.len() * BANDS);
    check_against_oracle(net, &or, 5, 5);
}

#[test]
fn embedded_lead_model_matches_a_separate_f64_reader() {
    // The lead chain's rate (44.1 kHz decimated for 1400 Hz) and its melody grid.
    let net = BassNet::embedded_lead();
    let or = oracle_of(LEAD_WEIGHTS, 216, 70.0);
    assert_eq!(net.offsets(), &[-6, -3, 0, 3]);
    assert_eq!(net.offsets(), &or.offsets[..]);
    assert_eq!(
        (net.bands(), net.low_hz(), net.cand_fmin_hz()),
        (216, 70.0, 70.0)
    );
    assert_eq!(
        net.candidates(),
        ShsConfig::melody(14_700, 70.0, 1400.0).n_bins().unwrap()
    );
    check_against_oracle(net, &or, 9, 3);
}

/// The second lead model's file (`BassNet::embedded_lead_sung`).
const LEAD_SUNG_WEIGHTS: &[u8] = include_bytes!("../weights/leadnet_sung.bin");

/// The third lead model's file (`BassNet::embedded_lead_3`).
const LEAD_3_WEIGHTS: &[u8] = include_bytes!("../weights/leadnet_3.bin");

#[test]
fn embedded_sung_lead_model_matches_a_separate_f64_reader_and_the_first_lead_models_layout() {
    check_lead_member(BassNet::embedded_lead_sung(), LEAD_SUNG_WEIGHTS, 11);
}

#[test]
fn embedded_third_lead_model_matches_a_separate_f64_reader_and_the_first_lead_models_layout() {
    check_lead_member(BassNet::embedded_lead_3(), LEAD_3_WEIGHTS, 13);
    assert_ne!(BassNet::embedded_lead_3(), BassNet::embedded_lead_sung());
}

/// A lead ensemble member: its file read by the f64 oracle, and the first lead model's
/// front end, context and classes.
fn check_lead_member(net: &BassNet, weights: &[u8], seed: u64) {
    check_member_of(BassNet::embedded_lead(), net, weights, seed);
}

/// `net` read from `weights` by the f64 oracle, with `first`'s front end, context and
/// classes, and not `first` itself.
fn check_member_of(first: &BassNet, net: &BassNet, weights: &[u8], seed: u64) {
    let or = oracle_of(weights, first.bands(), first.low_hz());
    assert_eq!(net.offsets(), &or.offsets[..]);
    assert_eq!(net.offsets(), first.offsets());
    assert_eq!(
        (
            net.bands(),
            net.low_hz(),
            net.cand_fmin_hz(),
            net.candidates()
        ),
        (
            first.bands(),
            first.low_hz(),
            first.cand_fmin_hz(),
            first.candidates()
        )
    );
    assert_ne!(net, first, "a different model");
    check_against_oracle(net, &or, seed, 3);
}

#[test]
fn the_lead_ensemble_is_the_mean_of_its_models_probabilities() {
    // `forward_ensemble_batch` with the embedded members against their f64 readers:
    // log(Σᵢ pᵢ / n) per class, within 1e-3, on front-end-like inputs, three hops at once;
    // each hop's row is the same bits as that hop alone; the mean is a distribution; no
    // allocation. For two members it is `forward_mean`, bit for bit.
    let n1 = BassNet::embedded_lead();
    let others = BassNet::embedded_lead_others();
    assert_eq!(others.len(), 2, "the sung model and the third");
    assert!(std::ptr::eq(others[0], BassNet::embedded_lead_sung()));
    assert!(std::ptr::eq(others[1], BassNet::embedded_lead_3()));
    let oracles = [
        oracle_of(LEAD_WEIGHTS, 216, 70.0),
        oracle_of(LEAD_SUNG_WEIGHTS, 216, 70.0),
        oracle_of(LEAD_3_WEIGHTS, 216, 70.0),
    ];
    const HOPS: usize = 3;
    let mut rng = Rng::new(5);
    let (len, c) = (n1.input_len(), n1.candidates() + 1);
    let w = HOPS * n1.width().max(len);
    let (mut a, mut b) = (vec![0.0f32; w], vec![0.0f32; w]);
    let mut out = vec![0.0f32; HOPS * c];
    let mut scratch = vec![0.0f32; others.len() * HOPS * c];
    let (mut one, mut one_scratch) = (vec![0.0f32; c], vec![0.0f32; others.len() * c]);
    let (mut single, mut pair, mut pair_scratch) =
        (vec![0.0f32; c], vec![0.0f32; c], vec![0.0f32; c]);
    let mut moved = 0usize;
    for trial in 0..3 {
        let x: Vec<f32> = (0..HOPS)
            .flat_map(|_| front_like_input(&mut rng, len))
            .collect();
        let allocs = tactus_testkit::allocations_during(|| {
            n1.forward_ensemble_batch(&others, &x, HOPS, &mut a, &mut b, &mut out, &mut scratch);
        });
        assert_eq!(allocs, 0);
        for h in 0..HOPS {
            let xh = &x[h * len..(h + 1) * len];
            let got = &out[h * c..(h + 1) * c];
            n1.forward_ensemble_batch(&others, xh, 1, &mut a, &mut b, &mut one, &mut one_scratch);
            for (p, q) in got.iter().zip(&one) {
                assert_eq!(
                    p.to_bits(),
                    q.to_bits(),
                    "trial {trial} hop {h}: batch and alone"
                );
            }
            let xd: Vec<f64> = xh.iter().map(|&v| v as f64).collect();
            let ls: Vec<Vec<f64>> = oracles.iter().map(|o| oracle_forward(o, &xd)).collect();
            for k in 0..c {
                let want = (ls.iter().map(|l| l[k].exp()).sum::<f64>() / ls.len() as f64).ln();
                assert!(
                    (got[k] as f64 - want).abs() < 1e-3,
                    "trial {trial} hop {h} class {k}: {} vs {want}",
                    got[k]
                );
            }
            let total: f64 = got.iter().map(|&v| (v as f64).exp()).sum();
            assert!((total - 1.0).abs() < 1e-4, "probabilities sum to {total}");
            n1.forward(xh, &mut a, &mut b, &mut single);
            moved += got
                .iter()
                .zip(&single)
                .filter(|(p, q)| (**p - **q).abs() > 1e-3)
                .count();
            // Two members: the general path is `forward_mean`'s arithmetic.
            n1.forward_mean(others[0], xh, &mut a, &mut b, &mut pair, &mut pair_scratch);
            n1.forward_ensemble_batch(
                &others[..1],
                xh,
                1,
                &mut a,
                &mut b,
                &mut one,
                &mut one_scratch,
            );
            for (p, q) in pair.iter().zip(&one) {
                assert_eq!(
                    p.to_bits(),
                    q.to_bits(),
                    "trial {trial} hop {h}: two members"
                );
            }
            let want2: Vec<f64> = (0..c)
                .map(|k| (0.5 * ls[0][k].exp() + 0.5 * ls[1][k].exp()).ln())
                .collect();
            for k in 0..c {
                assert!(
                    (pair[k] as f64 - want2[k]).abs() < 1e-3,
                    "two members, class {k}"
                );
            }
        }
    }
    assert!(moved > 0, "the other models change the output");
}

#[test]
fn the_ensemble_needs_the_leads_grid_and_streams_without_allocating() {
    let mut bass = cfg();
    bass.learned_ensemble = true;
    assert!(Shs::new(bass).is_err(), "the bass grid has no second model");
    // The lead chain's rate and grid, as the engine runs it.
    let mut lead = ShsConfig::melody(14_700, 70.0, 1400.0);
    lead.learned = true;
    lead.learned_ensemble = true;
    let mut t = Shs::new(lead.clone()).unwrap();
    // A 330 Hz tone with five harmonics, 2 s.
    let x: Vec<f32> = (0..14_700 * 2)
        .map(|i| {
            let ph = std::f32::consts::TAU * 330.0 * i as f32 / 14_700.0;
            (1..=5)
                .map(|h| 0.3 * (h as f32 * ph).sin() / h as f32)
                .sum::<f32>()
        })
        .collect();
    let mut n = 0usize;
    t.process(&x[..4096], &mut |_, _| n += 1);
    let allocs = tactus_testkit::allocations_during(|| {
        t.process(&x[4096..], &mut |_, _| n += 1);
    });
    assert_eq!(allocs, 0);
    assert!(n > 100, "{n} hops");
    // Chunking does not change it.
    let run = |chunk: usize| {
        let mut t = Shs::new(lead.clone()).unwrap();
        let mut v = Vec::new();
        for c in x.chunks(chunk) {
            t.process(c, &mut |_, e| v.push(e.f0_hz));
        }
        t.finish(&mut |_, e| v.push(e.f0_hz));
        v
    };
    let whole = run(x.len());
    assert_eq!(run(1000), whole);
    assert_eq!(run(147), whole);
    let voiced: Vec<f32> = whole.iter().copied().filter(|&f| f > 0.0).collect();
    assert!(voiced.len() * 2 > whole.len(), "the tone is voiced");
    let near = voiced
        .iter()
        .filter(|&&f| (f / 330.0 - 1.0).abs() < 0.03)
        .count();
    assert!(
        near * 10 >= voiced.len() * 9,
        "{near} of {} voiced hops at 330 Hz",
        voiced.len()
    );
}

#[test]
fn bad_model_files_are_errors() {
    for n in [0, 7, 8, 30, WEIGHTS.len() / 2, WEIGHTS.len() - 1] {
        assert!(BassNet::from_bytes(&WEIGHTS[..n]).is_err(), "prefix {n}");
    }
    let mut foreign = WEIGHTS.to_vec();
    foreign[0] = b'X';
    assert!(BassNet::from_bytes(&foreign).is_err());
    let mut other_front = WEIGHTS.to_vec();
    other_front[12] ^= 1; // bands
    assert!(BassNet::from_bytes(&other_front).is_err());
    let mut nan = WEIGHTS.to_vec();
    let at = WEIGHTS.len() - 4; // the last bias
    nan[at..].copy_from_slice(&f32::NAN.to_le_bytes());
    assert!(BassNet::from_bytes(&nan).is_err());
    let mut trailing = WEIGHTS.to_vec();
    trailing.push(0);
    assert!(BassNet::from_bytes(&trailing).is_err());
    assert!(BassNet::from_bytes(WEIGHTS).is_ok());
}

/// The front end in f64 with a direct DFT: the module docs' steps 1 and 2.
fn naive_features(frame: &[f32], n_fft: usize) -> Vec<f64> {
    let n = frame.len();
    let mean = frame.iter().map(|&x| x as f64).sum::<f64>() / n as f64;
    let peak = frame
        .iter()
        .map(|&x| (x as f64 - mean).abs())
        .fold(0.0, f64::max);
    if peak <= 1e-9 {
        return vec![0.0; BANDS];
    }
    let x: Vec<f64> = (0..n)
        .map(|i| {
            let w = 0.5 - 0.5 * (std::f64::consts::TAU * (i as f64 + 0.5) / n as f64).cos();
            (frame[i] as f64 - mean) / peak * w
        })
        .collect();
    let df = SR as f64 / n_fft as f64;
    let half = 2f64.powf(1.0 / (6.0 * BINS_PER_SEMITONE as f64));
    let power = |k: usize| {
        let (mut re, mut im) = (0.0, 0.0);
        for (i, &v) in x.iter().enumerate() {
            let ph = -std::f64::consts::TAU * (k * i % n_fft) as f64 / n_fft as f64;
            re += v * ph.cos();
            im += v * ph.sin();
        }
        re * re + im * im
    };
    let db: Vec<f64> = (0..BANDS)
        .map(|b| {
            let f = LOW_HZ as f64 * (b as f64 / (12.0 * BINS_PER_SEMITONE as f64)).exp2();
            let lo = ((f / half / df).round() as usize).max(1);
            let hi = ((f * half / df).round() as usize).max(lo);
            let p = (lo..=hi).map(power).fold(0.0, f64::max);
            10.0 * p.max(1e-24).log10()
        })
        .collect();
    let top = db.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let r = RANGE_DB as f64;
    db.iter()
        .map(|d| ((d - top + r) / r).clamp(0.0, 1.0))
        .collect()
}

#[test]
fn front_end_matches_a_direct_dft() {
    let c = ShsConfig::new(SR, 35.0, 400.0);
    let mut front = BassFront::with_bands(SR, c.frame, c.n_fft, BANDS, LOW_HZ).unwrap();
    let mut rng = Rng::new(9);
    let mut got = vec![0.0f32; BANDS];
    for (trial, f0) in [55.0, 98.0, 41.2].into_iter().enumerate() {
        let frame: Vec<f32> = (0..c.frame)
            .map(|i| {
                let t = i as f64 / SR as f64;
                let tone: f64 = (1..=6)
                    .map(|h| (std::f64::consts::TAU * f0 * h as f64 * t).sin() / h as f64)
                    .sum();
                (0.3 * tone + 0.01 * (uniform(&mut rng) - 0.5) + 0.2) as f32
            })
            .collect();
        assert!(front.features(&frame, &mut got));
        let want = naive_features(&frame, c.n_fft);
        for (b, (&g, &e)) in got.iter().zip(&want).enumerate() {
            // 1e-3 of the 60 dB range = 0.06 dB.
            assert!(
                (g as f64 - e).abs() < 1e-3,
                "trial {trial} band {b}: {g} vs {e}"
            );
        }
    }
    // Silence: all zeros, reported silent.
    assert!(!front.features(&vec![0.25f32; c.frame], &mut got));
    assert!(got.iter().all(|&v| v == 0.0));
}

/// A bass line of harmonic notes (5 harmonics at 1/h), `note_s` each, short gaps.
fn bass_line(pitches: &[f64], note_s: f64) -> (Vec<f32>, Vec<f64>) {
    let per = (note_s * SR as f64) as usize;
    let (mut x, mut truth) = (Vec::new(), Vec::new());
    for &f in pitches {
        let gap = per / 10;
        for i in 0..per {
            let t = i as f64 / SR as f64;
            let on = i < per - gap;
            let v: f64 = (1..=5)
                .map(|h| (std::f64::consts::TAU * f * h as f64 * t).sin() * 0.6 / h as f64)
                .sum();
            x.push(if on { (0.4 * v) as f32 } else { 0.0 });
            truth.push(if on { f } else { 0.0 });
        }
    }
    (x, truth)
}

/// The network was trained on separated bass stems of mixes; on bare synthetic tones it is
/// cautious about voicing (with the embedded model the lone 110 Hz note here stays unvoiced),
/// so this checks the pitch where it speaks, and that it speaks on most of the line.
#[test]
fn tracks_a_clean_bass_line() {
    let (x, truth) = bass_line(&[55.0, 82.4, 65.4, 110.0, 49.0, 73.4], 0.5);
    let mut s = Shs::new(cfg()).unwrap();
    let out = common::run(&mut s, &x, &[4096]);
    let hop = s.hop();
    let (mut ok, mut voiced, mut n) = (0, 0, 0);
    for (h, e) in out.iter().enumerate() {
        // Hops at least 100 ms inside a note.
        let t = h * hop;
        if t < 490 || t + 490 >= truth.len() || !(t - 490..t + 490).all(|j| truth[j] > 0.0) {
            continue;
        }
        n += 1;
        if e.f0_hz > 0.0 {
            voiced += 1;
            if (1200.0 * (e.f0_hz as f64 / truth[t]).log2()).abs() < 50.0 {
                ok += 1;
            }
        }
    }
    assert!(n > 150);
    let share = voiced as f64 / n as f64;
    assert!(
        share >= 0.6,
        "voiced on {share:.3} of {n} hops inside notes"
    );
    let acc = ok as f64 / voiced as f64;
    // A note's first voiced hops can still glide in from below (−40 to −60 cents).
    assert!(
        acc >= 0.95,
        "pitch within 50 cents on {acc:.3} of {voiced} voiced hops"
    );
}

/// A learned tracker's voiced estimate carries the network's confidence in its pitch,
/// `1 − aperiodicity` = the probability of the candidates within `CONFIDENCE_BINS` of the
/// decided one (`tactus_dsp::shs` module docs, "Learned salience"): a part of the network's
/// voicing probability `1 − p(no pitch)`, so never above it, and high inside clean notes. The
/// harmonic sum's estimates, and the learned tracker's unvoiced ones, keep
/// `aperiodicity = 1 − voiced_prob`.
#[test]
fn a_learned_trackers_estimates_carry_its_confidence_in_their_pitch() {
    let (x, truth) = bass_line(&[55.0, 82.4, 65.4, 110.0, 49.0, 73.4], 0.5);
    let mut s = Shs::new(cfg()).unwrap();
    let out = common::run(&mut s, &x, &[4096]);
    let hop = s.hop();
    let (mut inside, mut sure, mut below, mut voiced) = (0, 0, 0, 0);
    for (h, e) in out.iter().enumerate() {
        if !e.is_voiced() {
            assert_eq!(
                e.aperiodicity.to_bits(),
                (1.0 - e.voiced_prob).to_bits(),
                "hop {h}"
            );
            continue;
        }
        voiced += 1;
        let c = 1.0 - e.aperiodicity;
        assert!(
            (0.0..=e.voiced_prob + 1e-5).contains(&c),
            "hop {h}: confidence {c} against voicing {}",
            e.voiced_prob
        );
        below += usize::from(c < e.voiced_prob - 0.01);
        let t = h * hop;
        if t >= 490 && t + 490 < truth.len() && (t - 490..t + 490).all(|j| truth[j] > 0.0) {
            inside += 1;
            sure += usize::from(c >= 0.7);
        }
    }
    assert!(
        voiced > 100 && inside > 80,
        "{voiced} voiced, {inside} voiced inside notes"
    );
    assert!(
        sure * 10 >= inside * 9,
        "sure (≥ 0.7) on {sure} of {inside} hops inside clean notes"
    );
    assert!(below > 0, "the confidence is not the voicing probability");
    let mut c = cfg();
    c.learned = false;
    let mut plain = Shs::new(c).unwrap();
    for (h, e) in common::run(&mut plain, &x, &[4096]).iter().enumerate() {
        assert_eq!(
            e.aperiodicity.to_bits(),
            (1.0 - e.voiced_prob).to_bits(),
            "hop {h}"
        );
    }
}

#[test]
fn stated_latency_matches_emission_and_a_step() {
    let c = cfg();
    let future = BassNet::embedded().future();
    let (x, _) = bass_line(&[55.0, 110.0], 0.6);
    let mut s = Shs::new(c.clone()).unwrap();
    let (hop, lat) = (s.hop(), s.latency_samples());
    assert_eq!(lat, c.frame - c.frame / 2 + (c.lag_hops + future) * c.hop);
    common::assert_emission_follows_latency(&mut s, &x);
    // A step: silence, then a bass note at s0; the first voiced hop lies within a frame of
    // it and is known exactly `latency` samples after its centre.
    let s0 = 2 * SR as usize;
    let mut y = vec![0.0f32; s0];
    y.extend(bass_line(&[73.4], 1.0).0);
    let mut s = Shs::new(c.clone()).unwrap();
    // (first voiced hop, samples fed when it came out)
    let (h, fed) = common::first_voiced(&mut s, &y).expect("the note is found");
    let centre = h * hop;
    assert!(
        centre + c.frame >= s0 && centre <= s0 + c.frame,
        "first voiced hop {h} (sample {centre}) vs step at {s0}"
    );
    assert_eq!(fed, centre + lat, "measured vs stated latency");
}

#[test]
fn chunking_and_reset_do_not_change_the_output() {
    let (x, _) = bass_line(&[49.0, 65.4, 98.0, 87.3, 58.3], 0.35);
    let mut with_register = cfg();
    with_register.register_sigma_st = 12.0;
    with_register.register_min_hops = 20;
    common::assert_chunking_and_reset_invariant(&[cfg(), with_register], &x);
}

#[test]
fn a_grid_other_than_the_models_is_rejected() {
    for edit in [
        (|c: &mut ShsConfig| c.fmin_hz = 40.0) as fn(&mut ShsConfig),
        |c| c.fmax_hz = 300.0,
        |c| c.bins_per_semitone = 2,
    ] {
        let mut c = cfg();
        edit(&mut c);
        assert!(Shs::new(c).is_err());
    }
}

#[test]
fn no_allocation_after_construction() {
    let (x, _) = bass_line(&[55.0, 82.4], 0.5);
    let mut c = cfg();
    c.register_sigma_st = 12.0;
    c.register_min_hops = 20;
    let mut s = Shs::new(c).unwrap();
    let mut sink = 0usize;
    let n = tactus_testkit::allocations_during(|| {
        for ch in x.chunks(333) {
            s.process(ch, &mut |_, e| sink += (e.f0_hz > 0.0) as usize);
        }
        s.finish(&mut |_, e| sink += (e.f0_hz > 0.0) as usize);
        s.reset();
    });
    assert_eq!(n, 0, "allocations in process/finish/reset");
    assert!(sink > 0);
}

#[test]
fn voicing_nats_make_the_learned_tracker_voice_more_and_are_checked() {
    // A bass line with rests and a quiet tail: lowering "no bass" by some nats can only add
    // voiced hops (a bonus on every voiced state's path).
    let sr = SR as f32;
    let mut x = Vec::new();
    for (k, f) in [55.0f32, 0.0, 73.4, 61.7, 0.0, 49.0]
        .into_iter()
        .enumerate()
    {
        for i in 0..(0.4 * sr) as usize {
            let a = if f > 0.0 {
                0.3 * (-(i as f32) / (0.15 * sr)).exp()
            } else {
                0.0
            };
            let ph = std::f32::consts::TAU * f * i as f32 / sr;
            x.push(a * (ph.sin() + 0.5 * (2.0 * ph).sin()) + 1e-4 * (k as f32));
        }
    }
    let voiced = |nats: f32| {
        let mut c = cfg();
        c.learned_voicing_nats = nats;
        let mut t = Shs::new(c).unwrap();
        let mut n = 0usize;
        t.process(&x, &mut |_, e| n += usize::from(e.is_voiced()));
        t.finish(&mut |_, e| n += usize::from(e.is_voiced()));
        n
    };
    let (v0, v3, v10) = (voiced(0.0), voiced(3.0), voiced(10.0));
    assert!(
        v0 <= v3 && v3 <= v10 && v0 < v10,
        "voiced hops {v0} / {v3} / {v10}"
    );
    for bad in [-1.0, f32::NAN, 21.0] {
        let mut c = cfg();
        c.learned_voicing_nats = bad;
        assert!(Shs::new(c).is_err(), "{bad}");
    }
}

/// The harmonic-view lead models' files (`BassNet::embedded_lead_harmonic` and
/// `BassNet::embedded_lead_harmonic_others`).
const HARM_WEIGHTS: [&[u8]; 3] = [
    include_bytes!("../weights/leadnet_harm.bin"),
    include_bytes!("../weights/leadnet_harm_2.bin"),
    include_bytes!("../weights/leadnet_harm_3.bin"),
];

#[test]
fn embedded_harmonic_view_models_match_a_separate_f64_reader_and_the_lead_models_layout() {
    let others = BassNet::embedded_lead_harmonic_others();
    assert_eq!(others.len(), 2);
    let members: Vec<&BassNet> = std::iter::once(BassNet::embedded_lead_harmonic())
        .chain(others)
        .collect();
    for (k, (&net, weights)) in members.iter().zip(HARM_WEIGHTS).enumerate() {
        check_lead_member(net, weights, 21 + k as u64);
        for lead in [BassNet::embedded_lead_sung(), BassNet::embedded_lead_3()] {
            assert_ne!(net, lead, "member {k} is not a lead-band model");
        }
    }
    assert_ne!(members[0], members[1]);
    assert_ne!(members[1], members[2]);
}

#[test]
fn the_harmonic_view_needs_the_learned_salience_and_changes_the_lead_models() {
    let mut lead = ShsConfig::melody(14_700, 70.0, 1400.0);
    lead.learned_harmonic = true;
    assert!(
        Shs::new(lead.clone()).is_err(),
        "only with the learned salience"
    );
    lead.learned = true;
    lead.learned_ensemble = true;
    // A lead a sixth over a low chord tone, 2 s: the two model sets hear it differently.
    let x: Vec<f32> = (0..14_700 * 2)
        .map(|i| {
            let t = i as f32 / 14_700.0;
            let lead: f32 = (1..=6)
                .map(|h| 0.2 * (std::f32::consts::TAU * 392.0 * h as f32 * t).sin() / h as f32)
                .sum();
            lead + 0.3 * (std::f32::consts::TAU * 130.8 * t).sin()
        })
        .collect();
    let run = |c: &ShsConfig| {
        let mut t = Shs::new(c.clone()).unwrap();
        let mut out = Vec::new();
        t.process(&x, &mut |_, e| {
            out.push((e.f0_hz.to_bits(), e.voiced_prob.to_bits()))
        });
        t.finish(&mut |_, e| out.push((e.f0_hz.to_bits(), e.voiced_prob.to_bits())));
        out
    };
    let harm = run(&lead);
    lead.learned_harmonic = false;
    let band = run(&lead);
    assert_eq!(harm.len(), band.len());
    let differ = harm.iter().zip(&band).filter(|(a, b)| a != b).count();
    assert!(
        differ > 10,
        "the harmonic-view models are the ones read: {differ} hops differ"
    );
}

/// The harmonic-view bass model's file (`BassNet::embedded_bass_harmonic`).
const BASS_HARM_WEIGHTS: &[u8] = include_bytes!("../weights/bassnet_harm.bin");

#[test]
fn embedded_harmonic_view_bass_model_matches_a_separate_f64_reader_and_the_bass_layout() {
    assert_eq!(
        (BassNet::embedded().bands(), BassNet::embedded().low_hz()),
        (BANDS, LOW_HZ)
    );
    check_member_of(
        BassNet::embedded(),
        BassNet::embedded_bass_harmonic(),
        BASS_HARM_WEIGHTS,
        31,
    );
}

/// A bass line under a chord a tenth above it: the bass stem alone, and the harmonic sum
/// (the line plus the chord) as the view.
fn bass_and_view() -> (Vec<f32>, Vec<f32>) {
    let (x, _) = bass_line(&[55.0, 82.4, 65.4, 110.0, 49.0, 73.4], 0.5);
    let v = x
        .iter()
        .enumerate()
        .map(|(i, &s)| {
            let t = i as f32 / SR as f32;
            s + [164.8f32, 207.7, 246.9]
                .iter()
                .map(|f| 0.08 * (std::f32::consts::TAU * f * t).sin())
                .sum::<f32>()
        })
        .collect();
    (x, v)
}

type Out = Vec<(usize, u32, u32)>;

fn run_view(s: &mut WithDecoded, x: &[f32], v: &[f32], chunk: usize) -> Out {
    let mut out = Vec::new();
    for (a, b) in x.chunks(chunk).zip(v.chunks(chunk)) {
        s.process_with(a, Some(b), &mut |i, (e, d)| {
            out.push((i, e.f0_hz.to_bits(), d.f0_hz.to_bits()))
        });
    }
    s.finish(&mut |i, (e, d)| out.push((i, e.f0_hz.to_bits(), d.f0_hz.to_bits())));
    out
}

#[test]
fn the_bass_view_feeds_the_network_and_the_harmonic_sum_keeps_the_stem() {
    // The learned bass tracker as the engine runs it (blended with the harmonic sum):
    // `process_with(x, Some(x))` is `process(x)` bit for bit; another view changes the
    // output; any chunking gives the same; the harmonic-view model is the one read with
    // the flag; a warm tracker does not allocate.
    let (x, v) = bass_and_view();
    let mut c = cfg();
    c.learned_blend = 1.0;
    let plain: Out = {
        let mut s = Shs::new(c.clone()).unwrap().with_decoded();
        let mut out = Vec::new();
        for b in x.chunks(4096) {
            s.process(b, &mut |i, (e, d)| {
                out.push((i, e.f0_hz.to_bits(), d.f0_hz.to_bits()))
            });
        }
        s.finish(&mut |i, (e, d)| out.push((i, e.f0_hz.to_bits(), d.f0_hz.to_bits())));
        out
    };
    assert_eq!(
        run_view(
            &mut Shs::new(c.clone()).unwrap().with_decoded(),
            &x,
            &x,
            4096
        ),
        plain
    );
    let viewed = run_view(
        &mut Shs::new(c.clone()).unwrap().with_decoded(),
        &x,
        &v,
        4096,
    );
    assert_eq!(viewed.len(), plain.len());
    // The tracker alone, fed the same view, reports the same estimates (its tail too).
    let mut alone = Shs::new(c.clone()).unwrap();
    let mut reported = Vec::new();
    for (a, b) in x.chunks(4096).zip(v.chunks(4096)) {
        alone.process_with(a, Some(b), &mut |i, e| {
            reported.push((i, e.f0_hz.to_bits()))
        });
    }
    alone.finish(&mut |i, e| reported.push((i, e.f0_hz.to_bits())));
    let want: Vec<_> = viewed.iter().map(|&(i, e, _)| (i, e)).collect();
    assert_eq!(reported, want);
    let differ = viewed.iter().zip(&plain).filter(|(a, b)| a != b).count();
    assert!(
        differ > 5,
        "the view reaches the network: {differ} hops differ"
    );
    for chunk in [1usize, 49, 333, x.len()] {
        let mut s = Shs::new(c.clone()).unwrap().with_decoded();
        assert_eq!(run_view(&mut s, &x, &v, chunk), viewed, "chunk {chunk}");
        s.reset();
        assert_eq!(
            run_view(&mut s, &x, &v, chunk),
            viewed,
            "chunk {chunk}, after reset"
        );
    }
    let mut h = c.clone();
    h.learned_harmonic = true;
    let harm = run_view(
        &mut Shs::new(h.clone()).unwrap().with_decoded(),
        &x,
        &v,
        4096,
    );
    let moved = harm.iter().zip(&viewed).filter(|(a, b)| a != b).count();
    assert!(
        moved > 5,
        "the harmonic-view bass model is the one read: {moved} hops"
    );
    let mut s = Shs::new(h).unwrap();
    let cut = x.len() / 3;
    s.process_with(&x[..cut], Some(&v[..cut]), &mut |_, _| {});
    let allocs = tactus_testkit::allocations_during(|| {
        for (a, b) in x[cut..].chunks(512).zip(v[cut..].chunks(512)) {
            s.process_with(a, Some(b), &mut |_, _| {});
        }
    });
    assert_eq!(allocs, 0);
}

/// The live models' files (`BassNet::embedded_bass_live`, `BassNet::embedded_lead_live`).
const BASS_LIVE_WEIGHTS: &[u8] = include_bytes!("../weights/bassnet_live.bin");
const LEAD_LIVE_WEIGHTS: &[u8] = include_bytes!("../weights/leadnet_live.bin");

#[test]
fn live_models_match_a_separate_f64_reader_and_look_only_back() {
    // Each live model against its own f64 reader, on the layout (bands, grid) of the model
    // it stands in for; its context is past frames only, so it adds no latency of its own.
    for (live, like, weights, seed) in [
        (
            BassNet::embedded_bass_live(),
            BassNet::embedded(),
            BASS_LIVE_WEIGHTS,
            41,
        ),
        (
            BassNet::embedded_lead_live(),
            BassNet::embedded_lead(),
            LEAD_LIVE_WEIGHTS,
            43,
        ),
    ] {
        let or = oracle_of(weights, like.bands(), like.low_hz());
        assert_eq!(live.offsets(), &or.offsets[..]);
        assert_eq!(live.future(), 0, "{:?}", live.offsets());
        assert!(live.offsets().iter().all(|&o| o <= 0));
        assert_eq!(
            (
                live.bands(),
                live.low_hz(),
                live.cand_fmin_hz(),
                live.candidates()
            ),
            (
                like.bands(),
                like.low_hz(),
                like.cand_fmin_hz(),
                like.candidates()
            )
        );
        check_against_oracle(live, &or, seed, 3);
    }
}
