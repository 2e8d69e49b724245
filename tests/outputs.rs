//! Outputs are a transaction: an output that is the input, two outputs naming
//! one file, a directory the user cannot write, Ctrl-C mid-render: each through the binary,
//! each leaving every pre-existing file byte for byte as it was and no temporary behind.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

mod common;

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

/// A tone with clicks, `seconds` long, 16-bit mono WAV.
fn write_song(path: &Path, seconds: f32) {
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: 44_100,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    let n = (seconds * 44_100.0) as usize;
    for i in 0..n {
        let t = i as f32 / 44_100.0;
        let click = if i % 22_050 < 200 { 0.5 } else { 0.0 };
        let x = 0.3 * (2.0 * std::f32::consts::PI * 220.0 * t).sin() + click;
        w.write_sample((x * 20_000.0) as i16).unwrap();
    }
    w.finalize().unwrap();
}

fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Fails with exit code 1 and exactly one line on stderr that contains `needle`.
fn assert_refused(o: &Output, needle: &str) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(
        err.trim_end().lines().count(),
        1,
        "one line expected: {err}"
    );
    assert!(err.contains(needle), "expected {needle:?} in {err}");
    assert!(!err.contains("panicked"), "{err}");
}

fn setup() -> (tempfile::TempDir, PathBuf, Vec<u8>) {
    let d = tempfile::tempdir().unwrap();
    let song = d.path().join("song.wav");
    write_song(&song, 2.0);
    let bytes = fs::read(&song).unwrap();
    (d, song, bytes)
}

#[test]
fn output_that_is_the_input_is_refused() {
    let (d, song, bytes) = setup();
    let o = tactus(d.path(), &["render", "song.wav", "-o", "song.wav"]);
    assert_refused(&o, "is the input");
    assert_eq!(fs::read(&song).unwrap(), bytes);
    // Through another spelling of the same path, and as the features or the plot.
    for args in [
        ["render", "song.wav", "-o", "./sub/../song.wav"],
        ["render", "song.wav", "--features", "song.wav"],
        ["render", "song.wav", "--plot", "song.wav"],
    ] {
        fs::create_dir_all(d.path().join("sub")).unwrap();
        let o = tactus(d.path(), &args);
        assert_refused(&o, "is the input");
        assert_eq!(fs::read(&song).unwrap(), bytes);
    }
    assert_eq!(listing(d.path()), vec!["song.wav", "sub"]);
}

#[test]
fn hard_and_symbolic_links_to_the_input_are_refused() {
    let (d, song, bytes) = setup();
    fs::hard_link(&song, d.path().join("hard.wav")).unwrap();
    let o = tactus(d.path(), &["render", "song.wav", "-o", "hard.wav"]);
    assert_refused(&o, "is the input");
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(&song, d.path().join("soft.json")).unwrap();
        let o = tactus(d.path(), &["render", "song.wav", "--features", "soft.json"]);
        assert_refused(&o, "is the input");
    }
    assert_eq!(fs::read(&song).unwrap(), bytes);
    // A supplied stem is an input too.
    let o = tactus(
        d.path(),
        &[
            "render",
            "song.wav",
            "--stem",
            "bass=hard.wav",
            "-o",
            "song.wav",
        ],
    );
    assert_refused(&o, "is the input");
    assert_eq!(fs::read(&song).unwrap(), bytes);
}

#[test]
fn two_outputs_naming_one_file_are_refused() {
    let (d, _song, _) = setup();
    fs::write(d.path().join("a.json"), b"keep me").unwrap();
    for args in [
        ["render", "song.wav", "-o", "a.json", "--features", "a.json"],
        [
            "render",
            "song.wav",
            "-o",
            "new.json",
            "--features",
            "./new.json",
        ],
    ] {
        let o = tactus(d.path(), &args);
        assert_refused(&o, "both name");
    }
    fs::hard_link(d.path().join("a.json"), d.path().join("b.svg")).unwrap();
    let o = tactus(
        d.path(),
        &["render", "song.wav", "-o", "a.json", "--plot", "b.svg"],
    );
    assert_refused(&o, "both name");
    assert_eq!(fs::read(d.path().join("a.json")).unwrap(), b"keep me");
    assert_eq!(listing(d.path()), vec!["a.json", "b.svg", "song.wav"]);
}

#[test]
fn impossible_locations_fail_before_any_work() {
    let (d, _song, _) = setup();
    fs::write(d.path().join("file"), b"x").unwrap();
    fs::create_dir(d.path().join("dir")).unwrap();
    for (args, needle) in [
        (
            [
                "render",
                "song.wav",
                "-o",
                "ok.json",
                "--features",
                "nodir/f.json",
            ],
            "does not exist",
        ),
        (
            [
                "render",
                "song.wav",
                "-o",
                "ok.json",
                "--features",
                "file/f.json",
            ],
            "not a directory",
        ),
        (
            ["render", "song.wav", "-o", "ok.json", "--features", "dir"],
            "is a directory",
        ),
    ] {
        let o = tactus(d.path(), &args);
        assert_refused(&o, needle);
        assert!(!d.path().join("ok.json").exists());
    }
    assert_eq!(listing(d.path()), vec!["dir", "file", "song.wav"]);
    assert!(listing(&d.path().join("dir")).is_empty());
}

/// Runs `tactus` as uid/gid 65534 (nobody) through util-linux's `setpriv`, when we are
/// root and it is installed; `None` otherwise.
#[cfg(unix)]
fn as_nobody(dir: &Path, args: &[&str]) -> Option<Output> {
    let root = Command::new("id").arg("-u").output().ok()?;
    if String::from_utf8_lossy(&root.stdout).trim() != "0" {
        return None;
    }
    Command::new("setpriv")
        .args(["--reuid=65534", "--regid=65534", "--clear-groups", "--"])
        .arg(env!("CARGO_BIN_EXE_tactus"))
        .args(args)
        .current_dir(dir)
        .output()
        .ok()
}

#[cfg(unix)]
#[test]
fn read_only_features_directory_leaves_no_pattern_behind() {
    use std::os::unix::fs::PermissionsExt;
    let (d, _song, _) = setup();
    let ro = d.path().join("ro");
    fs::create_dir(&ro).unwrap();
    fs::set_permissions(&ro, fs::Permissions::from_mode(0o555)).unwrap();
    fs::set_permissions(d.path(), fs::Permissions::from_mode(0o777)).unwrap();
    fs::set_permissions(d.path().join("song.wav"), fs::Permissions::from_mode(0o644)).unwrap();
    let args = [
        "render",
        "song.wav",
        "-o",
        "ok.json",
        "--features",
        "ro/f.json",
    ];
    let o = match as_nobody(d.path(), &args) {
        Some(o) => o,
        // Not root: then we are an ordinary user already, and 0o555 binds us.
        None => tactus(d.path(), &args),
    };
    if o.status.code() == Some(0) && stderr(&o).is_empty() {
        // Root without setpriv: the directory is writable for us; nothing to check.
        common::skip("read_only_features_directory: cannot drop root");
        return;
    }
    assert_refused(&o, "ro/f.json");
    assert!(stderr(&o).contains("Permission denied"), "{}", stderr(&o));
    assert_eq!(
        listing(d.path()),
        vec!["ro", "song.wav"],
        "ok.json must not exist"
    );
    assert!(listing(&ro).is_empty());
}

#[test]
fn every_output_or_none_and_old_files_survive_a_failure() {
    let (d, _song, _) = setup();
    fs::write(d.path().join("old.json"), b"old pattern").unwrap();
    // A run that fails (an unknown plot format) changes nothing.
    let o = tactus(
        d.path(),
        &["render", "song.wav", "-o", "old.json", "--plot", "x.gif"],
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert_eq!(fs::read(d.path().join("old.json")).unwrap(), b"old pattern");
    assert_eq!(listing(d.path()), vec!["old.json", "song.wav"]);
    // Success replaces every output.
    let o = tactus(
        d.path(),
        &[
            "render",
            "song.wav",
            "-o",
            "old.json",
            "--features",
            "f.json",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(fs::read_to_string(d.path().join("old.json"))
        .unwrap()
        .contains("tactus-pattern"));
    assert_eq!(listing(d.path()), vec!["f.json", "old.json", "song.wav"]);
}

#[cfg(unix)]
#[test]
fn ctrl_c_mid_render_removes_the_temporaries_and_keeps_old_files() {
    let d = tempfile::tempdir().unwrap();
    write_song(&d.path().join("long.wav"), 240.0);
    fs::write(d.path().join("old.json"), b"old pattern").unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_tactus"))
        .current_dir(d.path())
        .args([
            "render",
            "long.wav",
            "-o",
            "old.json",
            "--features",
            "f.json",
        ])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // The temporaries exist from the start of the run: wait for them, then interrupt.
    let t0 = Instant::now();
    while !listing(d.path()).iter().any(|n| n.contains(".tmp-")) {
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "no temporary appeared"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
    std::thread::sleep(Duration::from_millis(200));
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    assert!(stderr(&o).contains("interrupted"), "{}", stderr(&o));
    assert_eq!(fs::read(d.path().join("old.json")).unwrap(), b"old pattern");
    assert_eq!(listing(d.path()), vec!["long.wav", "old.json"]);
}

#[test]
fn render_without_outputs_says_what_it_did() {
    let (d, _song, _) = setup();
    let o = tactus(d.path(), &["render", "song.wav"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.contains("wrote nothing") && err.contains("-o PATTERN.json"),
        "{err}"
    );
    assert_eq!(listing(d.path()), vec!["song.wav"]);
}

#[test]
fn a_directory_as_input_is_named_as_such() {
    let (d, _song, _) = setup();
    let o = tactus(d.path(), &["render", ".", "-o", "x.json"]);
    assert_refused(&o, "is a directory");
    assert_eq!(listing(d.path()), vec!["song.wav"]);
}
