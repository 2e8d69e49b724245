//! Small messages through the binary: built-in maps by name, errors on one line
//! without repetition, devices advice in user terms, eval's hint when the log is not the
//! pattern's.

use std::path::Path;
use std::process::{Command, Output};

fn tactus(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tactus"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("run tactus")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn write_song(path: &Path) {
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: 44_100,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    for i in 0..2 * 44_100 {
        let t = i as f32 / 44_100.0;
        let click = if i % 11_025 < 100 { 0.6 } else { 0.0 };
        let x = 0.3 * (t * 220.0 * std::f32::consts::TAU).sin() + click;
        w.write_sample((x * 20_000.0) as i16).unwrap();
    }
    w.finalize().unwrap();
}

/// One line on stderr, starting `tactus: error: `, in which no fragment of 12 or more
/// characters after a `: ` separator appears twice.
fn assert_one_clean_line(o: &Output) -> String {
    let err = stderr(o);
    assert!(!o.status.success(), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.starts_with("tactus: error: "), "{err}");
    let parts: Vec<&str> = err
        .trim_end()
        .split(": ")
        .filter(|p| p.len() >= 12)
        .collect();
    for (i, a) in parts.iter().enumerate() {
        assert!(!parts[i + 1..].contains(a), "repeated {a:?} in {err}");
    }
    assert!(!err.contains("configuration:"), "{err}");
    err
}

#[test]
fn built_in_maps_by_name() {
    let d = tempfile::tempdir().unwrap();
    write_song(&d.path().join("song.wav"));
    for name in ["drums-only", "melody", "default", "drums-only.toml"] {
        let o = tactus(
            d.path(),
            &["render", "song.wav", "--map", name, "-o", "p.json"],
        );
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        let want = tactus_glove::GloveMap::builtin(name).unwrap();
        let got = tactus_glove::Pattern::from_path(d.path().join("p.json")).unwrap();
        assert_eq!(got.map, want, "{name}");
    }
    // A file of that name wins over the built-in map.
    std::fs::write(
        d.path().join("melody"),
        "[thumb]\ncell0 = { onsets = \"kick\" }\n",
    )
    .unwrap();
    let o = tactus(
        d.path(),
        &["render", "song.wav", "--map", "melody", "-o", "p.json"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let p = std::fs::read_to_string(d.path().join("p.json")).unwrap();
    assert!(p.contains("kick"), "{p}");
    let o = tactus(
        d.path(),
        &["render", "song.wav", "--map", "nosuch", "-o", "p.json"],
    );
    let err = assert_one_clean_line(&o);
    assert!(err.contains("drums-only, melody"), "{err}");
}

#[test]
fn errors_are_one_line_without_repetition() {
    let d = tempfile::tempdir().unwrap();
    write_song(&d.path().join("song.wav"));
    std::fs::write(
        d.path().join("bad.toml"),
        "[index]\ncell0 = { onsets = \"kik\" }\n",
    )
    .unwrap();
    std::fs::write(d.path().join("bad.json"), "{not json").unwrap();
    let cases: [&[&str]; 6] = [
        &["render", "song.wav", "--map", "bad.toml"],
        &["render", "nosuch.wav"],
        &["render", "."],
        &["play", "bad.json", "--glove", "null", "--no-audio"],
        &["render", "song.wav", "--separator", "htdemucs"],
        &["play", "song.wav", "--glove", "bogus:x"],
    ];
    for args in cases {
        let o = tactus(d.path(), args);
        let err = assert_one_clean_line(&o);
        println!("{args:?} -> {err}");
    }
    let o = tactus(d.path(), &["render", "song.wav", "--map", "bad.toml"]);
    assert!(stderr(&o).contains("index.cell0") && stderr(&o).contains("\"kik\""));
}

#[test]
fn devices_advice_names_no_internal_crate() {
    let d = tempfile::tempdir().unwrap();
    let o = tactus(d.path(), &["devices", "--ble-scan-s", "0"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(!out.contains("tactus-"), "{out}");
    assert!(!out.contains("tactus_"), "{out}");
}

#[test]
fn eval_warns_when_the_log_is_not_the_pattern_played() {
    let d = tempfile::tempdir().unwrap();
    write_song(&d.path().join("song.wav"));
    let o = tactus(
        d.path(),
        &["render", "song.wav", "-o", "p.json", "--bin-ms", "50"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let p: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.path().join("p.json")).unwrap()).unwrap();
    let frames: Vec<&str> = p["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap())
        .collect();
    let log = |frames: &[&str], start_ms: u64| {
        let mut s = String::new();
        for (k, f) in frames.iter().enumerate() {
            s.push_str(&format!(
                "{{\"time_ms\":{},\"type\":\"pins\",\"frame\":\"{f}\"}}\n",
                start_ms + 50 * k as u64
            ));
        }
        s
    };
    // The whole pattern from the start: no warning.
    std::fs::write(d.path().join("good.jsonl"), log(&frames, 0)).unwrap();
    let o = tactus(
        d.path(),
        &["eval", "--glove-log", "good.jsonl", "--pattern", "p.json"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
    // A quarter of it, starting 1 s late: both warnings, and the scores still print.
    std::fs::write(
        d.path().join("short.jsonl"),
        log(&frames[..frames.len() / 4], 1000),
    )
    .unwrap();
    let o = tactus(
        d.path(),
        &["eval", "--glove-log", "short.jsonl", "--pattern", "p.json"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("the log covers") && err.contains("first frame is at 1000 ms"),
        "{err}"
    );
}

/// Every hint that sends the user to the documentation names a section that exists:
/// `see docs/install.md, "TITLE"` with a `## TITLE` in docs/install.md, never a README title.
#[test]
fn hints_name_sections_that_exist() {
    let d = tempfile::tempdir().unwrap();
    write_song(&d.path().join("song.wav"));
    let install =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/install.md"))
            .unwrap();
    let mut cases: Vec<Vec<&str>> = vec![
        vec!["render", "song.wav", "--separator", "htdemucs"],
        vec!["render", "song.wav", "--separator", "spleeter"],
        vec!["render", "song.wav", "--drums", "adtlib"],
    ];
    if !cfg!(feature = "onnx") {
        cases.push(vec![
            "render",
            "song.wav",
            "--separator",
            "htdemucs",
            "--model",
            "m.onnx",
        ]);
        cases.push(vec![
            "render",
            "song.wav",
            "--drums",
            "adtlib",
            "--drum-model",
            "m.onnx",
        ]);
    }
    if !cfg!(feature = "audio") {
        cases.push(vec!["live", "--glove", "null"]);
    }
    for args in cases {
        let o = tactus(d.path(), &args);
        let err = assert_one_clean_line(&o);
        assert!(!err.contains("README"), "{args:?}: {err}");
        let hints: Vec<&str> = err
            .split("see docs/install.md, \"")
            .skip(1)
            .map(|rest| rest.split('"').next().unwrap())
            .collect();
        assert!(!hints.is_empty(), "{args:?}: no hint in {err}");
        for title in hints {
            assert!(
                install.lines().any(|l| l == format!("## {title}")),
                "{args:?}: docs/install.md has no section {title:?}"
            );
        }
    }
}
