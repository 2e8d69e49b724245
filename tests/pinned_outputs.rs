//! Pinned outputs (issue 12): moving code between crates must not change a single byte of
//! what `tactus render` writes. The demo song is rendered with the defaults, with
//! `--pitch pyin`, with `--drums bands`, with `--mode streaming`, with `--pitch auto-shs`
//! and with `--kit-mask off --pitch auto-shs`;
//! the SHA-256 of each
//! pattern and features file must equal the one committed in `tests/golden/pinned.txt`.
//!
//! A change that means to alter the outputs regenerates the file with
//! `TACTUS_PIN_UPDATE=1 cargo test --test pinned_outputs` and says why in its commit. On a
//! mismatch the produced files are kept under the test's temporary folder's name printed in
//! the message, for `diff`.

use std::path::{Path, PathBuf};
use std::process::Command;

/// (name, extra arguments).
const CASES: &[(&str, &[&str])] = &[
    ("default", &[]),
    ("pyin", &["--pitch", "pyin"]),
    ("bands", &["--drums", "bands"]),
    ("streaming", &["--mode", "streaming"]),
    // The default before the learned bass salience (2026-11-24 22:35); byte for byte until
    // the mix's bass range left out octave shadows (2026-11-25), which changes its levels.
    ("auto-shs", &["--pitch", "auto-shs"]),
    // The separator without its learned kit mask and the harmonic-sum bass: the default
    // outputs from before the mask (2026-11-24), byte for byte.
    (
        "kit-mask-off",
        &["--kit-mask", "off", "--pitch", "auto-shs"],
    ),
];

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn golden_path() -> PathBuf {
    root().join("tests/golden/pinned.txt")
}

fn sha256(path: &Path) -> String {
    tactus_glove::sha256_file(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Renders every case; returns lines `name kind sha256`.
fn render_all(out: &Path) -> Vec<String> {
    let mut lines = Vec::new();
    for (name, extra) in CASES {
        let pattern = out.join(format!("{name}.pattern.json"));
        let features = out.join(format!("{name}.features.json"));
        let o = Command::new(env!("CARGO_BIN_EXE_tactus"))
            // The pattern records the input path as given: render from the repository root
            // with a relative path so the hash does not depend on where the checkout is.
            .current_dir(root())
            .args(["render", "examples/demo.ogg", "-o"])
            .arg(&pattern)
            .arg("--features")
            .arg(&features)
            .args(*extra)
            .output()
            .expect("run tactus");
        assert!(
            o.status.success(),
            "render {name}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        lines.push(format!("{name} pattern {}", sha256(&pattern)));
        lines.push(format!("{name} features {}", sha256(&features)));
    }
    lines
}

#[test]
fn demo_outputs_are_byte_identical_to_the_pinned_ones() {
    let dir = tempfile::tempdir().unwrap();
    let got = render_all(dir.path());
    if std::env::var("TACTUS_PIN_UPDATE").is_ok_and(|v| v == "1") {
        std::fs::create_dir_all(golden_path().parent().unwrap()).unwrap();
        std::fs::write(golden_path(), got.join("\n") + "\n").unwrap();
        return;
    }
    let want = std::fs::read_to_string(golden_path())
        .expect("tests/golden/pinned.txt (TACTUS_PIN_UPDATE=1 writes it)");
    let want: Vec<&str> = want.lines().filter(|l| !l.trim().is_empty()).collect();
    let differ: Vec<String> = got
        .iter()
        .filter(|g| !want.contains(&g.as_str()))
        .cloned()
        .collect();
    if !differ.is_empty() {
        let keep = dir.keep();
        panic!(
            "outputs changed (kept in {}):\n  got  {}\n  want {}",
            keep.display(),
            differ.join("\n  got  "),
            want.join("\n  want ")
        );
    }
    assert_eq!(got.len(), want.len(), "cases differ from the pinned list");
}
