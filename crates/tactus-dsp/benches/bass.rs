//! Criterion benches for the bass trackers of a mix.
//!
//! * `bass_210s/shs` and `bass_210s/learned`: a 210 s bass line at the bass chain's 4.9 kHz
//!   through the harmonic-sum tracker with the mixture settings (fundamental presence 0.1,
//!   register prior σ 12 semitones) and through the learned salience times the harmonic
//!   sum^0.3 (the render's default for the spectral separator's bass): what the learned
//!   salience adds to a 3.5-minute song's bass chain.
//! * `networks/NAME/HOPS`: every embedded pitch network (the lead's mix default: the
//!   harmonic view's three-member ensemble) on one hop and on a batch of 8, in hops per
//!   second.
//! * `lead_210s/shs` and `lead_210s/pair`: a 210 s melody at the lead chain's 14.7 kHz
//!   through the harmonic-sum melody tracker alone and through the voicing/pitch pair with
//!   the lead network's tracker and its veto (the render's default for the spectral
//!   separator's lead): what the learned lead adds to a song's lead chain.
use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use tactus_dsp::bassnet::BassNet;
use tactus_dsp::pair::VoicingPitchPair;
use tactus_dsp::shs::{Shs, ShsConfig};
use tactus_dsp::HopStage;

const SR: u32 = 4900;

fn bass_line(seconds: f64) -> Vec<f32> {
    // Notes changing every 0.5 s over two octaves, five harmonics, a little noise (LCG).
    let n = (seconds * SR as f64) as usize;
    let mut seed = 7u32;
    let mut phase = 0.0f64;
    (0..n)
        .map(|i| {
            let note = (i / (SR as usize / 2) * 5) % 24;
            let f0 = 41.2 * 2f64.powf(note as f64 / 12.0);
            phase += std::f64::consts::TAU * f0 / SR as f64;
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let noise = (seed >> 8) as f64 / (1u32 << 24) as f64 - 0.5;
            let v: f64 = (1..=5).map(|h| (h as f64 * phase).sin() / h as f64).sum();
            (0.4 * v + 0.01 * noise) as f32
        })
        .collect()
}

fn config(learned: bool) -> ShsConfig {
    let mut c = ShsConfig::new(SR, 35.0, 400.0);
    c.fundamental_ratio = 0.1;
    c.register_sigma_st = 12.0;
    if learned {
        c.learned = true;
        c.learned_blend = 0.3;
    }
    c
}

fn song(c: &mut Criterion) {
    let x = bass_line(210.0);
    let mut g = c.benchmark_group("bass_210s");
    g.sample_size(10);
    for (name, learned) in [("shs", false), ("learned", true)] {
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut s = Shs::new(config(learned)).unwrap();
                let mut acc = 0.0f32;
                for ch in x.chunks(4096) {
                    s.process(black_box(ch), &mut |_, e| acc += e.f0_hz);
                }
                s.finish(&mut |_, e| acc += e.f0_hz);
                acc
            })
        });
    }
    g.finish();
}

fn forward(c: &mut Criterion) {
    // Every embedded pitch network as the trackers run it: one hop (a live block) and a
    // batch of 8 (`shs::net`'s batch in a render), throughput in hops per second. The lead's
    // mix default is the harmonic view's three-member ensemble.
    let mut g = c.benchmark_group("networks");
    let ensembles: [(&str, &'static BassNet, Vec<&'static BassNet>); 7] = [
        ("bass", BassNet::embedded(), Vec::new()),
        ("lead", BassNet::embedded_lead(), Vec::new()),
        (
            "bass_harmonic",
            BassNet::embedded_bass_harmonic(),
            Vec::new(),
        ),
        ("bass_live", BassNet::embedded_bass_live(), Vec::new()),
        ("lead_live", BassNet::embedded_lead_live(), Vec::new()),
        (
            "lead_pair",
            BassNet::embedded_lead(),
            vec![BassNet::embedded_lead_sung()],
        ),
        (
            "lead_harmonic_x3",
            BassNet::embedded_lead_harmonic(),
            BassNet::embedded_lead_harmonic_others(),
        ),
    ];
    for (name, net, others) in &ensembles {
        let (len, w, out) = (
            net.input_len(),
            net.width().max(net.input_len()),
            net.candidates() + 1,
        );
        for hops in [1usize, 8] {
            let xs: Vec<f32> = (0..hops * len)
                .map(|i| ((i * 7919) % 1000) as f32 / 1000.0)
                .collect();
            let (mut a, mut b) = (vec![0.0f32; hops * w], vec![0.0f32; hops * w]);
            let mut o = vec![0.0f32; hops * out];
            let mut o2 = vec![0.0f32; others.len().max(1) * hops * out];
            g.throughput(Throughput::Elements(hops as u64));
            g.bench_function(format!("{name}/{hops}"), |bch| {
                bch.iter(|| {
                    if others.is_empty() {
                        net.forward_batch(black_box(&xs), hops, &mut a, &mut b, &mut o);
                    } else {
                        net.forward_ensemble_batch(
                            others,
                            black_box(&xs),
                            hops,
                            &mut a,
                            &mut b,
                            &mut o,
                            &mut o2,
                        );
                    }
                    o[0]
                })
            });
        }
    }
    g.finish();
}

/// The lead chain's rate and range (44.1 kHz decimated by 3; `Stem::Vocals`).
const LEAD_SR: u32 = 14_700;

fn melody(seconds: f64) -> Vec<f32> {
    // Notes changing every 0.4 s over an octave and a half from A3, eight harmonics, rests.
    let n = (seconds * LEAD_SR as f64) as usize;
    let mut phase = 0.0f64;
    (0..n)
        .map(|i| {
            let k = i / (LEAD_SR as usize * 2 / 5);
            if k % 7 == 6 {
                return 0.0;
            }
            let f0 = 220.0 * 2f64.powf(((k * 5) % 18) as f64 / 12.0);
            phase += std::f64::consts::TAU * f0 / LEAD_SR as f64;
            let v: f64 = (1..=8).map(|h| (h as f64 * phase).sin() / h as f64).sum();
            (0.3 * v) as f32
        })
        .collect()
}

fn lead_config() -> ShsConfig {
    let mut c = ShsConfig::melody(LEAD_SR, 70.0, 1400.0);
    c.fundamental_ratio = 0.1;
    c.contour_gate_db = 6.0;
    c
}

fn lead(c: &mut Criterion) {
    let x = melody(210.0);
    let mut g = c.benchmark_group("lead_210s");
    g.sample_size(10);
    for name in ["shs", "pair", "pair_ensemble"] {
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut t: Box<dyn HopStage<Out = tactus_dsp::yin::PitchEstimate>> =
                    if name == "shs" {
                        Box::new(Shs::new(lead_config()).unwrap())
                    } else {
                        let mut lc = lead_config();
                        lc.learned = true;
                        lc.contour_gate_db = 0.0;
                        lc.learned_voicing_nats = 3.0;
                        lc.learned_ensemble = name == "pair_ensemble";
                        Box::new(
                            VoicingPitchPair::new(
                                Box::new(Shs::new(lead_config()).unwrap()),
                                Box::new(Shs::new(lc).unwrap()),
                            )
                            .unwrap()
                            .with_veto(),
                        )
                    };
                let mut acc = 0.0f32;
                for ch in x.chunks(4096) {
                    t.process(black_box(ch), &mut |_, e| acc += e.f0_hz);
                }
                t.finish(&mut |_, e| acc += e.f0_hz);
                acc
            })
        });
    }
    // The spectral separator's lead as the engine runs it: the pitch
    // tracker (harmonic-view ensemble) reads a second view of the same span
    // (the pair's side input; here the melody under a quiet low pad).
    let view: Vec<f32> = x
        .iter()
        .enumerate()
        .map(|(i, &s)| s + 0.1 * (std::f32::consts::TAU * 98.0 * i as f32 / LEAD_SR as f32).sin())
        .collect();
    g.bench_function("pair_harmonic", |b| {
        b.iter(|| {
            let mut lc = lead_config();
            lc.learned = true;
            lc.contour_gate_db = 0.0;
            lc.learned_voicing_nats = 3.0;
            lc.learned_ensemble = true;
            lc.learned_harmonic = true;
            let mut t = VoicingPitchPair::new(
                Box::new(Shs::new(lead_config()).unwrap()),
                Box::new(Shs::new(lc).unwrap()),
            )
            .unwrap()
            .with_veto();
            let mut acc = 0.0f32;
            for (ch, v) in x.chunks(4096).zip(view.chunks(4096)) {
                t.process_with(black_box(ch), Some(black_box(v)), &mut |_, e| {
                    acc += e.f0_hz
                });
            }
            t.finish(&mut |_, e| acc += e.f0_hz);
            acc
        })
    });
    // A lead on its own stem as the engine runs it (twelve harmonics), without and with the
    // attack alignment of step 9 (both estimates per hop through `Shs::with_decoded`).
    for (name, attack_db) in [("clean", 0.0f32), ("clean_aligned", 0.5)] {
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut cfg = ShsConfig::melody(LEAD_SR, 70.0, 1400.0);
                cfg.harmonics = 12;
                cfg.attack_rise_db = attack_db;
                let mut t = Shs::new(cfg).unwrap().with_decoded();
                let mut acc = 0.0f32;
                for ch in x.chunks(4096) {
                    t.process(black_box(ch), &mut |_, (e, d)| acc += e.f0_hz + d.f0_hz);
                }
                t.finish(&mut |_, (e, d)| acc += e.f0_hz + d.f0_hz);
                acc
            })
        });
    }
    g.finish();
}

criterion_group!(benches, song, forward, lead);
criterion_main!(benches);
