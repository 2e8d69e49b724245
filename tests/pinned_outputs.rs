//! Pinned outputs: moving code must not change a single byte of what `tactus render` writes.
//!
//! Two gates share one rule: every case renders a song and the SHA-256 of its pattern and
//! features files must equal the one committed under `tests/golden/`.
//!
//! * `demo_and_fixtures_...` (always run): the bundled demo with the defaults and with each
//!   alternative tracker, separator setting and drum front end, and the demo plus the two
//!   committed corpus excerpts (`corpus/fixtures/*/mix.flac`) offline and streaming, with the
//!   full and the live profile. Golden file: `tests/golden/pinned.txt`.
//! * `corpus_...` (ignored by default; a refactor's local gate): the same four
//!   mode × profile combinations on every `*/mix.wav` or `*/mix.flac` under
//!   `TACTUS_PIN_CORPUS` (made by `corpus/generate.py`, see CONTRIBUTING.md). Golden file:
//!   `tests/golden/pinned_corpus.txt`.
//!
//! A change that means to alter the outputs regenerates the golden files with
//! `TACTUS_PIN_UPDATE=1` and says why in its commit. On a mismatch the produced files are kept
//! in the folder the message names, for `diff`.

use std::path::{Path, PathBuf};
use std::process::Command;

/// (name, extra arguments) rendered on the demo only.
const DEMO_CASES: &[(&str, &[&str])] = &[
    ("default", &[]),
    ("pyin", &["--pitch", "pyin"]),
    ("bands", &["--drums", "bands"]),
    ("streaming", &["--mode", "streaming"]),
    // The harmonic-sum bass in place of the learned salience.
    ("auto-shs", &["--pitch", "auto-shs"]),
    // The separator without its learned kit mask, with the harmonic-sum bass.
    (
        "kit-mask-off",
        &["--kit-mask", "off", "--pitch", "auto-shs"],
    ),
];

/// (name, extra arguments) rendered on every song: offline and streaming, full and live.
const MODE_PROFILE: &[(&str, &[&str])] = &[
    ("offline-full", &["--mode", "offline", "--profile", "full"]),
    ("offline-live", &["--mode", "offline", "--profile", "live"]),
    (
        "streaming-full",
        &["--mode", "streaming", "--profile", "full"],
    ),
    (
        "streaming-live",
        &["--mode", "streaming", "--profile", "live"],
    ),
];

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn sha256(path: &Path) -> String {
    tactus_glove::sha256_file(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Renders `song` (relative to `cwd`, so that the path recorded in the pattern does not
/// depend on where the checkout is) with `extra`; returns the lines `name kind sha256`.
fn render(cwd: &Path, song: &str, name: &str, extra: &[&str], out: &Path) -> [String; 2] {
    let pattern = out.join(format!("{name}.pattern.json"));
    let features = out.join(format!("{name}.features.json"));
    let o = Command::new(env!("CARGO_BIN_EXE_tactus"))
        .current_dir(cwd)
        .args(["render", song, "-o"])
        .arg(&pattern)
        .arg("--features")
        .arg(&features)
        .args(extra)
        .output()
        .expect("run tactus");
    assert!(
        o.status.success(),
        "render {name}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    [
        format!("{name} pattern {}", sha256(&pattern)),
        format!("{name} features {}", sha256(&features)),
    ]
}

/// Compares `got` with the golden file, or rewrites it under `TACTUS_PIN_UPDATE=1`.
fn check(golden: &Path, got: Vec<String>, dir: tempfile::TempDir) {
    if std::env::var("TACTUS_PIN_UPDATE").is_ok_and(|v| v == "1") {
        std::fs::create_dir_all(golden.parent().unwrap()).unwrap();
        std::fs::write(golden, got.join("\n") + "\n").unwrap();
        return;
    }
    let want = std::fs::read_to_string(golden)
        .unwrap_or_else(|e| panic!("{}: {e} (TACTUS_PIN_UPDATE=1 writes it)", golden.display()));
    let want: Vec<&str> = want.lines().filter(|l| !l.trim().is_empty()).collect();
    let differ: Vec<String> = got
        .iter()
        .filter(|g| !want.contains(&g.as_str()))
        .cloned()
        .collect();
    if !differ.is_empty() {
        let keep = dir.keep();
        panic!(
            "outputs changed (kept in {}):\n  got  {}",
            keep.display(),
            differ.join("\n  got  "),
        );
    }
    assert_eq!(got.len(), want.len(), "cases differ from the pinned list");
}

#[test]
fn demo_and_fixtures_outputs_are_byte_identical_to_the_pinned_ones() {
    let dir = tempfile::tempdir().unwrap();
    let mut got = Vec::new();
    for (name, extra) in DEMO_CASES {
        got.extend(render(
            &root(),
            "examples/demo.ogg",
            name,
            extra,
            dir.path(),
        ));
    }
    let songs = [
        ("demo", "examples/demo.ogg".to_string()),
        ("bwv347", "corpus/fixtures/bwv347_120bpm/mix.flac".into()),
        ("bwv66-6", "corpus/fixtures/bwv66-6_96bpm/mix.flac".into()),
    ];
    for (song, path) in &songs {
        for (mode, extra) in MODE_PROFILE {
            let name = format!("{song}.{mode}");
            got.extend(render(&root(), path, &name, extra, dir.path()));
        }
    }
    check(&root().join("tests/golden/pinned.txt"), got, dir);
}

#[test]
#[ignore = "needs a generated corpus: TACTUS_PIN_CORPUS=DIR cargo test --test pinned_outputs -- --ignored"]
fn corpus_outputs_are_byte_identical_to_the_pinned_ones() {
    let corpus = PathBuf::from(
        std::env::var("TACTUS_PIN_CORPUS")
            .expect("TACTUS_PIN_CORPUS=DIR, a folder of corpus/generate.py songs"),
    );
    let mut songs: Vec<(String, String)> = std::fs::read_dir(&corpus)
        .unwrap_or_else(|e| panic!("{}: {e}", corpus.display()))
        .filter_map(|e| {
            let song = e.ok()?.file_name().into_string().ok()?;
            ["mix.wav", "mix.flac"]
                .iter()
                .map(|m| format!("{song}/{m}"))
                .find(|p| corpus.join(p).is_file())
                .map(|p| (song, p))
        })
        .collect();
    songs.sort();
    assert!(
        songs.len() >= 20,
        "{} holds {} songs; the gate wants at least 20",
        corpus.display(),
        songs.len()
    );
    let dir = tempfile::tempdir().unwrap();
    let mut got = Vec::new();
    for (song, path) in &songs {
        for (mode, extra) in MODE_PROFILE {
            let name = format!("{song}.{mode}");
            got.extend(render(&corpus, path, &name, extra, dir.path()));
        }
    }
    check(&root().join("tests/golden/pinned_corpus.txt"), got, dir);
}
