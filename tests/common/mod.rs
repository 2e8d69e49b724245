//! Helpers shared by the binary's integration tests (`mod common;`).
#![allow(dead_code)]

/// Whether this run is CI (`CI=true`, which `.ci/run` exports): then a missing stand-in
/// (socat, PulseAudio, ONNX Runtime, a model, privilege dropping) is a failure, not a skip.
pub fn in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true" || v == "1")
}

/// Skips the calling test with a `SKIPPED` line on a developer's machine; panics under
/// `CI=true`, so a broken install step cannot leave a real stand-in untested while CI is
/// green. `what` says which test and what is missing (and how to get it).
pub fn skip(what: &str) {
    if in_ci() {
        panic!("CI=true and a stand-in is missing, so this is a failure, not a skip: {what}");
    }
    eprintln!("SKIPPED {what}");
}
