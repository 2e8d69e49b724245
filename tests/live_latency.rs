//! End-to-end latency of `tactus live`, measured from outside the program by
//! `benches/live_latency.py`: a private PulseAudio null sink as the microphone, `pacat`
//! writing drum hits and tone bursts at wall-clock pace, `tactus live --glove serial:PTY`
//! over a socat pty pair, and the wire protocol read with arrival times on the far end.
//!
//! What it asserts (the targets, with the tolerance this loaded 2-core machine
//! needs, see README "Live latency"):
//! * rhythm fingers: p95 ≤ 40 ms (the target) from a click's samples reaching the sound
//!   server to the first packet with a rhythm pin up (the default band drums measured
//!   p95 23–33 ms at load 9–13), median ≤ 30 ms, at least 19 of 20 clicks felt (≥ 95 %),
//!   and
//!   no rhythm pin in either 1.5 s window of silence;
//! * pitch fingers: median ≤ 80 ms (the target) and p95 ≤ 120 ms: the target is 80 ms, and
//!   measured p95 was 64–80 ms on a quiet machine but single bursts reached 100–120 ms at
//!   load 10 (one late wake-up of the engine thread or the sink), so the test allows 40 ms
//!   for one scheduling stall;
//! * the capture line (the device's own buffering) is printed, and overruns are 0.
//!
//! A run that misses a target is measured once more (one late wake-up on this shared machine
//! can hold a click back by a bin); two misses in a row fail.
//!
//! Needs `pulseaudio`, `pactl`, `pacat`, `socat` and `python3`; without them it prints
//! SKIPPED, and fails under `CI=true` (`.ci/run` installs them).
#![cfg(feature = "audio")]

use std::process::{Command, Stdio};

mod common;

fn have(program: &str) -> bool {
    Command::new("sh")
        .args(["-c", &format!("command -v {program}")])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

#[test]
fn live_meets_the_latency_targets_end_to_end() {
    for p in ["pulseaudio", "pactl", "pacat", "socat", "python3"] {
        if !have(p) {
            common::skip(&format!(
                "live_meets_the_latency_targets_end_to_end: {p} is not installed \
                 (apt-get install pulseaudio pulseaudio-utils libasound2-plugins socat python3; CI does)"
            ));
            return;
        }
    }
    // One retry: on this shared 2-core machine one late wake-up (of the engine thread, the
    // sink or pacat) can hold a click back by a bin or two; two runs in a row that miss a
    // target fail the test, and both runs' reports are printed.
    let mut errors = Vec::new();
    for attempt in 1..=2 {
        match measure_once() {
            Ok(()) => return,
            Err(e) => {
                eprintln!("attempt {attempt}: {e}");
                errors.push(e);
            }
        }
    }
    panic!("both runs missed a target: {errors:?}");
}

macro_rules! check {
    ($cond:expr, $($fmt:tt)+) => {
        if !$cond {
            return Err(format!($($fmt)+));
        }
    };
}

/// One measurement by `benches/live_latency.py` and the checks the header lists.
fn measure_once() -> Result<(), String> {
    let d = tempfile::tempdir().unwrap();
    let json = d.path().join("latency.json");
    let out = Command::new("python3")
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/benches/live_latency.py"
        ))
        .args([
            "--tactus",
            env!("CARGO_BIN_EXE_tactus"),
            "--clicks",
            "20",
            "--tones",
            "10",
        ])
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    eprintln!("{stdout}{stderr}");
    if !out.status.success() {
        return Err("live_latency.py failed".into());
    }
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let group = |name: &str| {
        r["groups"]
            .as_array()
            .unwrap()
            .iter()
            .find(|g| g["group"] == name)
            .unwrap_or_else(|| panic!("no group {name}"))
            .clone()
    };
    let f = |g: &serde_json::Value, k: &str| g[k].as_f64().unwrap_or(f64::NAN);

    let rhythm = group("rhythm (clicks)");
    check!(
        f(&rhythm, "felt") >= 19.0,
        "only {} of 20 clicks felt",
        rhythm["felt"]
    );
    check!(
        f(&rhythm, "median_ms") <= 30.0,
        "rhythm median {:.1} ms > 30 ms",
        f(&rhythm, "median_ms")
    );
    check!(
        f(&rhythm, "p95_ms") <= 40.0,
        "rhythm p95 {:.1} ms > 40 ms",
        f(&rhythm, "p95_ms")
    );
    let false_frames: Vec<u64> = r["false_rhythm"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    check!(
        false_frames.iter().all(|&n| n == 0),
        "rhythm pins up in silence: {false_frames:?}"
    );

    let pitch = group("pitch (all tones)");
    check!(
        f(&pitch, "felt") >= 9.0,
        "only {} of 10 tone bursts shown",
        pitch["felt"]
    );
    check!(
        f(&pitch, "median_ms") <= 80.0,
        "pitch median {:.1} ms > 80 ms",
        f(&pitch, "median_ms")
    );
    check!(
        f(&pitch, "p95_ms") <= 120.0,
        "pitch p95 {:.1} ms > 120 ms",
        f(&pitch, "p95_ms")
    );

    let live_err = r["runs"][0]["tactus_stderr"].as_str().unwrap();
    check!(live_err.contains("tactus: capture: "), "{live_err}");
    check!(live_err.contains("overruns 0 samples"), "{live_err}");
    Ok(())
}
