//! The paper's Table 7 as a criterion benchmark: one 3.5-minute song end to end (decode,
//! resample, separation, every feature, all frames), per configuration, against the paper's
//! 180.45 s of preprocessing; first, the default's time as a ratio to the paper's own
//! algorithms in Tactus (`--pitch yin --drums bands`), both timed in the same run. The song is the bundled demo looped to 210 s, written once to
//! a 16-bit stereo WAV in the target directory.
//!
//!     cargo bench --bench song -- --warm-up-time 1 --measurement-time 20

use std::path::{Path, PathBuf};
use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion};
use tactus_engine::render::{render, RenderRequest};
use tactus_engine::{DrumMethod, EngineConfig, Mode, PitchMethod, SeparatorChoice};

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

/// The CPU's model name and the widest vector extensions it has, for the report line.
fn cpu() -> String {
    let info = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let model = info
        .lines()
        .find_map(|l| {
            l.strip_prefix("model name")
                .map(|v| v.trim_start_matches([' ', '\t', ':']))
        })
        .unwrap_or("unknown CPU")
        .to_string();
    #[cfg(target_arch = "x86_64")]
    let flags = ["avx2", "fma", "avx512f"]
        .iter()
        .filter(|f| match **f {
            "avx2" => std::arch::is_x86_feature_detected!("avx2"),
            "fma" => std::arch::is_x86_feature_detected!("fma"),
            _ => std::arch::is_x86_feature_detected!("avx512f"),
        })
        .copied()
        .collect::<Vec<_>>()
        .join(" ");
    #[cfg(not(target_arch = "x86_64"))]
    let flags = String::new();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    format!("{model} ({cores} cores; {flags})")
}

fn request(
    input: &Path,
    sep: SeparatorChoice,
    pitch: PitchMethod,
    drums: DrumMethod,
    mode: Mode,
) -> RenderRequest {
    RenderRequest {
        input: input.to_path_buf(),
        stems: Vec::new(),
        config: EngineConfig {
            separator: sep,
            pitch,
            drums,
            mode,
            ..EngineConfig::default()
        },
    }
}

fn seconds(req: &RenderRequest) -> f64 {
    let t = Instant::now();
    render(req, &mut |_| {}).expect("render");
    t.elapsed().as_secs_f64()
}

/// The default render against the paper's own algorithms in Tactus (`--pitch yin --drums
/// bands`), timed in turn on the same song in the same run, five times each: machines here
/// differ by up to 2x from one session to the next, so only this ratio compares across
/// them. Printed with the CPU it ran on.
fn ratio(input: &Path) {
    let default = request(
        input,
        SeparatorChoice::Spectral,
        PitchMethod::Auto,
        DrumMethod::Classes,
        Mode::Offline,
    );
    let paper = request(
        input,
        SeparatorChoice::Spectral,
        PitchMethod::Yin,
        DrumMethod::Bands,
        Mode::Offline,
    );
    let (mut d, mut p) = (Vec::new(), Vec::new());
    for _ in 0..5 {
        d.push(seconds(&default));
        p.push(seconds(&paper));
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (md, mp) = (median(&mut d), median(&mut p));
    eprintln!(
        "song_210s ratio: default {md:.2} s / --pitch yin --drums bands {mp:.2} s = {:.2} (medians of 5, in turn) on {}",
        md / mp,
        cpu()
    );
}

fn bench(c: &mut Criterion) {
    let input = song();
    ratio(&input);
    let mut g = c.benchmark_group("song_210s");
    g.sample_size(10);
    let cases = [
        (
            "default",
            SeparatorChoice::Spectral,
            PitchMethod::Auto,
            DrumMethod::Classes,
            Mode::Offline,
        ),
        (
            "paper_yin_bands",
            SeparatorChoice::Spectral,
            PitchMethod::Yin,
            DrumMethod::Bands,
            Mode::Offline,
        ),
        (
            "pyin_bands",
            SeparatorChoice::Spectral,
            PitchMethod::Pyin,
            DrumMethod::Bands,
            Mode::Offline,
        ),
        (
            "default_streaming",
            SeparatorChoice::Spectral,
            PitchMethod::Auto,
            DrumMethod::Classes,
            Mode::Streaming,
        ),
        (
            "no_separator_yin_bands",
            SeparatorChoice::None,
            PitchMethod::Yin,
            DrumMethod::Bands,
            Mode::Offline,
        ),
    ];
    for (name, sep, pitch, drums, mode) in cases {
        let req = request(&input, sep, pitch, drums, mode);
        let once = seconds(&req);
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
