//! Every numeric option of every subcommand, given inf, nan, -1, 0 and huge values: the
//! binary either succeeds or fails with one line on stderr, and never panics (bad input:
//! `devices --ble-scan-s inf` and `emulate --duration 1e300` used to exit 101).

use std::path::Path;
use std::process::{Command, Output};

fn tactus(dir: &Path, args: &[String]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tactus"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("run tactus")
}

fn write_song(path: &Path) {
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: 44_100,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    for i in 0..44_100 {
        let x = 0.3 * (i as f32 * 220.0 * std::f32::consts::TAU / 44_100.0).sin();
        w.write_sample((x * 20_000.0) as i16).unwrap();
    }
    w.finalize().unwrap();
}

const VALUES: [&str; 9] = [
    "inf",
    "-inf",
    "nan",
    "-1",
    "0",
    "1e300",
    "99999999999999999999",
    "4294967296",
    "",
];

#[test]
fn numeric_options_never_panic_and_fail_in_one_line() {
    let d = tempfile::tempdir().unwrap();
    write_song(&d.path().join("song.wav"));
    // (subcommand and its fixed arguments, numeric options). The fixed arguments keep every
    // run short: a render of 1 s, a play of a missing file, an emulator on a missing port.
    let cases: [(&[&str], &[&str]); 5] = [
        (
            &["render", "song.wav", "-o", "out.json"],
            &["--bin-ms", "--levels", "--threads"],
        ),
        (
            &["play", "missing.wav", "--glove", "null", "--no-audio"],
            &["--bin-ms", "--levels", "--threads", "--offset-ms"],
        ),
        (
            &["live", "--glove", "null"],
            &["--seconds", "--bin-ms", "--levels", "--threads"],
        ),
        (&["emulate", "--port", "missing-port"], &["--duration"]),
        (&["devices"], &["--ble-scan-s"]),
    ];
    let mut runs = 0;
    for (fixed, options) in cases {
        for opt in options {
            for v in VALUES {
                let mut args: Vec<String> = fixed.iter().map(|s| s.to_string()).collect();
                args.push(format!("{opt}={v}"));
                let o = tactus(d.path(), &args);
                runs += 1;
                let err = String::from_utf8_lossy(&o.stderr);
                let code = o.status.code();
                assert!(
                    code.is_some() && code != Some(101) && !err.contains("panicked"),
                    "{args:?}: {code:?} {err}"
                );
                if code != Some(0) {
                    assert_eq!(
                        err.trim_end().lines().count(),
                        1,
                        "{args:?}: one line expected: {err}"
                    );
                    assert!(err.starts_with("tactus: error: "), "{args:?}: {err}");
                }
            }
        }
    }
    assert_eq!(runs, 13 * VALUES.len());
}

#[test]
fn out_of_range_values_are_refused_with_their_meaning() {
    let d = tempfile::tempdir().unwrap();
    write_song(&d.path().join("song.wav"));
    let refuse = |args: &[&str], needle: &str| {
        let args: Vec<String> = args.iter().map(|s| s.to_string()).collect();
        let o = tactus(d.path(), &args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {needle:?} not in {err}");
    };
    refuse(&["render", "song.wav", "--levels", "9"], "1..=8");
    refuse(&["render", "song.wav", "--levels", "255"], "1..=8");
    refuse(&["render", "song.wav", "--bin-ms", "5000000"], "1..=10000");
    refuse(&["devices", "--ble-scan-s", "inf"], "finite");
    refuse(&["emulate", "--port", "x", "--duration", "1e300"], "finite");
    refuse(&["live", "--glove", "null", "--seconds", "nan"], "finite");
    assert!(!d.path().join("out.json").exists());
}

#[test]
fn play_pattern_with_engine_options_is_an_error() {
    let d = tempfile::tempdir().unwrap();
    write_song(&d.path().join("song.wav"));
    let args = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let o = tactus(d.path(), &args(&["render", "song.wav", "-o", "p.json"]));
    assert!(o.status.success());
    let o = tactus(
        d.path(),
        &args(&[
            "play", "p.json", "--glove", "null", "--levels", "4", "--bin-ms", "50",
        ]),
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.contains("--bin-ms, --levels") && err.contains("pattern"),
        "{err}"
    );
}
