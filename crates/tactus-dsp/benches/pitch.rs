//! Criterion benches for YIN and pYIN.
//!
//! * `yin_block/{128,256,512}` and `pyin_block/…`: streaming cost per block of a 44.1 kHz
//!   vocal-range stage (70–1400 Hz, frame 2048, hop 441), in steady state.
//! * `song_180s/yin` and `song_180s/pyin`: a 180 s, 44.1 kHz signal with frame 2048 and
//!   hop 512 (50–2000 Hz, the "other" stem range), the configuration peers were measured
//!   with (NOTES.md: aubio yinfft 0.54 s, aubio yinfast 0.83 s, librosa.yin 2.2 s).
//! * `plain_guard_60s/{bass,lead}`: the plain-signal guard beside a learned tracker
//!   ([`tactus_dsp::plain`]) over 60 s of the bass (35–400 Hz at 4.9 kHz) and the lead
//!   (70–1400 Hz, ceiling 2 kHz, at 14.7 kHz), the decimated rates the engine runs them at,
//!   each hop resolved against a tracker reading; throughput in hops.
use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use tactus_dsp::plain::PlainGuard;
use tactus_dsp::pyin::{Pyin, PyinConfig};
use tactus_dsp::yin::{PitchEstimate, Yin, YinConfig};
use tactus_dsp::HopStage;

const SR: u32 = 44100;

fn melody(n: usize) -> Vec<f32> {
    // Notes changing every 0.25 s, three harmonics, a little noise (LCG).
    let mut seed = 1u32;
    let mut phase = 0.0f64;
    (0..n)
        .map(|i| {
            let note = (i / (SR as usize / 4)) % 12;
            let f0 = 110.0 * 2f64.powf(note as f64 / 12.0);
            phase += std::f64::consts::TAU * f0 / SR as f64;
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let noise = (seed >> 8) as f64 / (1u32 << 24) as f64 - 0.5;
            (0.5 * phase.sin()
                + 0.3 * (2.0 * phase).sin()
                + 0.2 * (3.0 * phase).sin()
                + 0.02 * noise) as f32
        })
        .collect()
}

/// One tracker fed blocks of 128, 256 and 512 samples of `x`, cycling through it.
fn bench_blocks<S: HopStage<Out = PitchEstimate>>(
    c: &mut Criterion,
    group: &str,
    x: &[f32],
    make: impl Fn() -> S,
) {
    let mut g = c.benchmark_group(group);
    for block in [128usize, 256, 512] {
        g.throughput(Throughput::Elements(block as u64));
        let mut tracker = make();
        let mut pos = 0;
        g.bench_with_input(BenchmarkId::from_parameter(block), &block, |b, &block| {
            b.iter(|| {
                if pos + block > x.len() {
                    pos = 0;
                }
                let mut acc = 0.0f32;
                tracker.process(
                    black_box(&x[pos..pos + block]),
                    &mut |_, e: PitchEstimate| acc += e.f0_hz,
                );
                pos += block;
                acc
            })
        });
    }
    g.finish();
}

fn blocks(c: &mut Criterion) {
    let x = melody(SR as usize * 4);
    bench_blocks(c, "yin_block", &x, || {
        Yin::new(YinConfig::new(SR, 70.0, 1400.0)).unwrap()
    });
    bench_blocks(c, "pyin_block", &x, || {
        Pyin::new(PyinConfig::new(SR, 70.0, 1400.0)).unwrap()
    });
}

fn song(c: &mut Criterion) {
    let x = melody(SR as usize * 180);
    let mut ycfg = YinConfig::new(SR, 50.0, 2000.0);
    ycfg.frame = 2048;
    ycfg.hop = 512;
    let mut g = c.benchmark_group("song_180s");
    g.sample_size(10);
    let mut pcfg = PyinConfig::new(SR, 50.0, 2000.0);
    pcfg.yin = ycfg.clone();
    let trackers: [(&str, Box<dyn HopStage<Out = PitchEstimate>>); 2] = [
        ("yin", Box::new(Yin::new(ycfg).unwrap())),
        ("pyin", Box::new(Pyin::new(pcfg).unwrap())),
    ];
    for (name, mut t) in trackers {
        g.bench_function(name, |b| {
            b.iter(|| {
                t.reset();
                let mut acc = 0.0f32;
                t.process(black_box(&x), &mut |_, e| acc += e.f0_hz);
                t.finish(&mut |_, e| acc += e.f0_hz);
                acc
            })
        });
    }
    g.finish();
}

/// `melody` at another rate.
fn melody_at(rate: u32, n: usize) -> Vec<f32> {
    (0..n)
        .map(|i| {
            let t = i as f64 / rate as f64;
            let f0 = 110.0 * 2f64.powf(((t * 4.0) as usize % 12) as f64 / 12.0);
            (0.5 * (std::f64::consts::TAU * f0 * t).sin()) as f32
        })
        .collect()
}

fn plain_guard(c: &mut Criterion) {
    let mut g = c.benchmark_group("plain_guard_60s");
    g.sample_size(10);
    for (name, rate, lo, hi, ceiling) in [
        ("bass", 4_900u32, 35.0f32, 400.0f32, 400.0f32),
        ("lead", 14_700, 70.0, 1400.0, 2000.0),
    ] {
        let yc = YinConfig::new(rate, lo, hi);
        let x = melody_at(rate, rate as usize * 60);
        let hops = x.len().div_ceil(yc.hop);
        g.throughput(Throughput::Elements(hops as u64));
        let mut guard = PlainGuard::new(&yc, ceiling, 16).unwrap();
        g.bench_function(name, |b| {
            b.iter(|| {
                guard.reset();
                let mut taken = 0usize;
                let (mut hop, mut pos) = (0usize, 0usize);
                while pos < x.len() {
                    let n = 4096.min(x.len() - pos);
                    guard.process(black_box(&x[pos..pos + n]));
                    pos += n;
                    // Resolve what YIN has judged so far, a tracker reading of 55 Hz.
                    while (hop + 1) * yc.hop + guard.latency_samples() <= pos {
                        taken += usize::from(guard.resolve(hop, 55.0).is_some());
                        hop += 1;
                    }
                }
                guard.finish();
                while hop < hops {
                    taken += usize::from(guard.resolve(hop, 55.0).is_some());
                    hop += 1;
                }
                taken
            })
        });
    }
    g.finish();
}

criterion_group!(benches, blocks, song, plain_guard);
criterion_main!(benches);
