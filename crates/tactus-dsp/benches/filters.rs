//! Filter throughput: each stage (the four order-4 drum bands, the denoising high-pass, the
//! median) at block sizes 128, 256 and 512 on 1 s of 44.1 kHz audio, and the whole drum
//! chain (high-pass 30 Hz -> median 3 -> four bands) over a 180.45 s song, the length of the
//! paper's test track. Throughput is in samples per second; the song's real-time factor is
//! 180.45 s divided by the reported time.
//!
//! Run briefly: `cargo bench -p tactus-dsp --bench filters -- --warm-up-time 1 --measurement-time 2`

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use tactus_dsp::median::MedianFilter;
use tactus_dsp::sos::{Response, SosFilter};
use tactus_dsp::{Band, SampleStage};
use tactus_testkit::Rng;

const FS: u32 = 44100;
const SONG_S: f64 = 180.45;

/// Deterministic noise with a slow envelope, in [-1, 1].
fn signal(n: usize) -> Vec<f32> {
    let mut x = Rng::new(0x9E37_79B9_7F4A_7C15).noise(n);
    for (i, u) in x.iter_mut().enumerate() {
        *u *= 0.5 + 0.5 * (i as f32 * 2.0e-4).sin();
    }
    x
}

fn stages() -> Vec<(String, Box<dyn SampleStage>)> {
    let mut v: Vec<(String, Box<dyn SampleStage>)> = Band::ALL
        .iter()
        .map(|&b| {
            let f: Box<dyn SampleStage> = Box::new(SosFilter::band(b, FS).unwrap());
            (format!("band_{}", b.name()), f)
        })
        .collect();
    v.push((
        "highpass_30hz_o4".into(),
        Box::new(SosFilter::highpass(30.0, 4, FS).unwrap()),
    ));
    // The pitch tracks' anti-aliasing low-pass (order 8, four sections), as the lead's
    // decimator by 3 designs it.
    v.push((
        "lowpass_5880hz_o8".into(),
        Box::new(
            SosFilter::butterworth(
                8,
                Response::LowPass {
                    cutoff_hz: 0.4 * FS as f64 / 3.0,
                },
                FS,
            )
            .unwrap(),
        ),
    ));
    v.push(("median_3".into(), Box::new(MedianFilter::new(3).unwrap())));
    v.push(("median_31".into(), Box::new(MedianFilter::new(31).unwrap())));
    v
}

fn per_stage(c: &mut Criterion) {
    let x = signal(FS as usize);
    let mut out = vec![0.0f32; x.len()];
    let mut group = c.benchmark_group("filters/stage");
    group.throughput(Throughput::Elements(x.len() as u64));
    for (name, mut stage) in stages() {
        for block in [128usize, 256, 512] {
            group.bench_with_input(BenchmarkId::new(&name, block), &block, |b, &block| {
                b.iter(|| {
                    for (i, o) in x.chunks(block).zip(out.chunks_mut(block)) {
                        stage.process(i, o);
                    }
                    black_box(&out);
                })
            });
        }
    }
    group.finish();
}

fn drum_chain_song(c: &mut Criterion) {
    let n = (SONG_S * f64::from(FS)) as usize;
    let x = signal(n);
    let block = 512;
    let mut hp = SosFilter::highpass(30.0, 4, FS).unwrap();
    let mut median = MedianFilter::new(3).unwrap();
    let mut bands: Vec<SosFilter> = Band::ALL
        .iter()
        .map(|&b| SosFilter::band(b, FS).unwrap())
        .collect();
    let mut clean = vec![0.0f32; block];
    let mut band_out = vec![vec![0.0f32; block]; bands.len()];
    let mut group = c.benchmark_group("filters/song_180s");
    group.sample_size(10);
    group.throughput(Throughput::Elements(n as u64));
    group.bench_function("hp30_median3_4bands_block512", |b| {
        b.iter(|| {
            for chunk in x.chunks(block) {
                let clean = &mut clean[..chunk.len()];
                hp.process(chunk, clean);
                median.process_inplace(clean);
                for (f, o) in bands.iter_mut().zip(band_out.iter_mut()) {
                    f.process(clean, o);
                }
            }
            black_box(&band_out);
        })
    });
    group.finish();
}

criterion_group!(benches, per_stage, drum_chain_song);
criterion_main!(benches);
