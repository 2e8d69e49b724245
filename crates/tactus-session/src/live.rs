//! `live`: capture → engine → sink, as it plays.
//!
//! A capture ring's reading end ([`tactus_audio::ring::CaptureReader`], filled by a device
//! callback or by anything else that writes it) hands stereo samples to the calling thread,
//! which resamples them to 44.1 kHz ([`StreamResampler`]), feeds the streaming engine in
//! whatever blocks arrive, and sends each frame as soon as it is final. After sending, the
//! engine forgets the bins it sent ([`Engine::discard_before`]), so memory stays flat
//! however long the session runs.
//!
//! The session ends when `stop` is set, when `seconds` of audio have been captured, or when
//! the ring's writer is gone and the ring is empty (a file fed through the ring).
//!
//! Real-time hygiene (issue 13): the loop records how long it takes per 256-sample block
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
//! the capture clock is watched as well ([`ClockLag`]: wall time against audio received):
//! from a jump past the bound, and for as long as that lag keeps falling, every read is
//! dropped. Dropped
//! audio is counted ([`LiveReport::caught_up`]); frame times include it, so a frame's
//! `time_ms` stays the time of its audio. The engine sees a splice; a pin may rise there.
//! Frames the ring could not take (overruns) and device-side xruns are counted too; the
//! overruns also count in frame times and in the capture clock, like dropped audio (they
//! passed; leaving them out made every later frame look that much late).
//!
//! Latency: the device period, the resampler ([`StreamResampler::latency_samples`]), the
//! engine's look-ahead and the bin, then the link and the 50 ms pin rise; the report carries
//! the budget and the measured delay from the end of a bin's audio (as captured) to its
//! frame's send.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use tactus_audio::resample::StreamResampler;
use tactus_audio::ring::CaptureReader;
use tactus_engine::{Engine, EngineConfig, ENGINE_RATE};
use tactus_transport::SinkHandle;

use crate::SessionError;

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
    /// Issue 13: the budget per finger group, (group, [(stage, samples at the engine
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
        // Issue 13: real-time hygiene. Time per 256-sample block of the read -> process ->
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

/// The device's usual `callback − capture` delay: the smallest seen over the last one to
/// two buckets of [`DelayFloor::READS`] reads (about 2 s each at one read per 4 ms
/// capture period; counted in reads, not time, so that a stall does not age the floor
/// out). Its excess is audio that waited in the device (or sound server) longer than
/// usual: a backlog that the ring does not show. A device whose delay rises for good stops
/// counting as behind after two buckets, so a large but steady delay (a Bluetooth
/// microphone) never drops audio.
#[derive(Debug)]
struct DelayFloor {
    current: f64,
    previous: f64,
    reads: u32,
}

impl Default for DelayFloor {
    fn default() -> Self {
        DelayFloor {
            current: f64::INFINITY,
            previous: f64::INFINITY,
            reads: 0,
        }
    }
}

impl DelayFloor {
    const READS: u32 = 512;

    /// Records one read's `delay_ms`; returns how far it exceeds the floor, ms.
    fn excess(&mut self, delay_ms: f64) -> f64 {
        let d = if delay_ms.is_finite() {
            delay_ms.max(0.0)
        } else {
            0.0
        };
        self.current = self.current.min(d);
        let floor = self.current.min(self.previous);
        self.reads += 1;
        if self.reads >= Self::READS {
            (self.previous, self.current, self.reads) = (self.current, f64::INFINITY, 0);
        }
        d - floor
    }
}

/// How much later than usual the newest captured sample reaches this loop, by the capture
/// clock: wall time since the first callback minus the audio received since then, over its
/// floor ([`DelayFloor`], which also follows a slow drift between the two clocks). Unlike
/// the device's delay report, it sees audio that the sound server held back (PulseAudio's
/// ALSA plugin does not always count it), and so it catches a stalled process's burst on any
/// sound server.
///
/// A late sample is worth dropping only while the loop can win the lag back: while audio
/// arrives faster than real time and the lag falls. So [`ClockLag::update`] says "catch up"
/// from the read where the lag jumps past the bound (a stall: half the bound in one read)
/// and for as long as it keeps falling (by [`ClockLag::STEP_MS`], three capture periods, at
/// least once every [`ClockLag::HOLD_MS`]). A lag that crept up and stays (a starved sound
/// server handing audio over late at the pace it makes it, or samples lost in a device xrun)
/// is never dropped for: the floor takes it in after two buckets of reads.
#[derive(Debug, Default)]
struct ClockLag {
    floor: DelayFloor,
    /// The previous read's excess, ms.
    previous: f64,
    /// While over the bound: the lowest excess seen and when (wall ms), and whether a
    /// jump started it.
    low: Option<(f64, f64)>,
}

impl ClockLag {
    /// A fall that counts as winning the lag back, ms.
    const STEP_MS: f64 = 12.0;
    /// How long catching up goes on without such a fall, ms.
    const HOLD_MS: f64 = 200.0;

    /// One read: `wall_ms` since the first callback, `audio_ms` of audio received since
    /// then up to the newest sample, the bound `max_ms`. Returns the excess lag (ms) and
    /// whether to drop what this read brought.
    fn update(&mut self, wall_ms: f64, audio_ms: f64, max_ms: f64) -> (f64, bool) {
        let e = self.floor.excess(wall_ms - audio_ms);
        let previous = std::mem::replace(&mut self.previous, e);
        if e <= max_ms {
            self.low = None;
            return (e, false);
        }
        match &mut self.low {
            None => {
                // Past the bound: a jump catches up at once, a creep waits for a fall.
                let since = if e - previous > max_ms / 2.0 {
                    wall_ms
                } else {
                    wall_ms - Self::HOLD_MS - 1.0
                };
                self.low = Some((e, since));
            }
            Some((low, since)) => {
                if e < *low - Self::STEP_MS {
                    (*low, *since) = (e, wall_ms);
                }
            }
        }
        let (_, since) = self.low.expect("set above");
        (e, wall_ms - since <= Self::HOLD_MS)
    }
}

/// A histogram of durations on log-spaced buckets (10 per decade from 1 µs to 10 s), kept
/// in a fixed array: recording never allocates. Quantiles are read as a bucket's upper
/// edge, so they overstate by at most one bucket (26 %).
#[derive(Debug, Clone, PartialEq)]
pub struct BlockTimes {
    counts: [u64; BlockTimes::BUCKETS],
    max_us: f64,
    n: u64,
}

impl Default for BlockTimes {
    fn default() -> Self {
        BlockTimes {
            counts: [0; BlockTimes::BUCKETS],
            max_us: 0.0,
            n: 0,
        }
    }
}

impl BlockTimes {
    const BUCKETS: usize = 71;

    /// Upper edge of bucket `i`, µs: 10^(i/10).
    fn edge(i: usize) -> f64 {
        10f64.powf(i as f64 / 10.0)
    }

    /// Records one duration, µs.
    pub fn record(&mut self, us: f64) {
        let us = if us.is_finite() { us.max(0.0) } else { 0.0 };
        let i = if us <= 1.0 {
            0
        } else {
            ((us.log10() * 10.0).ceil() as usize).min(Self::BUCKETS - 1)
        };
        self.counts[i] += 1;
        self.n += 1;
        self.max_us = self.max_us.max(us);
    }

    /// How many durations were recorded.
    pub fn count(&self) -> u64 {
        self.n
    }

    /// The largest, µs.
    pub fn max_us(&self) -> f64 {
        self.max_us
    }

    /// The `q` quantile (0..=1), µs: the upper edge of the bucket holding it (never above
    /// the maximum); 0 when empty.
    pub fn quantile_us(&self, q: f64) -> f64 {
        if self.n == 0 {
            return 0.0;
        }
        let rank = ((self.n as f64 * q.clamp(0.0, 1.0)).ceil() as u64).max(1);
        let mut seen = 0;
        for (i, c) in self.counts.iter().enumerate() {
            seen += c;
            if seen >= rank {
                return Self::edge(i).min(self.max_us);
            }
        }
        self.max_us
    }

    /// Counts per range, for printing: (upper edge µs, count) of the non-empty buckets
    /// merged into the ranges ≤ 50 µs, 100, 200, 500 µs, 1, 2, 5, 10, 20, 50, 100 ms and
    /// above.
    pub fn ranges(&self) -> Vec<(f64, u64)> {
        const EDGES: [f64; 11] = [50.0, 100.0, 200.0, 500.0, 1e3, 2e3, 5e3, 1e4, 2e4, 5e4, 1e5];
        let mut out: Vec<(f64, u64)> = EDGES.iter().map(|&e| (e, 0)).collect();
        out.push((f64::INFINITY, 0));
        for (i, &c) in self.counts.iter().enumerate() {
            // Bucket i holds (edge(i-1), edge(i)]; its upper edge decides the range.
            let e = Self::edge(i);
            let k = EDGES
                .iter()
                .position(|&x| e <= x * (1.0 + 1e-9))
                .unwrap_or(EDGES.len());
            out[k].1 += c;
        }
        out
    }
}

/// `p50 158 us, p99 631 us, p99.9 3981 us, max 16057 us; histogram: <=100 us 1855, ...`:
/// the quantiles and the non-empty [`BlockTimes::ranges`], as `tactus live` prints them.
impl std::fmt::Display for BlockTimes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "p50 {:.0} us, p99 {:.0} us, p99.9 {:.0} us, max {:.0} us; histogram:",
            self.quantile_us(0.5),
            self.quantile_us(0.99),
            self.quantile_us(0.999),
            self.max_us()
        )?;
        let mut first = true;
        for (edge, n) in self.ranges().into_iter().filter(|r| r.1 > 0) {
            f.write_str(if first { " " } else { ", " })?;
            first = false;
            if !edge.is_finite() {
                write!(f, ">100 ms {n}")?;
            } else if edge < 1e3 {
                write!(f, "<={edge:.0} us {n}")?;
            } else {
                write!(f, "<={:.0} ms {n}", edge / 1e3)?;
            }
        }
        if first {
            f.write_str(" empty")?;
        }
        Ok(())
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
        let bin_ms = eng.config().bin_ms;
        let mut rs = StreamResampler::new(rate, ENGINE_RATE, 2)?;
        // Everything the loop touches is allocated here.
        let cap = reader.capacity();
        let (mut left, mut right) = (Vec::with_capacity(cap), Vec::with_capacity(cap));
        let ratio = f64::from(ENGINE_RATE) / f64::from(rate);
        let out_cap = (cap as f64 * ratio) as usize + 4 * rs.latency_samples() + 8192;
        let mut out = vec![Vec::with_capacity(out_cap), Vec::with_capacity(out_cap)];
        let mut latencies: Vec<f64> = Vec::with_capacity(1 << 16);
        let mut backlogs = BlockTimes::default();
        let mut block_times = BlockTimes::default();
        let (mut caught_up, mut skipped) = (0u64, 0u64);
        // Frames the ring had no room for (its overruns) are audio that passed too: they
        // count in frame times and in the capture clock like frames dropped to catch up,
        // or every later frame would look that much late (a 3 s stall's burst once filled
        // the ring for 66 ms, and every frame after it read 66 ms late).
        let mut lost = 0u64;
        let mut last_backlog_ms = 0.0;
        let mut last_latency: Option<f64> = None;
        let mut delay_floor = DelayFloor::default();
        let mut clock_lag = ClockLag::default();
        let max_backlog = opts
            .max_backlog
            .map(|d| ((d.as_secs_f64() * f64::from(rate)) as usize).max(1));
        let limit = opts.seconds.map(|s| (s.max(0.0) * f64::from(rate)) as u64);
        let bin_samples = eng.bin_samples() as f64;
        let (mut captured, mut delivered) = (0u64, 0usize);
        let t_open = Instant::now();
        let mut last_status = Instant::now();
        let mut peak = 0.0f32;
        let result: Result<(), SessionError> = loop {
            if stop.load(Ordering::Relaxed) {
                break Ok(());
            }
            left.clear();
            right.clear();
            if reader.read(&mut left, &mut right) == 0 {
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
                let t_block = Instant::now();
                // Overruns counted by now were frames the ring turned away while it was full
                // of this read's frames: they passed after this read's newest frame and
                // before the next read's oldest, and count from then on.
                let lost_now = reader.overruns().saturating_sub(lost);
                // The backlog: what waited in the ring (`read` drains it all) plus what
                // waited in the device beyond its usual delay (its buffer fills while this
                // process is stopped, then arrives in a burst).
                let mut excess_ms = delay_floor.excess(reader.input_delay_ms());
                let ring_ms = left.len() as f64 * 1e3 / f64::from(rate);
                // The capture clock's view of the same lag (see ClockLag).
                let mut clock_catch_up = false;
                if let (Some((t0, n0)), Some(max)) = (reader.first_callback(), max_backlog) {
                    let newest = (captured + left.len() as u64).saturating_sub(n0);
                    let (lag, catch_up) = clock_lag.update(
                        t0.elapsed().as_secs_f64() * 1e3,
                        newest as f64 * 1e3 / f64::from(rate),
                        max as f64 * 1e3 / f64::from(rate),
                    );
                    if catch_up {
                        excess_ms = excess_ms.max(lag);
                        clock_catch_up = true;
                    }
                }
                last_backlog_ms = ring_ms + excess_ms;
                backlogs.record(last_backlog_ms * 1e3);
                if let Some(max) = max_backlog {
                    let max_ms = max as f64 * 1e3 / f64::from(rate);
                    // The device's excess delay counts only with a burst in the ring (more
                    // than an eighth of the bound arrived at once): a steady rise of the
                    // device's delay is latency that reading faster cannot win back.
                    if ring_ms > max_ms
                        || clock_catch_up
                        || (ring_ms > max_ms / 8.0 && last_backlog_ms > max_ms)
                    {
                        // Fallen behind: keep only audio younger than a quarter of the
                        // bound (the newest sample is `excess_ms` older than usual).
                        let keep_ms = (max_ms / 4.0 - excess_ms).max(0.0);
                        let keep = ((keep_ms * f64::from(rate) / 1e3) as usize).min(left.len());
                        let drop = left.len() - keep;
                        if drop > 0 {
                            left.drain(..drop);
                            right.drain(..drop);
                            caught_up += 1;
                            skipped += drop as u64;
                            captured += drop as u64;
                        }
                    }
                }
                if let Some(l) = limit {
                    let keep = l.saturating_sub(captured).min(left.len() as u64) as usize;
                    left.truncate(keep);
                    right.truncate(keep);
                }
                captured += left.len() as u64;
                out[0].clear();
                out[1].clear();
                rs.process(&[&left, &right], &mut out);
                eng.process(&out[0], &out[1], &[]);
                if let Some(e) = eng.take_separator_error() {
                    break Err(e.into());
                }
                // Issue 13: each finger group goes out as soon as it is final
                // (Engine::live_frame): a pitch tracker's look-ahead no longer holds back
                // the rhythm pins.
                let ready = eng.live_ready_bins();
                let first = reader.first_callback();
                // Audio dropped to catch up counts in frame times and capture times (bins
                // finished just after a drop are placed as if they followed it).
                let skipped_ms = (skipped + lost) as f64 * 1e3 / f64::from(rate);
                while delivered < ready {
                    sink.send_frame(
                        eng.live_frame(delivered),
                        (delivered as f64 * f64::from(bin_ms) + skipped_ms) as u64 as u32,
                    );
                    if let Some((t0, n0)) = first {
                        // The bin's last sample, in device frames, was captured about
                        // (n − n0) / rate after the first callback (which brought n0 frames).
                        let end =
                            (delivered + 1) as f64 * bin_samples / ratio + (skipped + lost) as f64;
                        let captured_at = (end - n0 as f64) / f64::from(rate);
                        let lat = t0.elapsed().as_secs_f64() * 1e3 - captured_at * 1e3;
                        last_latency = Some(lat);
                        if latencies.len() < latencies.capacity() {
                            latencies.push(lat);
                        }
                    }
                    delivered += 1;
                }
                lost += lost_now;
                captured += lost_now;
                // live_frame still reads the slower features' and the pulses' bins.
                eng.discard_before(delivered.saturating_sub(eng.live_history_bins()));
                if !left.is_empty() {
                    // Per 256-sample block at the engine rate.
                    let blocks = left.len() as f64 * ratio / 256.0;
                    block_times.record(t_block.elapsed().as_secs_f64() * 1e6 / blocks);
                }
                if limit.is_some_and(|l| captured >= l) {
                    break Ok(());
                }
            }
            if last_status.elapsed() >= opts.status_every {
                last_status = Instant::now();
                peak = peak.max(reader.take_peak());
                status(&LiveStatus {
                    captured_s: captured as f64 / f64::from(rate),
                    frames: delivered,
                    overruns: reader.overruns(),
                    peak,
                    xruns: reader.xruns(),
                    backlog_ms: last_backlog_ms,
                    caught_up_s: skipped as f64 / f64::from(rate),
                    latency_ms: last_latency,
                });
                peak = 0.0;
            }
        };
        sink.all_down();
        result?;

        let ms = |n: usize, r: u32| n as f64 * 1e3 / f64::from(r);
        let mut budget = vec![(
            "resample to 44.1 kHz".to_string(),
            ms(rs.latency_samples(), ENGINE_RATE),
        )];
        budget.extend(eng.latency_budget());
        let rise = f64::from(tactus_glove::PIN_RISE_MS);
        budget.push(("link".into(), opts.lead_ms as f64 - rise));
        budget.push(("pin rise".into(), rise));
        let mut paths = eng.latency_paths();
        if rate != ENGINE_RATE {
            for (_, v) in &mut paths {
                v.insert(
                    0,
                    (
                        format!("resample {rate} -> {ENGINE_RATE} Hz"),
                        rs.latency_samples(),
                    ),
                );
            }
        }
        latencies.sort_by(f64::total_cmp);
        let measured_ms = (!latencies.is_empty()).then(|| {
            let p = |q: f64| {
                latencies
                    [((latencies.len() as f64 * q).ceil() as usize).clamp(1, latencies.len()) - 1]
            };
            (p(0.5), p(0.95), p(1.0))
        });
        let wall = reader
            .first_callback()
            .map(|(t, n0)| (t.elapsed().as_secs_f64(), n0))
            .unwrap_or((0.0, 0));
        Ok(LiveReport {
            captured_s: captured as f64 / f64::from(rate),
            frames: delivered,
            callbacks: reader.callbacks(),
            overruns: reader.overruns(),
            xruns: reader.xruns(),
            caught_up: (caught_up, skipped),
            backlog_ms: (
                backlogs.quantile_us(0.5) / 1e3,
                backlogs.quantile_us(0.99) / 1e3,
                backlogs.max_us() / 1e3,
                last_backlog_ms,
            ),
            block_times,
            capture_drift_ms: ((reader.frames().saturating_sub(wall.1)) as f64 / f64::from(rate)
                - wall.0)
                * 1e3,
            input_delay_ms: reader.input_delay_ms(),
            budget,
            paths,
            measured_ms,
            retained_values: eng.retained_values(),
        })
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The oracle: the nearest-rank quantile of the sorted values.
    fn exact(v: &mut [f64], q: f64) -> f64 {
        v.sort_by(f64::total_cmp);
        v[((v.len() as f64 * q).ceil() as usize).clamp(1, v.len()) - 1]
    }

    #[test]
    fn block_time_quantiles_are_within_one_bucket_of_the_sorted_values() {
        let mut seed = 7u32;
        let mut v = Vec::new();
        let mut h = BlockTimes::default();
        for _ in 0..20_000 {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            // Log-uniform from 10 us to 100 ms.
            let us = 10f64.powf(1.0 + 4.0 * f64::from(seed >> 8) / f64::from(1u32 << 24));
            v.push(us);
            h.record(us);
        }
        for q in [0.01, 0.5, 0.9, 0.99, 0.999, 1.0] {
            let want = exact(&mut v, q);
            let got = h.quantile_us(q);
            // An upper bucket edge: never below, at most one bucket (10^0.1) above.
            assert!(
                got >= want * (1.0 - 1e-9) && got <= want * 10f64.powf(0.1) * (1.0 + 1e-9),
                "q {q}: {got} for {want}"
            );
        }
        assert_eq!(h.count(), 20_000);
        assert_eq!(h.max_us(), v.iter().cloned().fold(0.0, f64::max));
        assert_eq!(h.ranges().iter().map(|r| r.1).sum::<u64>(), 20_000);
        // Each value lands in the first range whose edge is at least its bucket's edge.
        let mut one = BlockTimes::default();
        one.record(150.0);
        one.record(150_000.0);
        let r = one.ranges();
        assert_eq!(r.iter().find(|x| x.0 == 200.0).unwrap().1, 1);
        assert_eq!(r.last().unwrap(), &(f64::INFINITY, 1));
        assert_eq!(BlockTimes::default().quantile_us(0.5), 0.0);
        assert_eq!(
            one.to_string(),
            "p50 158 us, p99 150000 us, p99.9 150000 us, max 150000 us; histogram: \
             <=200 us 1, >100 ms 1"
        );
    }

    #[test]
    fn the_delay_floor_ignores_a_burst_and_follows_a_lasting_rise() {
        let mut f = DelayFloor::default();
        for _ in 0..100 {
            assert_eq!(f.excess(5.0), 0.0);
        }
        // A stall: the first block after it waited 3 s longer than usual.
        assert_eq!(f.excess(3005.0), 3000.0);
        assert_eq!(f.excess(5.0), 0.0);
        // A lasting rise to 250 ms counts as excess for at most two buckets of reads.
        let n = (0..3 * DelayFloor::READS)
            .filter(|_| f.excess(250.0) > 0.0)
            .count();
        assert!(n <= 2 * DelayFloor::READS as usize, "{n}");
        assert_eq!(f.excess(250.0), 0.0);
        assert_eq!(f.excess(f64::NAN), 0.0);
    }

    /// Per read: (excess, catch up).
    type Reads = Vec<(f64, bool)>;

    /// Reads every 4 ms of 4 ms of audio, the clock lag at 5 ms; then a 3 s stall whose
    /// audio arrives in a burst at `speed` times real time; then a lag that creeps up by
    /// 300 ms over 3 s and stays. Returns, per read, (excess, catch up).
    fn clock_lag_run(speed: f64) -> (Reads, Reads) {
        let mut c = ClockLag::default();
        let (mut wall, mut audio) = (5.0, 0.0);
        for _ in 0..200 {
            (wall, audio) = (wall + 4.0, audio + 4.0);
            assert_eq!(c.update(wall, audio, 200.0), (0.0, false));
        }
        // The stall, then the burst: each read brings 4 * speed ms until caught up.
        wall += 3000.0;
        let mut burst = Vec::new();
        while wall - audio > 5.0 + 1e-9 {
            (wall, audio) = (wall + 4.0, (audio + 4.0 * speed).min(wall + 4.0 - 5.0));
            burst.push(c.update(wall, audio, 200.0));
        }
        let mut creep = Vec::new();
        for i in 0..1500 {
            let extra = if i < 750 { 0.4 } else { 0.0 };
            (wall, audio) = (wall + 4.0, audio + 4.0 - extra);
            creep.push(c.update(wall, audio, 200.0));
        }
        (burst, creep)
    }

    #[test]
    fn the_clock_lag_catches_up_a_burst_at_any_speed_but_not_a_creep() {
        for speed in [1.5, 2.0, 5.0, 50.0] {
            let (burst, creep) = clock_lag_run(speed);
            // Every read of the burst whose audio is more than the bound late is dropped,
            // the first (the read right after the stall) included.
            for (i, &(e, drop)) in burst.iter().enumerate() {
                assert_eq!(drop, e > 200.0, "speed {speed}, read {i}: excess {e}");
            }
            assert!((burst[0].0 - (3004.0 - 4.0 * speed)).abs() < 1e-6 && burst[0].1);
            // The creep (0.4 ms per read up to 300 ms, then flat) is never dropped for,
            // though it passes the bound: reading faster cannot win it back.
            assert!(creep.iter().any(|x| x.0 > 250.0), "speed {speed}");
            assert!(creep.iter().all(|x| !x.1), "speed {speed}");
        }
        // Jitter of one capture period around a lag over the bound is no fall.
        let mut c = ClockLag::default();
        let mut wall = 0.0;
        for i in 0..300 {
            wall += 4.0;
            c.update(wall, wall - 5.0 - f64::from(i.min(60)) * 5.0, 200.0);
        }
        for i in 0..400 {
            wall += 4.0;
            let jitter = if i % 2 == 0 { 3.9 } else { 0.0 };
            let (_, drop) = c.update(wall, wall - 305.0 + jitter, 200.0);
            assert!(!drop, "read {i}");
        }
    }
}
