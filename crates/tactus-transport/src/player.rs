//! Clocked playback of a pattern's frames (`tactus play`).
//!
//! ## Algorithm
//! Frame `k` holds the pins for `[k·bin_ms, (k+1)·bin_ms)` of the song (pattern file v1).
//! To make a pin *reach* the finger when its sound plays, it must be commanded early by the
//! link latency plus the 50 ms pin rise (docs/design.md, "Latency"). So frame `k` is handed to the
//! sink at clock time `k·bin_ms − offset_ms`; [`lead_ms`] computes the usual `offset_ms`
//! (pin rise + the link's typical latency + the user's `--offset-ms`). Frames whose time is
//! already past when playback starts (the first ones, when `offset_ms > 0`) are sent at
//! once. After the last frame, all-down is sent at `n·bin_ms − offset_ms` (end of the song).
//!
//! The time base is a [`Clock`]: [`WallClock`] (monotonic, starts at construction, for
//! `--no-audio`), or one the caller implements on the audio output position so touch follows
//! the sound even if the audio device drifts.
//!
//! Stopping (Ctrl-C): the loop checks `stop` at least every 10 ms; on every exit path
//! (end, stop) it sends all-down.
//!
//! Jitter: for every frame, `actual − scheduled` (scheduled clamped at 0) is measured on the
//! clock right after the hand-off; [`PlayReport`] gives its max, p95 and mean. The hand-off
//! itself never blocks ([`crate::sink`]), so jitter is the sleep precision of the machine.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use tactus_glove::Frame;

use crate::sink::SinkHandle;
use crate::spec::SinkSpec;

/// A playback time base in ms.
pub trait Clock {
    /// Milliseconds since playback start (monotonic, non-decreasing).
    fn now_ms(&self) -> f64;
    /// Sleeps about `ms` (callers ask for at most 10 ms at a time).
    fn sleep_ms(&self, ms: f64) {
        std::thread::sleep(Duration::from_secs_f64(ms.max(0.0) / 1e3));
    }
}

/// The monotonic system clock; time 0 is its construction.
#[derive(Debug, Clone, Copy)]
pub struct WallClock {
    start: Instant,
}

impl WallClock {
    /// A clock starting now.
    pub fn new() -> WallClock {
        WallClock {
            start: Instant::now(),
        }
    }

    /// A clock whose time 0 is `start`.
    pub fn starting_at(start: Instant) -> WallClock {
        WallClock { start }
    }
}

impl Default for WallClock {
    fn default() -> WallClock {
        WallClock::new()
    }
}

impl Clock for WallClock {
    fn now_ms(&self) -> f64 {
        self.start.elapsed().as_secs_f64() * 1e3
    }
}

/// Progress, reported after each frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlayStatus {
    /// Index of the frame just sent.
    pub frame_index: usize,
    /// Frames in the pattern.
    pub frames: usize,
    /// Clock time of the hand-off, ms.
    pub clock_ms: f64,
    /// `actual − scheduled` for this frame, ms.
    pub late_ms: f64,
    /// Whether the sink's link is up.
    pub link_up: bool,
}

/// What a playback did.
#[derive(Debug, Clone, PartialEq)]
pub struct PlayReport {
    /// Frames handed to the sink.
    pub frames_sent: usize,
    /// Whether `stop` ended it early.
    pub stopped: bool,
    /// max |actual − scheduled| over the frames, ms.
    pub jitter_max_ms: f64,
    /// 95th percentile of |actual − scheduled|, ms (nearest rank).
    pub jitter_p95_ms: f64,
    /// Mean of |actual − scheduled|, ms.
    pub jitter_mean_ms: f64,
    /// `actual − scheduled` per frame sent, ms.
    pub late_ms: Vec<f64>,
    /// Clock time when all-down was sent, ms.
    pub end_ms: f64,
}

/// The usual `offset_ms` for [`play_frames`]: the 50 ms pin rise, plus the link's typical
/// latency (serial: 2 ms for 16 bytes at 115200 baud; BLE: 15 ms, one typical connection
/// interval; in-process sinks: 0), plus the user's `--offset-ms`.
pub fn lead_ms(spec: &SinkSpec, user_offset_ms: i64) -> i64 {
    let link = match spec {
        SinkSpec::Serial { baud, .. } => {
            // 16 bytes of 10 bits each, rounded up to whole ms.
            (160_000u64).div_ceil(u64::from(*baud)) as i64
        }
        SinkSpec::Ble(_) => 15,
        _ => 0,
    };
    i64::from(tactus_glove::PIN_RISE_MS) + link + user_offset_ms
}

/// Waits until `t_ms` on `clock`; false if `stop` was set first.
fn wait_until(clock: &dyn Clock, t_ms: f64, stop: &AtomicBool) -> bool {
    loop {
        if stop.load(Ordering::Relaxed) {
            return false;
        }
        let rem = t_ms - clock.now_ms();
        if rem <= 0.0 {
            return true;
        }
        clock.sleep_ms(rem.min(10.0));
    }
}

/// Plays `frames` (one per `bin_ms`) into `sink`, `offset_ms` early (see the module docs),
/// until the end or until `stop` is set. Always ends with all-down. `status` is called after
/// each frame. A `bin_ms` of 0 is treated as 1.
pub fn play_frames(
    frames: &[Frame],
    bin_ms: u32,
    sink: &SinkHandle,
    clock: &dyn Clock,
    offset_ms: i64,
    stop: &AtomicBool,
    status: &mut dyn FnMut(PlayStatus),
) -> PlayReport {
    let bin = f64::from(bin_ms.max(1));
    let offset = offset_ms as f64;
    let mut late = Vec::with_capacity(frames.len());
    let mut stopped = false;
    for (k, frame) in frames.iter().enumerate() {
        let scheduled = (k as f64 * bin - offset).max(0.0);
        if !wait_until(clock, scheduled, stop) {
            stopped = true;
            break;
        }
        let time_ms = (k as u64 * u64::from(bin_ms.max(1))).min(u64::from(u32::MAX)) as u32;
        sink.send_frame(*frame, time_ms);
        let now = clock.now_ms();
        late.push(now - scheduled);
        status(PlayStatus {
            frame_index: k,
            frames: frames.len(),
            clock_ms: now,
            late_ms: now - scheduled,
            link_up: sink.stats().link_up,
        });
    }
    if !stopped {
        let end = (frames.len() as f64 * bin - offset).max(0.0);
        stopped = !wait_until(clock, end, stop);
    }
    sink.all_down();
    let end_ms = clock.now_ms();

    let mut abs: Vec<f64> = late.iter().map(|x| x.abs()).collect();
    abs.sort_by(f64::total_cmp);
    let jitter_max_ms = abs.last().copied().unwrap_or(0.0);
    let jitter_p95_ms = if abs.is_empty() {
        0.0
    } else {
        // Nearest rank: the ceil(0.95 n)-th smallest value.
        abs[((abs.len() as f64 * 0.95).ceil() as usize).clamp(1, abs.len()) - 1]
    };
    let jitter_mean_ms = if abs.is_empty() {
        0.0
    } else {
        abs.iter().sum::<f64>() / abs.len() as f64
    };
    PlayReport {
        frames_sent: late.len(),
        stopped,
        jitter_max_ms,
        jitter_p95_ms,
        jitter_mean_ms,
        late_ms: late,
        end_ms,
    }
}
