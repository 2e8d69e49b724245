//! Criterion benches for the bass trackers of a mix (issue 16).
//!
//! * `bass_210s/shs` and `bass_210s/learned`: a 210 s bass line at the bass chain's 4.9 kHz
//!   through the harmonic-sum tracker with the mixture settings (fundamental presence 0.1,
//!   register prior σ 12 semitones) and through the learned salience times the harmonic
//!   sum^0.3 (the render's default for the spectral separator's bass): what the learned
//!   salience adds to a 3.5-minute song's bass chain.
//! * `bassnet_forward`: one network pass (one hop).
use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use tactus_dsp::bassnet::BassNet;
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
    let net = BassNet::embedded();
    let (len, w, out) = (net.input_len(), net.width(), net.candidates() + 1);
    let x: Vec<f32> = (0..len)
        .map(|i| ((i * 7919) % 1000) as f32 / 1000.0)
        .collect();
    let (mut a, mut b, mut o) = (vec![0.0f32; w], vec![0.0f32; w], vec![0.0f32; out]);
    c.bench_function("bassnet_forward", |bch| {
        bch.iter(|| {
            net.forward(black_box(&x), &mut a, &mut b, &mut o);
            o[0]
        })
    });
}

criterion_group!(benches, song, forward);
criterion_main!(benches);
