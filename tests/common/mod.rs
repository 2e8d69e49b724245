//! Helpers shared by the binary's integration tests (`mod common;`).
#![allow(dead_code)]

/// Skips the calling test on a developer's machine, fails it under `CI=true`, when a
/// stand-in (socat, PulseAudio, ONNX Runtime, a model, privilege dropping) is missing.
#[allow(unused_imports)] // not every test binary that includes this module skips
pub use tactus_testkit::skip;

/// Runs the `tactus` binary with `args` and returns what it did (status, stdout, stderr).
pub fn tactus_output<I, S>(args: I) -> std::process::Output
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    std::process::Command::new(env!("CARGO_BIN_EXE_tactus"))
        .args(args)
        .output()
        .unwrap()
}

/// Runs the `tactus` binary with `args`; panics with its stderr unless it succeeded.
pub fn tactus_ok<I, S>(args: I)
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    let out = tactus_output(args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// `tactus render SONG --mode MODE --bin-ms 25 -o OUT` (what `play` sends, 25 ms bins); the
/// pattern's frames as hex strings.
pub fn render_frames(song: &std::path::Path, out: &std::path::Path, mode: &str) -> Vec<String> {
    tactus_ok([
        "render".as_ref(),
        song.as_os_str(),
        "--mode".as_ref(),
        mode.as_ref(),
        "--bin-ms".as_ref(),
        "25".as_ref(),
        "-o".as_ref(),
        out.as_os_str(),
    ]);
    let p: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out).unwrap()).unwrap();
    p["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap().to_string())
        .collect()
}

/// `tactus eval FEATURES --truth SONG --json OUT`; the parsed report.
pub fn eval(
    features: &std::path::Path,
    song: &std::path::Path,
    out: &std::path::Path,
) -> serde_json::Value {
    tactus_ok([
        "eval".as_ref(),
        features.as_os_str(),
        "--truth".as_ref(),
        song.as_os_str(),
        "--json".as_ref(),
        out.as_os_str(),
    ]);
    serde_json::from_str(&std::fs::read_to_string(out).unwrap()).unwrap()
}
