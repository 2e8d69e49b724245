//! Seconds per network segment of the ONNX backends (feature `onnx`).
//!
//! `cargo bench -p tactus-separate --features onnx --bench onnx -- --warm-up-time 1 --measurement-time 5`
//!
//! * `spleeter/*`: a 10 s stereo stream (one 512-frame segment: STFT, both U-Nets,
//!   masks, iSTFT, and for `all` the spectral split of the accompaniment).
//! * `adtlib/*`: a 10 s mono stream through the ADTLib drum transcriber (front end,
//!   three networks, peak picking), streaming and offline windows, one ORT thread.
//! * `htdemucs/*`: one 7.8 s segment (`separate_segment`: Demucs STFT, network, iSTFT)
//!   with models/htdemucs.onnx or models/htdemucs-random.onnx (same size and speed),
//!   and with the tiny golden-fixture model (the non-network overhead).
//!
//! Needs ONNX Runtime (`ORT_DYLIB_PATH` or vendor/) and the models; what is missing is
//! skipped with a printed reason.

use std::path::{Path, PathBuf};

use criterion::{criterion_group, criterion_main, Criterion};
use tactus_separate::onnx::adtlib::{AdtLib, AdtLibConfig};
use tactus_separate::onnx::htdemucs::{HtDemucsSeparator, SEGMENT_SAMPLES};
use tactus_separate::onnx::spleeter::SpleeterSeparator;
use tactus_separate::onnx::OnnxConfig;
use tactus_separate::{Separator, Stem, StemOutput, StemSet};

const SR: u32 = 44_100;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn library() -> Option<PathBuf> {
    let vendored = root().join("vendor/onnxruntime/capi/libonnxruntime.so.1.31.1");
    std::env::var_os("ORT_DYLIB_PATH")
        .map(PathBuf::from)
        .filter(|p| p.is_file())
        .or_else(|| vendored.is_file().then_some(vendored))
}

fn signal(n: usize) -> (Vec<f32>, Vec<f32>) {
    let mut state = 7u32;
    let mut noise = move || {
        state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (state >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0
    };
    (0..n)
        .map(|i| {
            let t = i as f32 / SR as f32;
            let tone = 0.3 * (std::f32::consts::TAU * 220.0 * t).sin();
            let hit = (-(t % 0.5) / 0.05).exp() * noise() * 0.3;
            (tone + hit, 0.8 * tone + hit)
        })
        .unzip()
}

fn cfg(lib: &Path, model: PathBuf) -> OnnxConfig {
    OnnxConfig {
        library: Some(lib.to_path_buf()),
        model,
        threads: 0,
    }
}

fn bench(c: &mut Criterion) {
    let Some(lib) = library() else {
        eprintln!("SKIPPED onnx benches: no ONNX Runtime (models/setup_onnxruntime.sh)");
        return;
    };
    let mut g = c.benchmark_group("onnx");
    g.sample_size(10);

    let spleeter = root().join("models/spleeter-2stems.onnx");
    if spleeter.is_file() {
        let (l, r) = signal(10 * SR as usize);
        for (name, stems) in [
            ("spleeter/vocals", StemSet::EMPTY.with(Stem::Vocals)),
            ("spleeter/all", StemSet::all()),
        ] {
            let mut sep = SpleeterSeparator::new(SR, stems, &cfg(&lib, spleeter.clone())).unwrap();
            let mut out = StemOutput::with_capacity(stems, l.len() + sep.latency_samples());
            g.bench_function(name, |b| {
                b.iter(|| {
                    sep.reset();
                    out.clear();
                    sep.process(&l, &r, &mut out);
                    sep.finish(&mut out);
                })
            });
        }
    } else {
        eprintln!(
            "SKIPPED spleeter bench: models/spleeter-2stems.onnx missing (models/setup_models.sh)"
        );
    }

    let adtlib = root().join("models/adtlib.onnx");
    if adtlib.is_file() {
        let (mono, _) = signal(10 * SR as usize);
        for (name, acfg) in [
            ("adtlib/streaming", AdtLibConfig::streaming()),
            ("adtlib/offline", AdtLibConfig::offline()),
        ] {
            let onnx = OnnxConfig {
                threads: 1,
                ..cfg(&lib, adtlib.clone())
            };
            let mut det = AdtLib::new(&onnx, SR, acfg).unwrap();
            let mut count = 0usize;
            g.bench_function(name, |b| {
                b.iter(|| {
                    det.reset();
                    for chunk in mono.chunks(512) {
                        det.process(chunk, &mut |_| count += 1);
                    }
                    det.finish(&mut |_| count += 1);
                })
            });
            std::hint::black_box(count);
        }
    } else {
        eprintln!("SKIPPED adtlib bench: models/adtlib.onnx missing (models/setup_adtlib.sh)");
    }

    let (l, r) = signal(SEGMENT_SAMPLES);
    let full = ["htdemucs.onnx", "htdemucs-random.onnx"]
        .map(|f| root().join("models").join(f))
        .into_iter()
        .find(|p| p.is_file());
    let tiny = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/onnx/htdemucs_golden/htdemucs-tiny.onnx");
    for (name, model) in [("htdemucs/full", full), ("htdemucs/tiny", Some(tiny))] {
        let Some(model) = model else {
            eprintln!("SKIPPED {name}: no models/htdemucs.onnx or htdemucs-random.onnx (models/export_htdemucs.py)");
            continue;
        };
        let mut sep = HtDemucsSeparator::new(SR, StemSet::all(), &cfg(&lib, model)).unwrap();
        let mut out = StemOutput::with_capacity(StemSet::all(), SEGMENT_SAMPLES);
        g.bench_function(name, |b| {
            b.iter(|| {
                out.clear();
                sep.separate_segment(&l, &r, &mut out);
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
