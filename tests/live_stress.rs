//! Real-time hygiene under stress: `tactus live` through a private PulseAudio null
//! sink (the recipe of `tests/live.rs`), drum hits every 500 ms played into it, the frames
//! logged by the file sink, while
//!
//! 1. both cores are saturated by other processes (two busy loops per core) for
//!    `TACTUS_STRESS_LOAD_S` seconds (default 15; the figure is 30, README reports
//!    that run), and then
//! 2. the whole process is stopped (SIGSTOP) for 3 s, the worst starvation there is: the
//!    sound server queues those 3 s and hands them over in one burst on SIGCONT.
//!
//! Measured from the log: each frame's lag = the time it was written (`mono_ms`) minus its
//! audio's time (`time_ms`, which counts audio dropped to catch up), relative to the median
//! lag before the load. A growing backlog shows as a growing lag.
//!
//! Asserts:
//! * no crash: exit 0 after SIGINT, with the processing histogram, the backlog and the
//!   overrun/xrun counters printed;
//! * during the load the lag is printed, not asserted: it includes the sound server's own
//!   delay, which a starved PulseAudio (normal priority) let grow to 2 s in one run at load
//!   8.5, audio that did not exist yet and so could not be caught up on;
//! * 1 s after the load and 2 s after the stall, the lag is back at the baseline: median within
//!   20 ms (two 10 ms bins), p95 within 40 ms (the rhythm target), and no frame later than
//!   250 ms (the catch-up bound plus one 50 ms stall of the sink thread: the sound server
//!   and the other jobs on this 2-core machine still delay single frames by up to 100 ms;
//!   a backlog that did not recover would show seconds), and the hits are felt again (at
//!   least 3 of every 4);
//! * the stall was caught up by dropping audio (at least 80 % of the 3 s, counting what the
//!   full ring turned away, which was not sent late either), at most one
//!   frame of it (one on its way when the process stopped) went out late, and the overrun
//!   and xrun counters are printed (non-zero when they happened: the ring's overruns are
//!   checked in `crates/tactus-session/tests/sessions.rs`).
//!
//! Needs `pulseaudio`, `pactl` and `paplay`; without them it prints SKIPPED, and fails under
//! `CI=true`.
#![cfg(feature = "audio")]

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

mod common;

#[path = "common/pulse.rs"]
mod pulse;
use pulse::Pulse;

/// Child processes killed (by their own pid) and reaped on drop.
struct Children(Vec<Child>);

impl Drop for Children {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// A mono 16-bit WAV of `seconds` with a drum hit (70 Hz thump and a noise burst, as in
/// `tests/live.rs`) every `period` s.
fn write_hits(path: &Path, rate: u32, seconds: f32, period: f32) {
    let n = (seconds * rate as f32) as usize;
    let mut x = vec![0.0f32; n];
    let mut seed = 1u32;
    let mut t = period;
    while t < seconds {
        let i0 = (t * rate as f32) as usize;
        for j in 0..(rate as usize / 10).min(n - i0) {
            let tt = j as f32 / rate as f32;
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let noise = (seed >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0;
            x[i0 + j] += 0.8 * (std::f32::consts::TAU * 70.0 * tt).sin() * (-tt / 0.04).exp()
                + 0.5 * noise * (-tt / 0.008).exp();
        }
        t += period;
    }
    pulse::write_wav(path, rate, &x);
}

/// (mono_ms, time_ms, index finger up) of every pins packet in a file-sink log.
fn pins(log: &Path) -> Vec<(f64, f64, bool)> {
    pulse::pins(log)
        .into_iter()
        .map(|(t, mono, hex)| (mono, t as f64, pulse::index_up(&hex)))
        .collect()
}

/// Seconds between hits (the spacing `tests/live.rs` shows is followed hit for hit).
const PERIOD: f64 = 0.5;

fn sleep_until(t0: Instant, s: f64) {
    if let Some(d) = (t0 + Duration::from_secs_f64(s)).checked_duration_since(Instant::now()) {
        std::thread::sleep(d);
    }
}

fn signal(pid: u32, sig: &str) {
    let st = Command::new("kill")
        .args([sig, &pid.to_string()])
        .status()
        .unwrap();
    assert!(st.success(), "kill {sig} {pid}");
}

/// A number after `key` in `text` (e.g. "overruns 3").
fn number_after(text: &str, key: &str) -> f64 {
    let at = text
        .find(key)
        .unwrap_or_else(|| panic!("no {key:?} in {text}"))
        + key.len();
    text[at..]
        .trim_start()
        .split(|c: char| !(c.is_ascii_digit() || c == '.'))
        .next()
        .unwrap()
        .parse()
        .unwrap_or_else(|_| panic!("no number after {key:?} in {text}"))
}

#[test]
fn live_keeps_up_under_cpu_load_and_catches_up_after_a_stall() {
    let Some(pulse) = Pulse::start(
        "live_keeps_up_under_cpu_load_and_catches_up_after_a_stall",
        &["pulseaudio", "pactl", "paplay"],
    ) else {
        return;
    };
    let load_s: f64 = std::env::var("TACTUS_STRESS_LOAD_S")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(15.0);
    let (load_start, stall_s) = (5.0, 3.0);
    let load_end = load_start + load_s;
    let stop_at = load_end + 3.0;
    let cont_at = stop_at + stall_s;
    let end_at = cont_at + 6.0;

    let d = tempfile::tempdir().unwrap();
    let wav = d.path().join("hits.wav");
    write_hits(&wav, 48_000, end_at as f32 + 10.0, PERIOD as f32);
    let log = d.path().join("live.jsonl");
    let t0 = Instant::now();
    let live = pulse
        .cmd(env!("CARGO_BIN_EXE_tactus"))
        .args(["live", "--seconds", "600", "--glove"])
        .arg(format!("file:{}", log.display()))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let pid = live.id();
    let mut live = Children(vec![live]);
    let _player = Children(vec![pulse
        .cmd("paplay")
        .args(["-d", "vsink"])
        .arg(&wav)
        .spawn()
        .unwrap()]);

    sleep_until(t0, load_start);
    let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
    let hogs = Children(
        (0..2 * cores)
            .map(|_| {
                Command::new("sh")
                    .args(["-c", "while :; do :; done"])
                    .spawn()
                    .unwrap()
            })
            .collect(),
    );
    sleep_until(t0, load_end);
    drop(hogs);
    sleep_until(t0, stop_at);
    signal(pid, "-STOP");
    sleep_until(t0, cont_at);
    signal(pid, "-CONT");
    sleep_until(t0, end_at);
    signal(pid, "-INT");
    let child = live.0.pop().unwrap();
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    eprintln!("{err}");
    assert!(out.status.success(), "tactus live failed: {err}");

    // Printed at exit: the processing histogram, the backlog, the counters.
    assert!(
        err.contains("tactus: processing per 256-sample block"),
        "{err}"
    );
    let overruns = number_after(&err, "overruns ");
    let xruns = number_after(&err, "xruns ");
    let caught_up = number_after(&err, "caught up ");
    let dropped_s = number_after(&err, "dropping ");
    eprintln!("overruns {overruns}, xruns {xruns}, caught up {caught_up} times, {dropped_s} s");
    assert!(caught_up >= 1.0, "the stall was not caught up: {err}");
    // Audio the full ring turned away (its overruns, at the device's rate) was not sent
    // late either: it counts with what was dropped.
    let rate = number_after(&err, "live from default (");
    let lost_s = overruns / rate;
    assert!(
        dropped_s + lost_s >= 0.8 * stall_s,
        "only {dropped_s} s dropped and {lost_s} s lost in the ring after a {stall_s} s stall"
    );

    let p = pins(&log);
    let lag = |x: &(f64, f64, bool)| x.0 - x.1;
    let window = |a: f64, b: f64| -> Vec<&(f64, f64, bool)> {
        p.iter()
            .filter(|x| x.0 >= a * 1e3 && x.0 < b * 1e3)
            .collect()
    };
    let first = p.first().expect("no frames").0 / 1e3;
    let mut base: Vec<f64> = window(first + 0.5, load_start)
        .iter()
        .map(|x| lag(x))
        .collect();
    assert!(base.len() > 50, "{} frames before the load", base.len());
    base.sort_by(f64::total_cmp);
    let baseline = base[base.len() / 2];
    eprintln!("baseline lag (written - audio time) {baseline:.1} ms");
    let extra = |a: f64, b: f64| -> (Vec<f64>, usize) {
        let w = window(a, b);
        // Hits felt: index-finger rises, those within 150 ms of the previous one merged
        // (a hit's thump and noise can raise the pins twice).
        let mut rises = 0;
        let mut last_rise = f64::NEG_INFINITY;
        for pair in w.windows(2) {
            if pair[1].2 && !pair[0].2 {
                if pair[1].0 - last_rise > 150.0 {
                    rises += 1;
                }
                last_rise = pair[1].0;
            }
        }
        let mut v: Vec<f64> = w.iter().map(|x| lag(x) - baseline).collect();
        v.sort_by(f64::total_cmp);
        (v, rises)
    };
    let show = |what: &str, v: &[f64], rises: usize, secs: f64| {
        let q = |f: f64| v[((v.len() as f64 * f).ceil() as usize).clamp(1, v.len()) - 1];
        eprintln!(
            "{what}: {} frames, extra lag median {:.1} / p95 {:.1} / max {:.1} ms, {rises} hits felt of {:.0}",
            v.len(),
            q(0.5),
            q(0.95),
            q(1.0),
            secs / PERIOD
        );
        q(1.0)
    };

    let (v, rises) = extra(first + 0.5, load_start);
    show("before the load", &v, rises, load_start - first - 0.5);
    // During the load: reported, not asserted. The lag then includes the sound server's
    // own delay (it runs at normal priority and, starved, hands audio over seconds late at
    // the pace it makes it: nothing to catch up on), which tactus cannot control.
    let (during, rises) = extra(load_start + 0.5, load_end);
    assert!(!during.is_empty(), "no frames during the load");
    show("load", &during, rises, load_s - 0.5);
    let (late_load, rises) = extra(load_start + load_s / 2.0, load_end);
    show("second half of the load", &late_load, rises, load_s / 2.0);

    // After the load and after the stall: back to the baseline, hits felt.
    for (what, a, b) in [
        ("after the load", load_end + 1.0, stop_at),
        ("2 s after the stall", cont_at + 2.0, end_at - 0.5),
    ] {
        let (v, rises) = extra(a, b);
        assert!(!v.is_empty(), "no frames {what}");
        let max = show(what, &v, rises, b - a);
        let median = v[v.len() / 2];
        let p95 = v[((v.len() as f64 * 0.95).ceil() as usize).clamp(1, v.len()) - 1];
        assert!(
            median <= 20.0 && p95 <= 40.0 && max <= 250.0,
            "{what}: frames {median:.1} ms (median), {p95:.1} ms (p95), {max:.1} ms (max) \
             later than before the load"
        );
        let expected = (b - a) / PERIOD;
        assert!(
            rises as f64 >= 0.75 * expected - 1.0,
            "{what}: {rises} hits felt of {expected:.0}"
        );
    }
    // The stall itself: what came out right after SIGCONT.
    // Right after the stall: the stale burst was dropped, not sent. One frame may have
    // been on its way when the process stopped (it is written on SIGCONT, 3 s late).
    let (v, rises) = extra(cont_at, cont_at + 2.0);
    assert!(!v.is_empty(), "no frames after the stall");
    show("first 2 s after the stall", &v, rises, 2.0);
    let stale = v.iter().filter(|&&x| x > 250.0).count();
    assert!(
        stale <= 1,
        "{stale} frames of the stalled audio were sent late"
    );
}
