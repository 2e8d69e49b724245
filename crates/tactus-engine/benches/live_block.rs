//! Processing time of one 256-sample block (5.8 ms of audio at 44.1 kHz) through the
//! streaming engine, as `tactus live` feeds it (the live loop's budget: p99 ≤ 1 ms per block;
//! `docs/decisions/0006-live-latency-profile.md`).
//!
//! * criterion: mean time per 256-sample block, live profile (what `tactus live` runs:
//!   drums by the bands on the mix, the 512-point separator, YIN) and full profile (the
//!   same map with the full stages), on a synthetic song (kick/noise hits, a bass line, a
//!   melody);
//! * before criterion runs, one pass over 60 s of that song in 256-sample blocks prints
//!   the distribution of per-block times (p50, p99, p99.9, max), which criterion's mean
//!   does not show, as the thread's CPU time (the engine's own cost) and as wall time
//!   (which also holds whatever the other processes of a loaded machine took).
//!
//! Run: `cargo bench -p tactus-engine --bench live_block -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use tactus_engine::{DrumMethod, Engine, EngineConfig, Mode, PitchMethod, Profile};

const SR: usize = 44_100;
const BLOCK: usize = 256;

/// A synthetic song: a hit every 0.4 s, a stepping bass line, a melody.
fn song(n: usize) -> Vec<f32> {
    let bass = [55.0f32, 73.4, 82.4, 65.4];
    let mel = [440.0f32, 494.0, 523.3, 587.3, 659.3];
    let (mut pb, mut pm) = (0.0f32, 0.0f32);
    let mut seed = 7u32;
    (0..n)
        .map(|i| {
            let t = i as f32 / SR as f32;
            pb += std::f32::consts::TAU * bass[(t / 0.75) as usize % 4] / SR as f32;
            pm += std::f32::consts::TAU * mel[(t / 0.3) as usize % 5] / SR as f32;
            let tk = t % 0.4;
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            let noise = (seed as f32 / u32::MAX as f32 - 0.5) * (-tk * 60.0).exp();
            0.4 * (-tk * 25.0).exp() * (std::f32::consts::TAU * 60.0 * tk).sin()
                + 0.3 * noise
                + 0.25 * (pb.sin() + 0.5 * (2.0 * pb).sin())
                + 0.15 * (pm.sin() + 0.3 * (2.0 * pm).sin())
        })
        .collect()
}

/// The CLI's defaults for the profile: `live` transcribes the drums with the 1-hop model,
/// `render`/`play` with the 4-hop one.
fn engine(profile: Profile) -> Engine {
    Engine::new(EngineConfig {
        mode: Mode::Streaming,
        profile,
        bin_ms: 10,
        drums: match profile {
            Profile::Live => DrumMethod::ClassesLive,
            Profile::Full => DrumMethod::Classes,
        },
        pitch: PitchMethod::Auto,
        ..EngineConfig::default()
    })
    .unwrap()
}

/// The calling thread's CPU time.
fn thread_cpu() -> Duration {
    nix::time::clock_gettime(nix::time::ClockId::CLOCK_THREAD_CPUTIME_ID)
        .map(Duration::from)
        .unwrap_or_default()
}

fn percentiles(profile: Profile, x: &[f32]) {
    let mut e = engine(profile);
    let n = x.len() / BLOCK;
    let (mut wall, mut cpu) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for b in x.chunks_exact(BLOCK) {
        let (s, c) = (Instant::now(), thread_cpu());
        e.process(b, b, &[]);
        black_box(e.live_ready_bins());
        cpu.push(thread_cpu().saturating_sub(c));
        wall.push(s.elapsed());
    }
    for (what, t) in [("thread CPU", &mut cpu), ("wall", &mut wall)] {
        t.sort();
        let q = |p: f64| t[((t.len() as f64 * p).ceil() as usize).clamp(1, t.len()) - 1];
        eprintln!(
            "{} profile, {} blocks of {BLOCK} samples (60 s), {what}: p50 {:?}, p99 {:?}, p99.9 {:?}, max {:?} (a block is {:.2} ms of audio)",
            profile.name(),
            t.len(),
            q(0.5),
            q(0.99),
            q(0.999),
            q(1.0),
            BLOCK as f64 * 1e3 / SR as f64
        );
    }
}

fn bench(c: &mut Criterion) {
    let x = song(SR * 60);
    for p in [Profile::Live, Profile::Full] {
        percentiles(p, &x);
    }
    let mut g = c.benchmark_group("engine_block_256");
    g.throughput(Throughput::Elements(BLOCK as u64));
    for p in [Profile::Live, Profile::Full] {
        g.bench_function(p.name(), |b| {
            let mut e = engine(p);
            let mut pos = 0;
            b.iter(|| {
                if pos + BLOCK > x.len() {
                    pos = 0;
                }
                let blk = &x[pos..pos + BLOCK];
                e.process(blk, blk, &[]);
                pos += BLOCK;
                black_box(e.live_ready_bins())
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
