//! Live memory is bounded: a long live session, fed at full speed through a capture ring,
//! keeps its resident memory flat. `TACTUS_LIVE_MINUTES` sets the length (default 10; the
//! figure in docs/results.md is for 60:
//! `TACTUS_LIVE_MINUTES=60 cargo test --release -p tactus-session --test live_memory -- --nocapture`).
//! The test fails if the engine still holds more than 5,000 per-hop or per-bin values at
//! the end, if the peak resident set exceeds 50 MB, or if it grows by more than 4 MB
//! between the end of the second minute and the end.

use std::sync::atomic::AtomicBool;
use std::time::Duration;

use tactus_audio::ring::capture_ring;
use tactus_session::{live, LiveInput, LiveOptions};
use tactus_transport::{open_sink, SinkOptions, SinkSpec};

mod common;

/// (VmRSS, VmHWM) of this process in kB, from /proc/self/status.
fn rss_kb() -> (u64, u64) {
    let s = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let field = |name: &str| {
        s.lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|v| v.parse().ok())
            .unwrap_or(0)
    };
    (field("VmRSS:"), field("VmHWM:"))
}

#[test]
fn a_long_live_run_stays_within_50_mb() {
    let minutes: f64 = std::env::var("TACTUS_LIVE_MINUTES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10.0);
    let rate = 48_000;
    let (w, mut reader) = capture_ring(rate as usize / 2);
    let feeder = common::feed(w, rate, minutes * 60.0);
    let sink = open_sink(&SinkSpec::Null, &SinkOptions::default()).unwrap();
    let stop = AtomicBool::new(false);
    let opts = LiveOptions {
        status_every: Duration::from_millis(200),
        ..LiveOptions::default()
    };
    let mut at_2min = None;
    let mut samples = Vec::new();
    let t = std::time::Instant::now();
    let report = live(
        LiveInput {
            reader: &mut reader,
            rate,
            name: "synthetic".into(),
        },
        common::live_config(),
        &sink,
        &opts,
        &stop,
        &mut |s| {
            let (rss, _) = rss_kb();
            if at_2min.is_none() && s.captured_s >= 120.0 {
                at_2min = Some(rss);
            }
            samples.push((s.captured_s, rss));
        },
    )
    .unwrap();
    feeder.join().unwrap();
    sink.close();
    let (end, peak) = rss_kb();
    eprintln!(
        "live_memory: {:.0} s of audio in {:.1} s: {} frames, {} feature values held at the end; RSS after 2 min {} kB, at the end {end} kB, peak (VmHWM) {peak} kB",
        report.captured_s,
        t.elapsed().as_secs_f64(),
        report.frames,
        report.retained_values,
        at_2min.unwrap_or(0),
    );
    // What the engine keeps: a few seconds of hops at most (RSS alone cannot show a slow
    // leak within minutes; this can: without forgetting, it holds every hop of the run).
    assert!(
        report.retained_values < 5_000,
        "the engine holds {} values after {} frames",
        report.retained_values,
        report.frames
    );
    assert!((report.captured_s - minutes * 60.0).abs() < 1e-6);
    assert!(peak < 50 * 1024, "peak RSS {peak} kB");
    if let Some(a) = at_2min {
        assert!(
            end < a + 4 * 1024,
            "RSS grew from {a} kB to {end} kB: {samples:?}"
        );
    }
}
