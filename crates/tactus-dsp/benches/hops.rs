//! Per-hop stages: RMS (frame 2048, hop 441 = 10 ms at 44.1 kHz) in 128/256/512-sample blocks
//! and over a whole 180 s song (the paper's 180.45 s test length), then the gate, Tukey fences,
//! discretizer and binners on 18 000 hops (180 s of 10 ms hops).
//!
//! Run: `cargo bench -p tactus-dsp --bench hops -- --warm-up-time 1 --measurement-time 2`

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use tactus_dsp::binner::{bin_beats, bin_levels, LevelBinner};
use tactus_dsp::discretize::{range_offline, Discretizer, RunningRange};
use tactus_dsp::rms::{gate_offline, Rms, StreamingGate, DEFAULT_DECAY_DB_PER_S, GATE_BELOW_DB};
use tactus_dsp::tukey::{
    reject_outliers_offline, SlidingTukey, DEFAULT_MIN_COUNT, DEFAULT_WINDOW_HOPS, TUKEY_K,
};
use tactus_dsp::HopStage;
use tactus_testkit::Rng;

const SR: usize = 44_100;
const FRAME: usize = 2048;
const HOP: usize = 441;
const BIN: usize = 4410;
const HOPS: usize = 18_000;

/// White noise in `[-1, 1)`, seeded.
fn noise(n: usize) -> Vec<f32> {
    Rng::new(0x2545_F491_4F6C_DD1D).noise(n)
}

/// A melody-like f0 track: 250 ms notes over an octave, 20% unvoiced, 3% octave errors.
fn melody() -> Vec<f32> {
    (0..HOPS)
        .map(|i| {
            let note = (i / 25) % 13;
            if i % 50 >= 40 {
                0.0
            } else {
                let f = 220.0 * 2f32.powf(note as f32 / 12.0);
                if i % 31 == 0 {
                    f * 2.0
                } else {
                    f
                }
            }
        })
        .collect()
}

fn bench_rms(c: &mut Criterion) {
    let one_s = noise(SR);
    let mut g = c.benchmark_group("rms_1s");
    g.throughput(Throughput::Elements(SR as u64));
    for block in [128usize, 256, 512] {
        g.bench_with_input(BenchmarkId::from_parameter(block), &block, |b, &block| {
            let mut rms = Rms::new(FRAME, HOP).unwrap();
            b.iter(|| {
                rms.reset();
                let mut acc = 0.0f32;
                for chunk in one_s.chunks(block) {
                    rms.process(black_box(chunk), &mut |_, d| acc += d);
                }
                rms.finish(&mut |_, d| acc += d);
                black_box(acc)
            })
        });
    }
    g.finish();

    let song = noise(SR * 180);
    let mut g = c.benchmark_group("rms_180s");
    g.sample_size(10);
    g.throughput(Throughput::Elements(song.len() as u64));
    g.bench_function("block512", |b| {
        let mut rms = Rms::new(FRAME, HOP).unwrap();
        b.iter(|| {
            rms.reset();
            let mut acc = 0.0f32;
            for chunk in song.chunks(512) {
                rms.process(black_box(chunk), &mut |_, d| acc += d);
            }
            rms.finish(&mut |_, d| acc += d);
            black_box(acc)
        })
    });
    g.finish();
}

fn bench_hops(c: &mut Criterion) {
    let f0 = melody();
    let db: Vec<f32> = (0..HOPS).map(|i| -((i % 500) as f32) * 0.1).collect();
    let levels: Vec<u8> = f0
        .iter()
        .map(|&f| if f > 0.0 { (f as u32 % 8 + 1) as u8 } else { 0 })
        .collect();
    let onsets: Vec<bool> = (0..HOPS).map(|i| i % 23 == 0).collect();

    let mut g = c.benchmark_group("hops_18000");
    g.throughput(Throughput::Elements(HOPS as u64));
    g.bench_function("gate_offline", |b| {
        let mut open = vec![false; HOPS];
        b.iter(|| black_box(gate_offline(black_box(&db), GATE_BELOW_DB, &mut open)))
    });
    g.bench_function("gate_streaming", |b| {
        let mut gate = StreamingGate::new(GATE_BELOW_DB, DEFAULT_DECAY_DB_PER_S, 0.01).unwrap();
        b.iter(|| {
            gate.reset();
            black_box(db.iter().filter(|&&d| gate.process(d)).count())
        })
    });
    g.bench_function("tukey_offline", |b| {
        b.iter(|| {
            let mut v = f0.clone();
            black_box(reject_outliers_offline(&mut v, TUKEY_K))
        })
    });
    g.bench_function("tukey_sliding_w1000", |b| {
        let mut t = SlidingTukey::new(DEFAULT_WINDOW_HOPS, TUKEY_K, DEFAULT_MIN_COUNT).unwrap();
        b.iter(|| {
            t.reset();
            black_box(f0.iter().map(|&f| t.process(f)).sum::<f32>())
        })
    });
    g.bench_function("discretize_offline", |b| {
        let d = Discretizer::default();
        b.iter(|| {
            let r = range_offline(black_box(&f0)).unwrap();
            black_box(f0.iter().map(|&f| u32::from(d.level(f, r))).sum::<u32>())
        })
    });
    g.bench_function("discretize_streaming", |b| {
        let d = Discretizer::default();
        b.iter(|| {
            let mut rr = RunningRange::new();
            black_box(
                f0.iter()
                    .map(|&f| u32::from(d.level(f, rr.update(f).unwrap_or((0.0, 0.0)))))
                    .sum::<u32>(),
            )
        })
    });
    g.bench_function("bin_levels", |b| {
        b.iter(|| black_box(bin_levels(black_box(&levels), HOP, BIN)))
    });
    g.bench_function("level_binner_streaming", |b| {
        let mut lb = LevelBinner::new(HOP, BIN).unwrap();
        b.iter(|| {
            lb.reset();
            let mut acc = 0u32;
            for (i, &l) in levels.iter().enumerate() {
                lb.push(i, l, &mut |_, v| acc += u32::from(v));
            }
            lb.finish(&mut |_, v| acc += u32::from(v));
            black_box(acc)
        })
    });
    g.bench_function("bin_beats", |b| {
        b.iter(|| black_box(bin_beats(black_box(&onsets), HOP, BIN)))
    });
    g.finish();
}

criterion_group!(benches, bench_rms, bench_hops);
criterion_main!(benches);
