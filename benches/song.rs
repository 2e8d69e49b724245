//! The paper's Table 7 as a criterion benchmark: one 3.5-minute song end to end (decode,
//! resample, separation, every feature, all frames), per separator, against the paper's
//! 180.45 s of preprocessing. The song is the bundled demo looped to 210 s, written once to
//! a 16-bit stereo WAV in the target directory.
//!
//!     cargo bench --bench song -- --warm-up-time 1 --measurement-time 20

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, Criterion};
use tactus_engine::render::{render, RenderRequest};
use tactus_engine::{EngineConfig, Mode, PitchMethod, SeparatorChoice};

const PAPER_S: f64 = 180.45;
const SONG_S: usize = 210;

fn song() -> PathBuf {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let path = root.join("target").join("bench-song-210s.wav");
    if !path.exists() {
        let d = tactus_engine::source::decode_all(&root.join("examples/demo.ogg"))
            .expect("demo decodes");
        let rate = d.info.sample_rate;
        let spec = hound::WavSpec {
            channels: 2,
            sample_rate: rate,
            bits_per_sample: 16,
            sample_format: hound::SampleFormat::Int,
        };
        let mut w = hound::WavWriter::create(&path, spec).expect("write bench song");
        let n = d.left.len();
        for i in 0..SONG_S * rate as usize {
            for x in [d.left[i % n], d.right[i % n]] {
                w.write_sample((x.clamp(-1.0, 1.0) * 32767.0) as i16)
                    .expect("write sample");
            }
        }
        w.finalize().expect("finalize");
    }
    path
}

fn bench(c: &mut Criterion) {
    let input = song();
    let mut g = c.benchmark_group("song_210s");
    g.sample_size(10);
    let cases = [
        (
            "spectral_pyin_offline",
            SeparatorChoice::Spectral,
            PitchMethod::Pyin,
            Mode::Offline,
        ),
        (
            "spectral_yin_offline",
            SeparatorChoice::Spectral,
            PitchMethod::Yin,
            Mode::Offline,
        ),
        (
            "spectral_pyin_streaming",
            SeparatorChoice::Spectral,
            PitchMethod::Pyin,
            Mode::Streaming,
        ),
        (
            "none_yin_offline",
            SeparatorChoice::None,
            PitchMethod::Yin,
            Mode::Offline,
        ),
    ];
    for (name, sep, pitch, mode) in cases {
        let req = RenderRequest {
            input: input.clone(),
            stems: Vec::new(),
            config: EngineConfig {
                separator: sep,
                pitch,
                mode,
                ..EngineConfig::default()
            },
        };
        let t = std::time::Instant::now();
        render(&req, &mut |_| {}).expect("render");
        let once = t.elapsed().as_secs_f64();
        eprintln!(
            "{name}: {once:.2} s for {SONG_S} s ({:.0}x real time, {:.0}x faster than the paper's {PAPER_S} s)",
            SONG_S as f64 / once,
            PAPER_S / once
        );
        g.bench_function(name, |b| {
            b.iter(|| render(&req, &mut |_| {}).expect("render"))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
