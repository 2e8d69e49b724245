//! Criterion benches for the drum transcriber.
//!
//! * `drums_210s/default` and `drums_210s/live`: a 210 s drum groove at 44.1 kHz through
//!   the whole transcriber (mel front end, network per 10 ms hop, peak picking) with the
//!   embedded default and live models: the transcriber's cost per 3.5-minute song.
//! * `drums_forward/default`: one network pass (one hop), without the front end.
use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use tactus_dsp::drums::{BatchScratch, DrumModel, DrumTranscriber, CLASSES};
use tactus_dsp::HopStage;

const SR: u32 = 44_100;

fn groove(seconds: f64) -> Vec<f32> {
    // A decaying low sine every 0.5 s (kick), noise bursts between (snare), ticks of
    // high-passed noise every 0.125 s (hats); an LCG for the noise.
    let n = (seconds * SR as f64) as usize;
    let mut seed = 11u32;
    let mut noise = move || {
        seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (seed >> 8) as f32 / (1u32 << 24) as f32 - 0.5
    };
    let (beat, tick) = (SR as usize / 2, SR as usize / 8);
    let mut prev = 0.0f32;
    (0..n)
        .map(|i| {
            let (tb, tt) = (i % beat, i % tick);
            let t = tb as f32 / SR as f32;
            let kick = if (i / beat) % 2 == 0 {
                (std::f32::consts::TAU * 60.0 * t).sin() * (-t * 20.0).exp()
            } else {
                0.0
            };
            let w = noise();
            let snare = if (i / beat) % 2 == 1 {
                w * (-t * 30.0).exp()
            } else {
                0.0
            };
            let hp = w - prev;
            prev = w;
            let hat = 0.3 * hp * (-(tt as f32 / SR as f32) * 80.0).exp();
            0.5 * kick + 0.4 * snare + hat
        })
        .collect()
}

fn song(c: &mut Criterion) {
    let x = groove(210.0);
    let mut g = c.benchmark_group("drums_210s");
    g.sample_size(10);
    for (name, model) in [
        ("default", DrumModel::embedded()),
        ("live", DrumModel::embedded_live()),
    ] {
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut t = DrumTranscriber::with_model(SR, model.clone()).unwrap();
                let mut onsets = 0usize;
                for ch in x.chunks(4096) {
                    t.process(black_box(ch), &mut |_, f| {
                        onsets += f.onset.iter().filter(|&&o| o).count()
                    });
                }
                t.finish(&mut |_, f| onsets += f.onset.iter().filter(|&&o| o).count());
                onsets
            })
        });
    }
    g.finish();
}

fn forward(c: &mut Criterion) {
    let m = DrumModel::embedded();
    let w = m.scratch_len();
    let window: Vec<f32> = (0..m.window_len())
        .map(|i| -20.0 + ((i * 7919) % 1000) as f32 / 50.0)
        .collect();
    let mut input = vec![0.0f32; m.input_len()];
    m.assemble(&window, &mut input);
    let (mut a, mut b, mut s) = (vec![0.0f32; w], vec![0.0f32; w], vec![0.0f32; w]);
    let mut g = c.benchmark_group("drums_forward");
    g.throughput(Throughput::Elements(1));
    g.bench_function("default", |bch| {
        bch.iter(|| m.forward(black_box(&input), &mut a, &mut b, &mut s))
    });
    // As the transcriber runs it: 16 hops at once (throughput in hops).
    const BATCH: usize = 16;
    let inputs: Vec<f32> = input
        .iter()
        .copied()
        .cycle()
        .take(BATCH * input.len())
        .collect();
    let mut scratch = BatchScratch::new(&m, BATCH);
    let mut acts = vec![[0.0f32; CLASSES]; BATCH];
    g.throughput(Throughput::Elements(BATCH as u64));
    g.bench_function("default_batch16", |bch| {
        bch.iter(|| m.forward_batch(black_box(&inputs), BATCH, &mut scratch, &mut acts))
    });
    g.finish();
}

criterion_group!(benches, song, forward);
criterion_main!(benches);
