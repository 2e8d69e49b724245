//! The one clocked frame scheduler ([`schedule`]) and its pattern front end ([`play_frames`]).
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
//! The time base is a [`Clock`] ([`crate::clock`]): [`WallClock`](crate::WallClock)
//! (monotonic, starts at construction, for `--no-audio`), one the caller implements on the
//! audio output position so touch follows the sound even if the audio device drifts, or a
//! [`FakeClock`](crate::FakeClock) in tests. With [`Timing::stall`], a clock that stops moving
//! (a stalled audio device) ends the schedule.
//!
//! The frames come from a [`FrameSource`]: a pattern's frames, or a queue that a renderer
//! fills as the song plays; a frame the source does not have in time is skipped
//! ([`Slot::Missing`]), the next one carries the full state anyway.
//!
//! Stopping (Ctrl-C): the loop checks `stop` at least every 10 ms; on every exit path
//! (end, stop, stall, source error) it sends all-down.
//!
//! Jitter: for every frame, `actual − scheduled` (scheduled clamped at 0) is measured on the
//! clock right after the hand-off; [`PlayReport`] gives its max, p95 and mean. The hand-off
//! itself never blocks ([`crate::sink`]), so jitter is the sleep precision of the machine.

use std::convert::Infallible;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use tactus_glove::Frame;

use crate::clock::Clock;
use crate::sink::SinkHandle;
use crate::spec::SinkSpec;

/// Progress, reported after each frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlayStatus {
    /// Index of the frame just sent.
    pub frame_index: usize,
    /// Frames in the pattern (0 when the source does not know).
    pub frames: usize,
    /// Clock time of the hand-off, ms.
    pub clock_ms: f64,
    /// `actual − scheduled` for this frame, ms.
    pub late_ms: f64,
    /// Whether the sink's link is up.
    pub link_up: bool,
}

/// What a playback did.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PlayReport {
    /// Frames handed to the sink.
    pub frames_sent: usize,
    /// Frames the source did not have in time ([`Slot::Missing`]).
    pub skipped: usize,
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

/// What a [`FrameSource`] holds for frame `k` when its time comes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Slot {
    /// The frame to send.
    Frame(Frame),
    /// Not ready in time: skipped (the next frame carries the full state anyway).
    Missing,
    /// There are no more frames: the schedule ends (with all-down).
    End,
}

/// Where the scheduler takes frame `k` from when its time comes: a pattern's frames (a
/// slice), or a queue a renderer fills while the song plays (`tactus-session`).
pub trait FrameSource {
    /// What a source can fail with (a renderer's error).
    type Error;
    /// Frame `k` (asked for in increasing order, once each). A source may block for it, but
    /// must give up soon (within ~50 ms) once `stop` is set.
    fn take(&mut self, k: usize, stop: &AtomicBool) -> Result<Slot, Self::Error>;
    /// How many frames there are, if known (for [`PlayStatus::frames`]).
    fn len_hint(&self) -> Option<usize> {
        None
    }
}

impl FrameSource for &[Frame] {
    type Error = Infallible;
    fn take(&mut self, k: usize, _stop: &AtomicBool) -> Result<Slot, Infallible> {
        Ok(self.get(k).map_or(Slot::End, |f| Slot::Frame(*f)))
    }
    fn len_hint(&self) -> Option<usize> {
        Some(self.len())
    }
}

/// The timing of a [`schedule`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timing {
    /// One frame per `bin_ms` (0 is treated as 1).
    pub bin_ms: u32,
    /// Send each frame this much early, ms ([`lead_ms`]).
    pub lead_ms: i64,
    /// End with [`ScheduleError::Stalled`] when the clock reads the same for this long of
    /// wall time (a stalled audio device); `None`: never.
    pub stall: Option<Duration>,
}

/// Why a [`schedule`] ended early (all-down was sent).
#[derive(Debug)]
pub enum ScheduleError<E> {
    /// The clock stood still for [`Timing::stall`].
    Stalled {
        /// How long it stood still, s.
        seconds: f64,
    },
    /// The frame source failed.
    Source(E),
}

/// The one scheduler: frame `k` of `source` is handed to `sink` when `clock` reads
/// `k·bin_ms − lead_ms` (see the module docs), until the source ends or `stop` is set; then
/// all-down is sent (on every exit, errors included). `status` is called after each frame.
pub fn schedule<S: FrameSource + ?Sized>(
    source: &mut S,
    sink: &SinkHandle,
    clock: &dyn Clock,
    timing: &Timing,
    stop: &AtomicBool,
    status: &mut dyn FnMut(PlayStatus),
) -> Result<PlayReport, ScheduleError<S::Error>> {
    let bin_ms = timing.bin_ms.max(1);
    let (bin, lead) = (f64::from(bin_ms), timing.lead_ms as f64);
    let frames = source.len_hint();
    let mut late = Vec::with_capacity(frames.unwrap_or(0));
    let (mut skipped, mut stopped) = (0usize, false);
    // The clock's last reading, and the wall time when it last changed.
    let (mut last, mut moved) = (f64::NAN, Instant::now());
    for k in 0.. {
        let due = k as f64 * bin - lead;
        // Wait until `due`.
        loop {
            if stop.load(Ordering::Relaxed) {
                stopped = true;
                break;
            }
            let now = clock.now_ms();
            if now != last {
                (last, moved) = (now, Instant::now());
            } else if let Some(stall) = timing.stall.filter(|&s| moved.elapsed() > s) {
                sink.all_down();
                return Err(ScheduleError::Stalled {
                    seconds: stall.as_secs_f64(),
                });
            }
            if now >= due {
                break;
            }
            // Before the clock starts (`-inf`), look again soon.
            clock.sleep_ms(if now.is_finite() {
                (due - now).min(10.0)
            } else {
                2.0
            });
        }
        if stopped {
            break;
        }
        match source.take(k, stop) {
            Ok(Slot::Frame(frame)) => {
                let time_ms = (k as u64 * u64::from(bin_ms)).min(u64::from(u32::MAX)) as u32;
                sink.send_frame(frame, time_ms);
                let now = clock.now_ms();
                // Frames due before the start are measured from the start.
                let late_ms = now - due.max(0.0);
                late.push(late_ms);
                status(PlayStatus {
                    frame_index: k,
                    frames: frames.unwrap_or(0),
                    clock_ms: now,
                    late_ms,
                    link_up: sink.stats().link_up,
                });
            }
            Ok(Slot::Missing) => skipped += 1,
            Ok(Slot::End) => break,
            Err(e) => {
                sink.all_down();
                return Err(ScheduleError::Source(e));
            }
        }
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
    Ok(PlayReport {
        frames_sent: late.len(),
        skipped,
        stopped,
        jitter_max_ms,
        jitter_p95_ms,
        jitter_mean_ms,
        late_ms: late,
        end_ms,
    })
}

/// Plays `frames` (one per `bin_ms`) into `sink`, `offset_ms` early (see the module docs),
/// until the end or until `stop` is set: [`schedule`] on a pattern's frames, with no stall
/// watch. Always ends with all-down. `status` is called after each frame. A `bin_ms` of 0 is
/// treated as 1.
pub fn play_frames(
    frames: &[Frame],
    bin_ms: u32,
    sink: &SinkHandle,
    clock: &dyn Clock,
    offset_ms: i64,
    stop: &AtomicBool,
    status: &mut dyn FnMut(PlayStatus),
) -> PlayReport {
    let timing = Timing {
        bin_ms,
        lead_ms: offset_ms,
        stall: None,
    };
    match schedule(&mut { frames }, sink, clock, &timing, stop, status) {
        Ok(r) => r,
        Err(ScheduleError::Source(never)) => match never {},
        // No stall watch, so no stall.
        Err(ScheduleError::Stalled { .. }) => unreachable!("no stall watch"),
    }
}
