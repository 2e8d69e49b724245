//! `live`: capture → engine → sink, as it plays.
//!
//! A capture ring's reading end ([`tactus_audio::ring::CaptureReader`], filled by a device
//! callback or by anything else that writes it) hands stereo samples to the calling thread,
//! which resamples them to 44.1 kHz ([`tactus_audio::resample::StreamResampler`]), feeds the streaming engine in
//! whatever blocks arrive, and sends each frame as soon as it is final. After sending, the
//! engine forgets the bins it sent ([`Engine::discard_before`]), so memory stays flat
//! however long the session runs.
//!
//! The session ends when `stop` is set, when `seconds` of audio have been captured, or when
//! the ring's writer is gone and the ring is empty (a file fed through the ring).
//!
//! Real-time hygiene: the loop records how long it takes per 256-sample block
//! ([`BlockTimes`], printed at exit) and, at each read, the backlog: the audio that waited
//! in the ring plus how much longer than usual the newest block waited in the device (its
//! `callback − capture` delay over the smallest of the last few seconds: a stopped or starved
//! process finds seconds of audio queued in the sound server, which then arrive in one
//! burst). When the thread falls behind, whether starved of the CPU or slower than real
//! time, the backlog would grow until the ring overruns and then stay there, every frame
//! late by the ring's length. With [`LiveOptions::max_backlog`] set (the CLI sets
//! [`MAX_BACKLOG`]) it instead drops the oldest audio once more than that waits, keeping
//! only audio younger than a quarter of the bound, and goes on from there: frames resume
//! on time at once. The device's part counts only when a burst arrives with it (more than
//! an eighth of the bound, 25 ms, in the ring at once): a device delay that rises and stays up is
//! latency that no reading speed wins back, and dropping would only lose audio. Some sound
//! servers hand a stalled process's queue over in many small reads and do not count it in
//! the device delay (seen on CI's machine: 11 frames up to 1.6 s late after a 3 s stop), so
//! the capture clock is watched as well (`ClockLag`: wall time against audio received):
//! from a jump past the bound, and for as long as that lag keeps falling, every read is
//! dropped. Dropped
//! audio is counted ([`LiveReport::caught_up`]); frame times include it, so a frame's
//! `time_ms` stays the time of its audio. The engine sees a splice; a pin may rise there.
//! Frames the ring could not take (overruns) and device-side xruns are counted too; the
//! overruns also count in frame times and in the capture clock, like dropped audio (they
//! passed; leaving them out made every later frame look that much late).
//!
//! Latency: the device period, the resampler ([`tactus_audio::resample::StreamResampler::latency_samples`]), the
//! engine's look-ahead and the bin, then the link and the 50 ms pin rise; the report carries
//! the budget and the measured delay from the end of a bin's audio (as captured) to its
//! frame's send.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use tactus_audio::ring::CaptureReader;
use tactus_engine::{Engine, EngineConfig, ENGINE_RATE};
use tactus_transport::SinkHandle;

use crate::SessionError;

mod backlog;
mod block_times;
mod session_loop;

pub use block_times::BlockTimes;
use session_loop::LiveLoop;

/// The backlog at which `tactus live` drops audio to catch up ([`LiveOptions::max_backlog`]):
/// 200 ms. Audio that waited this long makes frames that arrive on the next beat (the issue's
/// "not live" figure was 288 ms) and far beyond the 40/80 ms targets, so showing it late is
/// worse than not showing it; a normal read finds one capture period (4–11 ms) and a
/// scheduling stall on a loaded machine measured up to about 150 ms, which stays below.
pub const MAX_BACKLOG: Duration = Duration::from_millis(200);

/// Where live audio comes from: a capture ring's reading end and what it carries.
pub struct LiveInput<'a> {
    /// The ring's reading end.
    pub reader: &'a mut CaptureReader,
    /// Its sample rate, Hz.
    pub rate: u32,
    /// A name for messages (the device).
    pub name: String,
}

/// How a live session runs.
#[derive(Debug, Clone, PartialEq)]
pub struct LiveOptions {
    /// Stop after this many seconds of captured audio (`None`: until `stop`).
    pub seconds: Option<f64>,
    /// The link's latency plus the pin rise, ms, for the budget ([`tactus_transport::lead_ms`]
    /// with no user offset).
    pub lead_ms: i64,
    /// How long to wait for the first sample before giving up.
    pub first_sample_timeout: Duration,
    /// How often `status` is called.
    pub status_every: Duration,
    /// Drop the oldest audio once more than this waits (in the ring, and in the device beyond
    /// its usual delay), keeping audio younger than a quarter of it (see the module docs;
    /// [`MAX_BACKLOG`] for a device). `None` (the default):
    /// process every sample however late, as for an input that is not real time (a file fed
    /// through the ring as fast as it is read).
    pub max_backlog: Option<Duration>,
}

impl Default for LiveOptions {
    fn default() -> Self {
        LiveOptions {
            seconds: None,
            lead_ms: i64::from(tactus_glove::PIN_RISE_MS),
            first_sample_timeout: Duration::from_secs(10),
            status_every: Duration::from_millis(100),
            max_backlog: None,
        }
    }
}

/// Progress, reported every [`LiveOptions::status_every`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiveStatus {
    /// Seconds of audio captured: processed, dropped to catch up, or turned away by a full
    /// ring.
    pub captured_s: f64,
    /// Frames sent.
    pub frames: usize,
    /// Frames the ring dropped (it was full).
    pub overruns: u64,
    /// Peak |sample| since the last status.
    pub peak: f32,
    /// Device-side overruns (xruns) so far.
    pub xruns: u64,
    /// The backlog at the latest read, ms: audio waiting in the ring plus the device's delay
    /// beyond its usual (see the module docs).
    pub backlog_ms: f64,
    /// Audio dropped to catch up so far, s.
    pub caught_up_s: f64,
    /// The latest frame's measured delay from the end of its bin's audio (as captured) to
    /// its send, ms.
    pub latency_ms: Option<f64>,
}

/// What a live session did.
#[derive(Debug, Clone, PartialEq)]
pub struct LiveReport {
    /// Seconds of audio captured: processed, dropped to catch up, or turned away by a full
    /// ring.
    pub captured_s: f64,
    /// Frames sent to the sink.
    pub frames: usize,
    /// Callbacks the capture ran.
    pub callbacks: u64,
    /// Frames the ring dropped.
    pub overruns: u64,
    /// Device-side overruns (xruns) the device reported.
    pub xruns: u64,
    /// Audio dropped to catch up (see the module docs): (times, device frames).
    pub caught_up: (u64, u64),
    /// The backlog at each read (see the module docs), ms: (median, p99, max) over the
    /// reads, and the last read's.
    pub backlog_ms: (f64, f64, f64, f64),
    /// Time per 256-sample block of the read → process → send loop (wall clock).
    pub block_times: BlockTimes,
    /// Capture clock minus wall clock since the first callback, ms.
    pub capture_drift_ms: f64,
    /// The device's `callback − capture` delay of the latest block, ms.
    pub input_delay_ms: f64,
    /// Latency budget, (stage, ms), in pipeline order.
    pub budget: Vec<(String, f64)>,
    /// The budget per finger group, (group, [(stage, samples at the engine
    /// rate)]), resampler first when there is one ([`Engine::latency_paths`]).
    pub paths: Vec<(String, Vec<(String, usize)>)>,
    /// Measured end of a bin's audio (as captured) to its frame's send, ms: (median, p95,
    /// max), when any frame was sent.
    pub measured_ms: Option<(f64, f64, f64)>,
    /// Per-hop and per-bin feature values the engine held at the end
    /// ([`Engine::retained_values`]): stays small however long the session ran.
    pub retained_values: usize,
}

impl LiveReport {
    /// The measured latency (when any frame was sent), the processing time per block and
    /// the backlog, one line each, as `tactus live` prints them; `rate` is the capture's.
    pub fn timing_text(&self, rate: u32) -> String {
        use std::fmt::Write;
        let mut t = String::new();
        if let Some((median, p95, max)) = self.measured_ms {
            let _ = writeln!(
                t,
                "measured bin end (captured) -> frame sent: median {median:.1} ms, p95 {p95:.1} ms, max {max:.1} ms"
            );
        }
        // Real-time hygiene: time per 256-sample block of the read -> process ->
        // send loop (wall clock: preemption included), the backlog, what was dropped to
        // catch up.
        let _ = writeln!(
            t,
            "processing per 256-sample block ({} reads): {}",
            self.block_times.count(),
            self.block_times
        );
        let (b50, b99, bmax, blast) = self.backlog_ms;
        let _ = writeln!(
            t,
            "backlog (audio waiting in the ring, and in the device beyond its usual delay): median {b50:.1} ms, p99 {b99:.1} ms, max {bmax:.1} ms, last {blast:.1} ms; caught up {} times, dropping {:.3} s of audio (backlog over {} ms); xruns {}",
            self.caught_up.0,
            self.caught_up.1 as f64 / f64::from(rate),
            MAX_BACKLOG.as_millis(),
            self.xruns
        );
        t
    }

    /// The latency budget per finger group as a table, one group after the other: each
    /// stage in samples at the engine rate and in ms, then the link, the total to the glove
    /// and the pin rise. `profile` names the latency profile in each heading.
    pub fn budget_text(&self, profile: &str) -> String {
        use std::fmt::Write;
        let ms = |n: usize| n as f64 * 1e3 / f64::from(ENGINE_RATE);
        let find = |name: &str| {
            self.budget
                .iter()
                .find(|(n, _)| n == name)
                .map_or(0.0, |(_, v)| *v)
        };
        let (link, rise) = (find("link"), find("pin rise"));
        let mut t = String::new();
        for (group, stages) in &self.paths {
            let _ = writeln!(
                t,
                "latency budget, {group} fingers ({profile} profile; after the capture period):"
            );
            let mut sum = 0.0;
            for (name, n) in stages {
                sum += ms(*n);
                let _ = writeln!(t, "    {name:<44} {n:>6} samples {:>7.1} ms", ms(*n));
            }
            for (name, v) in [
                ("link", link),
                ("total to the glove", sum + link),
                ("(then the pin rise)", rise),
            ] {
                let _ = writeln!(t, "    {name:<44} {:>14} {v:>7.1} ms", "");
            }
        }
        t
    }
}

/// A live pipeline, built before the input opens so that a bad configuration fails first.
pub struct LiveEngine {
    engine: Engine,
}

impl LiveEngine {
    /// Builds the engine for `config`.
    pub fn new(config: EngineConfig) -> Result<LiveEngine, SessionError> {
        Ok(LiveEngine {
            engine: Engine::new(config)?,
        })
    }

    /// Runs capture → engine → sink until `stop`, `opts.seconds` or the end of the input.
    /// `status` is called every `opts.status_every`. The sink gets all-down at the end; the
    /// caller closes it.
    ///
    /// Errors: a separator failure while running, no sample within
    /// `opts.first_sample_timeout`, a device error before the first sample.
    pub fn run(
        self,
        input: LiveInput<'_>,
        sink: &SinkHandle,
        opts: &LiveOptions,
        stop: &AtomicBool,
        status: &mut dyn FnMut(&LiveStatus),
    ) -> Result<LiveReport, SessionError> {
        let mut eng = self.engine;
        let LiveInput { reader, rate, name } = input;
        let mut l = LiveLoop::new(&eng, reader, rate, opts)?;
        let t_open = Instant::now();
        let mut last_status = Instant::now();
        let mut peak = 0.0f32;
        let result: Result<(), SessionError> = loop {
            if stop.load(Ordering::Relaxed) {
                break Ok(());
            }
            if l.read(reader) == 0 {
                if reader.is_abandoned() {
                    break Ok(());
                }
                if reader.first_callback().is_none() && t_open.elapsed() > opts.first_sample_timeout
                {
                    break Err(SessionError::NoAudio {
                        device: name.clone(),
                        seconds: opts.first_sample_timeout.as_secs_f64(),
                    });
                }
                if reader.had_error() && reader.first_callback().is_none() {
                    break Err(SessionError::DeviceFailed {
                        device: name.clone(),
                    });
                }
                std::thread::sleep(Duration::from_millis(2));
            } else {
                match l.step(&mut eng, reader, sink) {
                    Err(e) => break Err(e),
                    Ok(true) => break Ok(()),
                    Ok(false) => {}
                }
            }
            if last_status.elapsed() >= opts.status_every {
                last_status = Instant::now();
                peak = peak.max(reader.take_peak());
                status(&l.status(reader, peak));
                peak = 0.0;
            }
        };
        sink.all_down();
        result?;
        Ok(l.report(&eng, reader, opts))
    }
}

/// [`LiveEngine::new`] then [`LiveEngine::run`].
pub fn live(
    input: LiveInput<'_>,
    config: EngineConfig,
    sink: &SinkHandle,
    opts: &LiveOptions,
    stop: &AtomicBool,
    status: &mut dyn FnMut(&LiveStatus),
) -> Result<LiveReport, SessionError> {
    LiveEngine::new(config)?.run(input, sink, opts, stop, status)
}
