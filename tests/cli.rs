//! End-to-end: the `tactus` binary on real files, including every bad input of issue 3.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn tactus(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tactus"))
        .args(args)
        .output()
        .expect("run tactus")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A short synthetic song: a kick-like thump every 0.5 s, a bass line, and a melody.
fn write_song(path: &Path, seconds: f32, rate: u32, stereo: bool) {
    let spec = hound::WavSpec {
        channels: if stereo { 2 } else { 1 },
        sample_rate: rate,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    let n = (seconds * rate as f32) as usize;
    let melody = [440.0f32, 494.0, 523.3, 587.3, 659.3, 587.3, 523.3, 494.0];
    let bass = [55.0f32, 73.4, 82.4, 65.4];
    let mut phase_m = 0.0f32;
    let mut phase_b = 0.0f32;
    for i in 0..n {
        let t = i as f32 / rate as f32;
        let fm = melody[((t / 0.5) as usize) % melody.len()];
        let fb = bass[((t / 1.0) as usize) % bass.len()];
        phase_m += 2.0 * std::f32::consts::PI * fm / rate as f32;
        phase_b += 2.0 * std::f32::consts::PI * fb / rate as f32;
        let tb = t % 0.5;
        let kick = (-tb * 30.0).exp() * (2.0 * std::f32::consts::PI * 60.0 * tb).sin();
        let m = 0.25 * (phase_m.sin() + 0.4 * (2.0 * phase_m).sin());
        let b = 0.3 * (phase_b.sin() + 0.5 * (2.0 * phase_b).sin() + 0.3 * (3.0 * phase_b).sin());
        let x = 0.5 * kick + m + b;
        let s = (x.clamp(-1.0, 1.0) * 30000.0) as i16;
        w.write_sample(s).unwrap();
        if stereo {
            w.write_sample(s).unwrap();
        }
    }
    w.finalize().unwrap();
}

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

fn p(dir: &Path, name: &str) -> PathBuf {
    dir.join(name)
}

#[test]
fn renders_pattern_features_and_plot() {
    let d = tmp();
    let song = p(d.path(), "song.wav");
    write_song(&song, 4.0, 44_100, true);
    let out = p(d.path(), "song.json");
    let feat = p(d.path(), "feat.json");
    let plot = p(d.path(), "song.svg");
    let o = tactus(&[
        "render",
        song.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--features",
        feat.to_str().unwrap(),
        "--plot",
        plot.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let pat: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(pat["format"], "tactus-pattern");
    assert_eq!(pat["version"], 1);
    assert_eq!(pat["bin_ms"], 100);
    let frames = pat["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 40, "4 s at 100 ms bins");
    assert!(frames.iter().all(|f| f.as_str().unwrap().len() == 20));
    // Something moves on the glove: the kick finger pulses and the bass thumb holds levels.
    let raised: usize = frames
        .iter()
        .map(|f| {
            let s = f.as_str().unwrap();
            (0..10).filter(|i| &s[2 * i..2 * i + 2] != "00").count()
        })
        .sum();
    assert!(raised > 40, "the glove barely moves: {raised} raised cells");
    let f: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&feat).unwrap()).unwrap();
    assert!((f["hop_s"].as_f64().unwrap() - 0.01).abs() < 1e-9);
    assert_eq!(f["levels"]["bass"].as_array().unwrap().len(), 40);
    let kicks = f["onsets_s"]["kick"].as_array().unwrap();
    assert!(kicks.len() >= 6, "8 thumps in 4 s, found {}", kicks.len());
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
}

#[test]
fn pattern_to_stdout() {
    let d = tmp();
    let song = p(d.path(), "song.wav");
    write_song(&song, 1.0, 22_050, false);
    let o = tactus(&["render", song.to_str().unwrap(), "-o", "-"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["frames"].as_array().unwrap().len(), 10);
}

fn assert_clean_failure(o: &Output, needle: &str, out: &Path) {
    assert!(!o.status.success(), "should fail");
    let e = stderr(o);
    assert_eq!(e.trim_end().lines().count(), 1, "one line on stderr: {e:?}");
    assert!(
        e.to_lowercase().contains(&needle.to_lowercase()),
        "{e:?} should mention {needle:?}"
    );
    assert!(!out.exists(), "no partial output");
    let dir = out.parent().unwrap();
    let leftovers: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

#[test]
fn missing_file() {
    let d = tmp();
    let out = p(d.path(), "o.json");
    let o = tactus(&[
        "render",
        p(d.path(), "nope.mp3").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_clean_failure(&o, "nope.mp3", &out);
}

#[test]
fn empty_file() {
    let d = tmp();
    let f = p(d.path(), "empty.wav");
    std::fs::write(&f, b"").unwrap();
    let out = p(d.path(), "o.json");
    let o = tactus(&["render", f.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_clean_failure(&o, "empty.wav", &out);
}

#[test]
fn random_bytes() {
    let d = tmp();
    let f = p(d.path(), "noise.mp3");
    let mut x: u32 = 12345;
    let bytes: Vec<u8> = (0..50_000)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x as u8
        })
        .collect();
    std::fs::write(&f, bytes).unwrap();
    let out = p(d.path(), "o.json");
    let o = tactus(&["render", f.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_clean_failure(&o, "noise.mp3", &out);
}

#[test]
fn unwritable_output_keeps_nothing() {
    let d = tmp();
    let song = p(d.path(), "song.wav");
    write_song(&song, 0.5, 44_100, false);
    let out = p(d.path(), "no/such/dir/o.json");
    let o = tactus(&[
        "render",
        song.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert_eq!(stderr(&o).trim_end().lines().count(), 1);
    assert!(stderr(&o).contains("does not exist"), "{}", stderr(&o));
}

#[test]
fn existing_output_survives_a_failed_render() {
    let d = tmp();
    let out = p(d.path(), "o.json");
    std::fs::write(&out, "precious").unwrap();
    let o = tactus(&[
        "render",
        p(d.path(), "missing.wav").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "precious");
}

#[test]
fn bad_stem_argument() {
    let d = tmp();
    let song = p(d.path(), "song.wav");
    write_song(&song, 0.5, 44_100, false);
    let o = tactus(&["render", song.to_str().unwrap(), "--stem", "piano=x.wav"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("unknown stem"), "{}", stderr(&o));
}

#[test]
fn supplied_stems_skip_separation_and_length_mismatch_warns() {
    let d = tmp();
    let song = p(d.path(), "song.wav");
    write_song(&song, 2.0, 44_100, true);
    let short = p(d.path(), "short.wav");
    write_song(&short, 1.5, 48_000, false);
    let out = p(d.path(), "o.json");
    let o = tactus(&[
        "render",
        song.to_str().unwrap(),
        "--stem",
        &format!("drums={}", short.display()),
        "--stem",
        &format!("bass={}", short.display()),
        "--stem",
        &format!("vocals={}", short.display()),
        "--stem",
        &format!("other={}", short.display()),
        "-o",
        out.to_str().unwrap(),
        "--verbose",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("padded"), "length mismatch should warn: {e}");
    assert!(
        e.contains("separator none needed"),
        "no separator should run: {e}"
    );
}
