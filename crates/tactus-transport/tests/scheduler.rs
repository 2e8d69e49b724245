//! The one scheduler on a fake clock: every frame goes at `k·bin − lead` (sooner ones at
//! once), the end is held until the song's end, missing frames are skipped, a source error,
//! a stop and a stalled clock all end it with exactly one all-down, and a clock that has not
//! started yet (`-inf`, the audio clock before its first callback) holds the first frame back.

use std::cell::Cell;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use tactus_transport::{
    open_sink, schedule, Clock, FakeClock, Frame, FrameSource, ScheduleError, SinkHandle,
    SinkOptions, SinkSpec, Slot, Timing,
};

fn quiet_sink() -> SinkHandle {
    let opts = SinkOptions {
        keep_alive: None,
        ..SinkOptions::default()
    };
    open_sink(&SinkSpec::Null, &opts).unwrap()
}

fn frames(n: u8) -> Vec<Frame> {
    (0..n)
        .map(|i| Frame([i, 0, 0, 0, 0, 0, 0, 0, 0, 1]))
        .collect()
}

fn timing(bin_ms: u32, lead_ms: i64) -> Timing {
    Timing {
        bin_ms,
        lead_ms,
        stall: None,
    }
}

#[test]
fn every_frame_goes_at_its_time_on_a_fake_clock() {
    let sink = quiet_sink();
    let clock = FakeClock::new(0.0);
    let stop = AtomicBool::new(false);
    let f = frames(20);
    let mut seen = Vec::new();
    let r = schedule(
        &mut &f[..],
        &sink,
        &clock,
        &timing(25, 60),
        &stop,
        &mut |s| seen.push((s.frame_index, s.clock_ms, s.frames)),
    )
    .unwrap();
    let stats = sink.close();
    assert_eq!(
        (r.frames_sent, r.skipped, r.stopped),
        (20, 0, false),
        "{r:?}"
    );
    assert_eq!(stats.frames_sent + stats.dropped, 20, "{stats:?}");
    assert_eq!(stats.all_down_sent, 1);
    for (k, &(i, t, n)) in seen.iter().enumerate() {
        assert_eq!((i, n), (k, 20));
        // Due at 25k − 60 ms; the first three (due ≤ 0) at once.
        let due = (k as f64 * 25.0 - 60.0).max(0.0);
        assert!(t >= due && t < due + 0.02, "frame {k} at {t} ms, due {due}");
    }
    assert!(r.jitter_max_ms < 0.02, "{r:?}");
    // All-down when the song ends, lead early: 20·25 − 60 ms.
    assert!(r.end_ms >= 440.0 && r.end_ms < 440.02, "{}", r.end_ms);
}

/// Every other frame missing, then an end.
struct Gappy(usize);

impl FrameSource for Gappy {
    type Error = String;
    fn take(&mut self, k: usize, _stop: &AtomicBool) -> Result<Slot, String> {
        Ok(if k >= self.0 {
            Slot::End
        } else if k % 2 == 1 {
            Slot::Missing
        } else {
            Slot::Frame(Frame::DOWN)
        })
    }
}

#[test]
fn missing_frames_are_skipped_and_counted() {
    let sink = quiet_sink();
    let clock = FakeClock::new(0.0);
    let stop = AtomicBool::new(false);
    let mut indices = Vec::new();
    let r = schedule(
        &mut Gappy(9),
        &sink,
        &clock,
        &timing(10, 0),
        &stop,
        &mut |s| {
            indices.push(s.frame_index);
            assert_eq!(s.frames, 0, "the source does not know its length");
        },
    )
    .unwrap();
    sink.close();
    assert_eq!((r.frames_sent, r.skipped), (5, 4), "{r:?}");
    assert_eq!(indices, [0, 2, 4, 6, 8]);
    assert!(r.end_ms >= 90.0 && r.end_ms < 90.02, "{}", r.end_ms);
}

/// Fails at frame 3.
struct Failing;

impl FrameSource for Failing {
    type Error = &'static str;
    fn take(&mut self, k: usize, _stop: &AtomicBool) -> Result<Slot, &'static str> {
        if k == 3 {
            Err("renderer failed")
        } else {
            Ok(Slot::Frame(Frame([0xff; 10])))
        }
    }
}

#[test]
fn a_source_error_ends_with_all_down() {
    let sink = quiet_sink();
    let clock = FakeClock::new(0.0);
    let stop = AtomicBool::new(false);
    let e = schedule(
        &mut Failing,
        &sink,
        &clock,
        &timing(10, 0),
        &stop,
        &mut |_| {},
    )
    .unwrap_err();
    assert!(
        matches!(e, ScheduleError::Source("renderer failed")),
        "{e:?}"
    );
    let stats = sink.close();
    assert_eq!(stats.all_down_sent, 1, "{stats:?}");
}

#[test]
fn stop_ends_the_schedule_with_all_down() {
    let sink = quiet_sink();
    let clock = FakeClock::new(0.0);
    let stop = AtomicBool::new(false);
    let f = frames(50);
    let r = schedule(
        &mut &f[..],
        &sink,
        &clock,
        &timing(10, 0),
        &stop,
        &mut |s| {
            if s.frame_index == 7 {
                stop.store(true, Ordering::Relaxed);
            }
        },
    )
    .unwrap();
    let stats = sink.close();
    assert!(r.stopped);
    assert_eq!(r.frames_sent, 8);
    assert_eq!(stats.all_down_sent, 1, "{stats:?}");
}

/// Reads `-inf` for its first `pending` reads (an audio clock before its first callback), then
/// runs like a fake clock; counts the sleeps.
struct LateStart {
    pending: Cell<u32>,
    started: Cell<bool>,
    clock: FakeClock,
    sleeps: Cell<u32>,
}

impl Clock for LateStart {
    fn now_ms(&self) -> f64 {
        if self.pending.get() > 0 {
            self.pending.set(self.pending.get() - 1);
            return f64::NEG_INFINITY;
        }
        self.started.set(true);
        self.clock.now_ms()
    }
    fn sleep_ms(&self, ms: f64) {
        self.sleeps.set(self.sleeps.get() + 1);
        if self.started.get() {
            self.clock.sleep_ms(ms);
        } else {
            // Before the start: only short looks again.
            assert_eq!(ms, 2.0);
        }
    }
}

#[test]
fn nothing_goes_before_the_clock_starts() {
    let sink = quiet_sink();
    let clock = LateStart {
        pending: Cell::new(5),
        started: Cell::new(false),
        clock: FakeClock::new(0.0),
        sleeps: Cell::new(0),
    };
    let stop = AtomicBool::new(false);
    let f = frames(3);
    let mut first = None;
    let r = schedule(
        &mut &f[..],
        &sink,
        &clock,
        &timing(10, 50),
        &stop,
        &mut |s| {
            first.get_or_insert(s.clock_ms);
        },
    )
    .unwrap();
    sink.close();
    assert_eq!(r.frames_sent, 3);
    assert_eq!(first, Some(0.0), "the first frame waited for the clock");
    assert!(clock.sleeps.get() >= 5);
}

/// Never moves; sleeping really sleeps.
struct Frozen;

impl Clock for Frozen {
    fn now_ms(&self) -> f64 {
        0.0
    }
    fn sleep_ms(&self, ms: f64) {
        std::thread::sleep(Duration::from_secs_f64(ms / 1e3));
    }
}

#[test]
fn a_stalled_clock_ends_the_schedule() {
    let sink = quiet_sink();
    let stop = AtomicBool::new(false);
    let f = frames(10);
    let t = Timing {
        stall: Some(Duration::from_millis(60)),
        ..timing(10, 0)
    };
    // Frame 0 is due at 0 and goes; frame 1 never comes due.
    let e = schedule(&mut &f[..], &sink, &Frozen, &t, &stop, &mut |_| {}).unwrap_err();
    match e {
        ScheduleError::Stalled { seconds } => assert_eq!(seconds, 0.06),
        ScheduleError::Source(never) => match never {},
    }
    let stats = sink.close();
    assert_eq!(stats.all_down_sent, 1, "{stats:?}");
}
