//! `tactus render INPUT... --out-dir DIR` through the binary: the layout, the
//! manifest, a broken file that does not stop the library, the same bytes as single renders
//! whatever the number of jobs, and resume (what a rerun skips and what it renders again).

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::SystemTime;

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

/// A bass tone, a melody and clicks, `seconds` long, 16-bit stereo WAV; `seed` changes the
/// notes so that songs differ.
fn write_song(path: &Path, seconds: f32, seed: u32) {
    let spec = hound::WavSpec {
        channels: 2,
        sample_rate: 44_100,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    let n = (seconds * 44_100.0) as usize;
    let tau = 2.0 * std::f32::consts::PI;
    for i in 0..n {
        let t = i as f32 / 44_100.0;
        let note = (t * 2.0) as u32 + seed;
        let f = 220.0 * 2f32.powf((note % 7) as f32 / 12.0);
        let click = if i % 22_050 < 150 { 0.4 } else { 0.0 };
        let x = 0.2 * (tau * 55.0 * (1 + seed % 3) as f32 * t).sin()
            + 0.2 * (tau * f * t).sin()
            + click;
        let s = (x * 20_000.0) as i16;
        w.write_sample(s).unwrap();
        w.write_sample(s).unwrap();
    }
    w.finalize().unwrap();
}

struct Library {
    _tmp: tempfile::TempDir,
    root: PathBuf,
    lib: PathBuf,
}

/// lib/one.wav, lib/sub/two (a WAV without an extension: found by its content),
/// lib/sub/deeper/three.wav, lib/notes.txt (not audio: ignored), lib/sub/broken.mp3
/// (random bytes with an audio extension: reported).
fn library() -> Library {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().to_path_buf();
    let lib = root.join("lib");
    fs::create_dir_all(lib.join("sub/deeper")).unwrap();
    write_song(&lib.join("one.wav"), 3.0, 0);
    write_song(&lib.join("sub/two"), 2.5, 1);
    write_song(&lib.join("sub/deeper/three.wav"), 2.0, 2);
    fs::write(lib.join("notes.txt"), "liner notes\n").unwrap();
    let junk: Vec<u8> = (0..4000u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    fs::write(lib.join("sub/broken.mp3"), junk).unwrap();
    Library {
        _tmp: tmp,
        root,
        lib,
    }
}

fn manifest(dir: &Path) -> Vec<serde_json::Value> {
    fs::read_to_string(dir.join("manifest.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

fn record<'a>(m: &'a [serde_json::Value], tail: &str) -> &'a serde_json::Value {
    m.iter()
        .find(|r| r["path"].as_str().unwrap().ends_with(tail))
        .unwrap_or_else(|| panic!("no record for {tail} in {m:?}"))
}

fn mtime(p: &Path) -> SystemTime {
    fs::metadata(p).unwrap().modified().unwrap()
}

const OUTPUTS: [&str; 3] = ["one", "sub/two", "sub/deeper/three"];

#[test]
fn a_library_renders_with_a_broken_file_reported() {
    let l = library();
    let o = tactus(
        &l.root,
        &[
            "render",
            "lib",
            "--out-dir",
            "out",
            "--with-features",
            "--jobs",
            "2",
        ],
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "one input failed: {err}");
    assert!(err.contains("broken.mp3"), "{err}");
    assert!(err.contains("1 failed"), "{err}");
    let out = l.root.join("out");
    for base in OUTPUTS {
        for suffix in [".pattern.json", ".features.json"] {
            assert!(
                out.join(format!("{base}{suffix}")).is_file(),
                "{base}{suffix}"
            );
        }
    }
    assert!(!out.join("notes.pattern.json").exists());
    assert!(!out.join("sub/broken.pattern.json").exists());
    let m = manifest(&out);
    assert_eq!(m.len(), 4, "{m:?}");
    for base in ["one.wav", "sub/two", "sub/deeper/three.wav"] {
        let r = record(&m, base);
        assert_eq!(r["status"], "ok", "{r}");
        let src = l.lib.join(base);
        assert_eq!(
            r["sha256"].as_str().unwrap(),
            tactus_glove::sha256_file(&src).unwrap()
        );
        assert!(r["seconds"].as_f64().unwrap() > 0.0);
        assert!(r["error"].is_null());
        assert_eq!(r["options"]["separator"], "spectral");
    }
    let bad = record(&m, "broken.mp3");
    assert_eq!(bad["status"], "failed");
    assert!(bad["error"].as_str().unwrap().contains("broken.mp3"));
    // No temporary file is left anywhere.
    for e in walk(&out) {
        let name = e.file_name().unwrap().to_string_lossy().into_owned();
        assert!(!name.starts_with('.'), "temporary left: {}", e.display());
    }
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut v = Vec::new();
    for e in fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            v.extend(walk(&p));
        } else {
            v.push(p);
        }
    }
    v
}

#[test]
fn batch_bytes_equal_single_renders_for_any_number_of_jobs() {
    let l = library();
    fs::remove_file(l.lib.join("sub/broken.mp3")).unwrap();
    for (dir, jobs) in [("j1", "1"), ("j2", "2")] {
        let o = tactus(
            &l.root,
            &[
                "render",
                "lib",
                "--out-dir",
                dir,
                "--with-features",
                "--jobs",
                jobs,
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
    }
    // One song on one thread per job, and one song with the engine's own threads.
    let o = tactus(
        &l.root,
        &[
            "render",
            "lib",
            "--out-dir",
            "t2",
            "--with-features",
            "--jobs",
            "1",
            "--job-threads",
            "2",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    for base in OUTPUTS {
        let name = format!("{base}.pattern.json");
        let feat = format!("{base}.features.json");
        let src = l.lib.join(if base == "sub/two" {
            base.to_string()
        } else {
            format!("{base}.wav")
        });
        let single = l.root.join("single.json");
        let single_f = l.root.join("single.features.json");
        let o = tactus(
            &l.root,
            &[
                "render",
                src.to_str().unwrap(),
                "-o",
                single.to_str().unwrap(),
                "--features",
                single_f.to_str().unwrap(),
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        for dir in ["j1", "j2", "t2"] {
            assert_eq!(
                fs::read(l.root.join(dir).join(&name)).unwrap(),
                fs::read(&single).unwrap(),
                "{dir}/{name} differs from the single render"
            );
            assert_eq!(
                fs::read(l.root.join(dir).join(&feat)).unwrap(),
                fs::read(&single_f).unwrap(),
                "{dir}/{feat} differs from the single render"
            );
        }
    }
}

#[test]
fn a_rerun_skips_what_is_up_to_date_and_renders_what_changed() {
    let l = library();
    fs::remove_file(l.lib.join("sub/broken.mp3")).unwrap();
    let run = |extra: &[&str]| {
        let mut args = vec!["render", "lib", "--out-dir", "out"];
        args.extend_from_slice(extra);
        let o = tactus(&l.root, &args);
        assert!(o.status.success(), "{}", stderr(&o));
        manifest(&l.root.join("out"))
    };
    let out = l.root.join("out");
    let first = run(&[]);
    assert!(first.iter().all(|r| r["status"] == "ok"), "{first:?}");
    let stamps: Vec<SystemTime> = OUTPUTS
        .iter()
        .map(|b| mtime(&out.join(format!("{b}.pattern.json"))))
        .collect();
    // Nothing changed: everything is skipped and no output is touched.
    let again = run(&[]);
    assert_eq!(again.len(), 3);
    assert!(again.iter().all(|r| r["status"] == "skipped"), "{again:?}");
    for (b, t) in OUTPUTS.iter().zip(&stamps) {
        assert_eq!(mtime(&out.join(format!("{b}.pattern.json"))), *t, "{b}");
    }
    // A changed song, a deleted output: only those render again.
    write_song(&l.lib.join("one.wav"), 3.0, 5);
    fs::remove_file(out.join("sub/two.pattern.json")).unwrap();
    let m = run(&[]);
    assert_eq!(record(&m, "one.wav")["status"], "ok");
    assert_eq!(record(&m, "sub/two")["status"], "ok");
    assert_eq!(record(&m, "three.wav")["status"], "skipped");
    assert_eq!(
        record(&m, "one.wav")["sha256"].as_str().unwrap(),
        tactus_glove::sha256_file(l.lib.join("one.wav")).unwrap()
    );
    // Other options, or an output not written before: everything renders again.
    let m = run(&["--levels", "4"]);
    assert!(m.iter().all(|r| r["status"] == "ok"), "{m:?}");
    assert_eq!(record(&m, "one.wav")["options"]["levels"], 4);
    let m = run(&["--levels", "4", "--with-features"]);
    assert!(m.iter().all(|r| r["status"] == "ok"), "{m:?}");
    let m = run(&["--levels", "4"]);
    assert!(m.iter().all(|r| r["status"] == "skipped"), "{m:?}");
}

#[test]
fn a_killed_batch_resumes_from_the_appended_records() {
    let l = library();
    fs::remove_file(l.lib.join("sub/broken.mp3")).unwrap();
    let o = tactus(
        &l.root,
        &["render", "lib", "--out-dir", "out", "--jobs", "1"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    // What a kill after the first song leaves: that song's line, then a torn line.
    let out = l.root.join("out");
    let text = fs::read_to_string(out.join("manifest.jsonl")).unwrap();
    let first = text.lines().next().unwrap();
    fs::write(
        out.join("manifest.jsonl"),
        format!("{first}\n{{\"path\":\"/x"),
    )
    .unwrap();
    let o = tactus(
        &l.root,
        &["render", "lib", "--out-dir", "out", "--jobs", "1"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let m = manifest(&out);
    assert_eq!(m.len(), 3, "one record per input: {m:?}");
    assert_eq!(m.iter().filter(|r| r["status"] == "skipped").count(), 1);
    assert_eq!(m.iter().filter(|r| r["status"] == "ok").count(), 2);
}

#[test]
fn globs_and_files_as_inputs() {
    let l = library();
    // A quoted glob: the root is the part before the first wildcard.
    let o = tactus(&l.root, &["render", "lib/sub/**/*.wav", "--out-dir", "g"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(l.root.join("g/deeper/three.pattern.json").is_file());
    assert_eq!(manifest(&l.root.join("g")).len(), 1);
    // Files: outputs named after the file alone; a missing one is reported.
    let o = tactus(
        &l.root,
        &[
            "render",
            "lib/one.wav",
            "lib/sub/two",
            "lib/missing.wav",
            "--out-dir",
            "f",
        ],
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("missing.wav: no such file"),
        "{}",
        stderr(&o)
    );
    assert!(l.root.join("f/one.pattern.json").is_file());
    assert!(l.root.join("f/two.pattern.json").is_file());
    let m = manifest(&l.root.join("f"));
    assert_eq!(record(&m, "missing.wav")["status"], "failed");
}

#[test]
fn one_song_options_do_not_mix_with_a_library() {
    let l = library();
    for (args, needle) in [
        (
            vec!["render", "lib", "--out-dir", "o", "-o", "x.json"],
            "-o names one song's output",
        ),
        (
            vec!["render", "lib/one.wav", "lib/sub/two"],
            "needs --out-dir",
        ),
        (
            vec!["render", "lib/one.wav", "--jobs", "2"],
            "--jobs needs --out-dir",
        ),
        (vec!["render", "lib"], "is a directory"),
    ] {
        let o = tactus(&l.root, &args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}
