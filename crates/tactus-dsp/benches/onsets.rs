//! Spectral-flux onset detection speed.
//!
//! * `onsets/block/{128,256,512}`: streaming at the default settings (causal and look-ahead),
//!   one second of audio fed in blocks of that size; throughput in samples.
//! * `onsets/song_180s/*`: a whole 180 s, 44.1 kHz track through [`detect_onsets`] with
//!   frame 2048 / hop 512 (librosa's defaults; librosa `onset_detect` takes 0.25–0.37 s on
//!   this machine, target ≤ 0.12 s) and with the default settings (frame 1024 / hop 220).
//!
//! Run: `cargo bench -p tactus-dsp --bench onsets -- --warm-up-time 1 --measurement-time 3`
//!
//! Measured on the shared 2-core dev box (load average 4–7, so upper bounds):
//! 180 s track, frame 2048 / hop 512: 99–116 ms; defaults: ~92 ms (look-ahead),
//! ~95 ms (causal); 1 s in blocks of 128/256/512: 0.49–0.62 ms (≈ 2000x real time).
use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use tactus_dsp::flux::{detect_onsets, OnsetConfig, OnsetDetector, OnsetFrame};
use tactus_dsp::HopStage;

const SR: u32 = 44_100;

/// A drum-like test track: a steady harmonic tone plus a decaying noise burst with a
/// falling thump every 250 ms. Deterministic (xorshift noise).
fn track(seconds: f64) -> Vec<f32> {
    let n = (seconds * SR as f64) as usize;
    let beat = SR as usize / 4;
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let sr = SR as f32;
    (0..n)
        .map(|i| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let white = (state >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0;
            let t = i as f32 / sr;
            let tb = (i % beat) as f32 / sr;
            let tone = 0.1 * (2.0 * std::f32::consts::PI * 220.0 * t).sin();
            let hit = (-tb / 0.03).exp()
                * (0.3 * white + 0.5 * (2.0 * std::f32::consts::PI * 60.0 * tb).sin());
            tone + hit
        })
        .collect()
}

fn blocks(c: &mut Criterion) {
    let x = track(1.0);
    let mut g = c.benchmark_group("onsets/block");
    g.throughput(Throughput::Elements(x.len() as u64));
    for (mode, cfg) in [
        ("causal", OnsetConfig::causal(SR)),
        ("lookahead", OnsetConfig::lookahead(SR)),
    ] {
        for block in [128usize, 256, 512] {
            let mut det = OnsetDetector::new(cfg.clone()).unwrap();
            g.bench_with_input(BenchmarkId::new(mode, block), &block, |b, &block| {
                b.iter(|| {
                    det.reset();
                    let mut count = 0usize;
                    let mut sink = |_: usize, f: OnsetFrame| count += f.onset as usize;
                    for chunk in x.chunks(block) {
                        det.process(black_box(chunk), &mut sink);
                    }
                    det.finish(&mut sink);
                    count
                })
            });
        }
    }
    g.finish();
}

fn song(c: &mut Criterion) {
    let x = track(180.0);
    let mut g = c.benchmark_group("onsets/song_180s");
    g.sample_size(10);
    let librosa_like = OnsetConfig {
        frame: 2048,
        hop: 512,
        ..OnsetConfig::lookahead(SR)
    };
    let librosa_like = OnsetConfig {
        lookahead_hops: 1,
        mean_before_hops: 9,
        ..librosa_like
    };
    let configs = [
        ("frame2048_hop512", librosa_like),
        ("default_causal", OnsetConfig::causal(SR)),
        ("default_lookahead", OnsetConfig::lookahead(SR)),
    ];
    for (name, cfg) in configs {
        g.bench_function(name, |b| {
            b.iter(|| detect_onsets(black_box(&x), &cfg).len())
        });
    }
    g.finish();
}

criterion_group!(benches, blocks, song);
criterion_main!(benches);
