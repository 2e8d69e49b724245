//! Real-time hygiene: when the processing thread falls behind the capture ring
//! (here: stalled for 800 ms inside its own status callback while a feeder writes the
//! ring at wall-clock pace, as a device would), `live` with
//! [`LiveOptions::max_backlog`] drops the oldest audio and goes on from the newest, so the
//! backlog does not persist; without it, every sample is processed however late.

mod common;

use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use tactus_audio::ring::{capture_ring, CaptureWriter};
use tactus_session::{live, LiveInput, LiveOptions, LiveReport, MAX_BACKLOG};
use tactus_transport::{open_sink, SinkOptions, SinkSpec};

const RATE: u32 = 48_000;
const SECONDS: f64 = 4.0;
const STALL: Duration = Duration::from_millis(800);

/// Writes `SECONDS` of the synthetic song in 10 ms blocks on a wall-clock schedule.
fn realtime_feed(mut w: CaptureWriter) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let block = RATE as u64 / 100;
        let blocks = (SECONDS * 100.0) as u64;
        let t0 = Instant::now();
        let mut buf = vec![0.0f32; 2 * block as usize];
        for b in 0..blocks {
            let due = t0 + Duration::from_millis(10 * b);
            if let Some(d) = due.checked_duration_since(Instant::now()) {
                std::thread::sleep(d);
            }
            for j in 0..block {
                let (l, r) = common::frame(b * block + j, RATE);
                buf[2 * j as usize] = l;
                buf[2 * j as usize + 1] = r;
            }
            w.write(&buf, 2, |x| x, Duration::ZERO);
        }
    })
}

/// One session with a stall of `STALL` once 1 s has been captured; the report and the
/// (wall time, backlog ms) of every status.
fn run(max_backlog: Option<Duration>) -> (LiveReport, Vec<(f64, f64)>) {
    // A 4 s ring: it never overruns here, so only the policy decides what is dropped.
    run_with_ring(max_backlog, RATE as usize * 4)
}

/// [`run`] with a ring of `ring_frames`.
fn run_with_ring(
    max_backlog: Option<Duration>,
    ring_frames: usize,
) -> (LiveReport, Vec<(f64, f64)>) {
    let (w, mut reader) = capture_ring(ring_frames);
    let feeder = realtime_feed(w);
    let sink = open_sink(&SinkSpec::Null, &SinkOptions::default()).unwrap();
    let stop = AtomicBool::new(false);
    let opts = LiveOptions {
        max_backlog,
        status_every: Duration::from_millis(20),
        ..LiveOptions::default()
    };
    let t0 = Instant::now();
    let mut stalled = false;
    let mut seen = Vec::new();
    let report = live(
        LiveInput {
            reader: &mut reader,
            rate: RATE,
            name: "synthetic, real time".into(),
        },
        common::live_config(),
        &sink,
        &opts,
        &stop,
        &mut |s| {
            seen.push((t0.elapsed().as_secs_f64(), s.backlog_ms));
            if !stalled && s.captured_s >= 1.0 {
                stalled = true;
                std::thread::sleep(STALL);
            }
        },
    )
    .unwrap();
    feeder.join().unwrap();
    sink.close();
    (report, seen)
}

#[test]
fn a_stalled_thread_drops_audio_to_catch_up_and_the_backlog_does_not_persist() {
    let (r, seen) = run(Some(MAX_BACKLOG));
    eprintln!("{:?} {:?} {:?}", r.caught_up, r.backlog_ms, r.measured_ms);
    assert_eq!(r.overruns, 0);
    assert!(r.caught_up.0 >= 1, "{r:?}");
    // What waited after the stall (800 ms and the reads around it), less the newest
    // quarter of the 200 ms bound that is kept.
    let skipped_s = r.caught_up.1 as f64 / f64::from(RATE);
    assert!(
        (0.65..=1.2).contains(&skipped_s),
        "dropped {skipped_s:.3} s after an 0.8 s stall"
    );
    // Everything the feeder wrote was captured (processed or dropped).
    assert!((r.captured_s - SECONDS).abs() < 1e-9, "{r:?}");
    // The largest backlog seen was the stall; the last read's is one feeder block or so.
    assert!(r.backlog_ms.2 >= 700.0, "{:?}", r.backlog_ms);
    assert!(r.backlog_ms.3 < 100.0, "{:?}", r.backlog_ms);
    // Half a second after the stall, no status saw more than the bound waiting.
    let end_of_stall = seen
        .iter()
        .find(|(_, b)| *b >= 700.0)
        .map(|(t, _)| *t)
        .expect("the stall's backlog was seen");
    let after: Vec<f64> = seen
        .iter()
        .filter(|(t, _)| *t > end_of_stall + 0.5)
        .map(|(_, b)| *b)
        .collect();
    assert!(!after.is_empty());
    assert!(
        after.iter().all(|&b| b <= MAX_BACKLOG.as_secs_f64() * 1e3),
        "{after:?}"
    );
    assert!(r.block_times.count() > 100);
    // No frame went out as late as the stall: they resumed from the newest audio.
    assert!(r.measured_ms.unwrap().2 < 500.0, "{:?}", r.measured_ms);
}

#[test]
fn without_a_bound_every_sample_is_processed_however_late() {
    let (r, _) = run(None);
    assert_eq!(r.caught_up, (0, 0));
    assert_eq!(r.overruns, 0);
    assert!(r.backlog_ms.2 >= 700.0, "{:?}", r.backlog_ms);
    // Every frame of the 4 s was made: the stall's frames went out late instead.
    let (_, p95, max) = r.measured_ms.unwrap();
    assert!(max >= 700.0, "{:?}", r.measured_ms);
    assert!(p95 < max);
}

#[test]
fn audio_the_full_ring_turned_away_still_counts_in_frame_times() {
    // A 300 ms ring and an 800 ms stall without a bound: the ring fills, about 0.5 s of
    // audio is lost before it, and the reads go on from the newest. The lost audio passed
    // all the same: the capture count and the frames' capture times include it, so the
    // frames after the stall are measured as on time, not 0.5 s late for ever (a CI run
    // once read every frame after a 3 s stall 66 ms late for this reason).
    let (r, _) = run_with_ring(None, RATE as usize * 3 / 10);
    eprintln!("{:?} {:?} {:?}", r.overruns, r.caught_up, r.measured_ms);
    let lost_s = r.overruns as f64 / f64::from(RATE);
    assert!(lost_s >= 0.3, "{r:?}");
    assert_eq!(r.caught_up, (0, 0));
    // Everything the feeder wrote passed: processed, or lost in the ring.
    assert!((r.captured_s - SECONDS).abs() < 1e-9, "{r:?}");
    // Three quarters of the frames come after the stall; measured without the lost audio
    // each of them would read at least `lost_s` late.
    let (median, _, max) = r.measured_ms.unwrap();
    assert!(
        median < 150.0,
        "{:?} with {lost_s:.3} s lost",
        r.measured_ms
    );
    assert!(max >= 300.0, "{:?}", r.measured_ms);
}
