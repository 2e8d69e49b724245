//! Throughput of the spectral separator on 30 s of stereo 44.1 kHz, as × real time.
//!
//! `cargo bench -p tactus-separate --bench separate -- --warm-up-time 1 --measurement-time 3`
//! Criterion's "thrpt" column is in input samples per second (per channel); divide by
//! 44 100 for × real time. The benchmark also prints × real time directly.

use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use tactus_separate::none::NoneSeparator;
use tactus_separate::spectral::{SpectralConfig, SpectralSeparator};
use tactus_separate::{Separator, Stem, StemOutput, StemSet};

const SR: u32 = 44_100;
const SECONDS: usize = 30;
const BLOCK: usize = 512;

/// 30 s of a deterministic stereo test signal: harmonic tones, clicks and noise.
fn song() -> (Vec<f32>, Vec<f32>) {
    let n = SR as usize * SECONDS;
    let mut state = 1u64;
    let mut noise = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    };
    let mut left = Vec::with_capacity(n);
    let mut right = Vec::with_capacity(n);
    for i in 0..n {
        let t = i as f32 / SR as f32;
        let tone = (std::f32::consts::TAU * 220.0 * t).sin() * 0.3
            + (std::f32::consts::TAU * 55.0 * t).sin() * 0.3;
        let hit = (-(t % 0.5) / 0.05).exp() * noise() * 0.3;
        left.push(tone + hit + 0.1 * (std::f32::consts::TAU * 330.0 * t).sin());
        right.push(tone + hit);
    }
    (left, right)
}

fn run(sep: &mut dyn Separator, left: &[f32], right: &[f32], out: &mut StemOutput) {
    out.clear();
    sep.reset();
    for (l, r) in left.chunks(BLOCK).zip(right.chunks(BLOCK)) {
        sep.process(l, r, out);
    }
    sep.finish(out);
}

fn bench(c: &mut Criterion) {
    let (left, right) = song();
    let n = left.len();
    let mut group = c.benchmark_group("separate_30s_stereo_44k1");
    group.sample_size(10);
    group.throughput(Throughput::Elements(n as u64));
    let cases: [(&str, StemSet, bool); 4] = [
        ("spectral_all_stems", StemSet::all(), true),
        (
            "spectral_bass_only",
            StemSet::default().with(Stem::Bass),
            true,
        ),
        (
            "spectral_drums_only",
            StemSet::default().with(Stem::Drums),
            true,
        ),
        ("none_all_stems", StemSet::all(), false),
    ];
    for (name, stems, spectral) in cases {
        let mut sep: Box<dyn Separator> = if spectral {
            Box::new(SpectralSeparator::new(SR, stems, SpectralConfig::default()).unwrap())
        } else {
            Box::new(NoneSeparator::new(SR, stems).unwrap())
        };
        let mut out = StemOutput::with_capacity(stems, n);
        // One timed pass for the × real time figure, printed next to criterion's numbers.
        let t0 = Instant::now();
        run(sep.as_mut(), &left, &right, &mut out);
        let secs = t0.elapsed().as_secs_f64();
        println!(
            "{name}: {:.3} s for {SECONDS} s of audio = {:.0}x real time",
            secs,
            SECONDS as f64 / secs
        );
        group.bench_function(name, |b| {
            b.iter(|| run(sep.as_mut(), &left, &right, &mut out))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
