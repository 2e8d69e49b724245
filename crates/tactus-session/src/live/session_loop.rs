//! The read → process → send loop of [`super::LiveEngine::run`].

use std::time::Instant;

use tactus_audio::resample::StreamResampler;
use tactus_audio::ring::CaptureReader;
use tactus_engine::{Engine, ENGINE_RATE};
use tactus_transport::SinkHandle;

use super::backlog::{ClockLag, DelayFloor};
use super::{BlockTimes, LiveOptions, LiveReport, LiveStatus};
use crate::SessionError;

/// What the read → process → send loop of [`LiveEngine::run`] keeps between reads; every
/// buffer it touches is allocated in [`LiveLoop::new`].
pub(super) struct LiveLoop {
    /// The capture's rate, Hz.
    rate: u32,
    bin_ms: u32,
    rs: StreamResampler,
    /// This read's audio (device frames, stereo).
    left: Vec<f32>,
    right: Vec<f32>,
    /// The resampler's output.
    out: Vec<Vec<f32>>,
    /// Engine rate over capture rate.
    ratio: f64,
    latencies: Vec<f64>,
    backlogs: BlockTimes,
    block_times: BlockTimes,
    /// Times audio was dropped to catch up, and device frames dropped.
    caught_up: u64,
    skipped: u64,
    /// Frames the ring had no room for (its overruns) are audio that passed too: they
    /// count in frame times and in the capture clock like frames dropped to catch up,
    /// or every later frame would look that much late (a 3 s stall's burst once filled
    /// the ring for 66 ms, and every frame after it read 66 ms late).
    lost: u64,
    last_backlog_ms: f64,
    last_latency: Option<f64>,
    delay_floor: DelayFloor,
    clock_lag: ClockLag,
    /// [`LiveOptions::max_backlog`] in device frames.
    max_backlog: Option<usize>,
    /// [`LiveOptions::seconds`] in device frames.
    limit: Option<u64>,
    bin_samples: f64,
    captured: u64,
    delivered: usize,
}

impl LiveLoop {
    pub(super) fn new(
        eng: &Engine,
        reader: &CaptureReader,
        rate: u32,
        opts: &LiveOptions,
    ) -> Result<LiveLoop, SessionError> {
        let rs = StreamResampler::new(rate, ENGINE_RATE, 2)?;
        // Everything the loop touches is allocated here.
        let cap = reader.capacity();
        let ratio = f64::from(ENGINE_RATE) / f64::from(rate);
        let out_cap = (cap as f64 * ratio) as usize + 4 * rs.latency_samples() + 8192;
        Ok(LiveLoop {
            rate,
            bin_ms: eng.config().bin_ms,
            rs,
            left: Vec::with_capacity(cap),
            right: Vec::with_capacity(cap),
            out: vec![Vec::with_capacity(out_cap), Vec::with_capacity(out_cap)],
            ratio,
            latencies: Vec::with_capacity(1 << 16),
            backlogs: BlockTimes::default(),
            block_times: BlockTimes::default(),
            caught_up: 0,
            skipped: 0,
            lost: 0,
            last_backlog_ms: 0.0,
            last_latency: None,
            delay_floor: DelayFloor::default(),
            clock_lag: ClockLag::default(),
            max_backlog: opts
                .max_backlog
                .map(|d| ((d.as_secs_f64() * f64::from(rate)) as usize).max(1)),
            limit: opts.seconds.map(|s| (s.max(0.0) * f64::from(rate)) as u64),
            bin_samples: eng.bin_samples() as f64,
            captured: 0,
            delivered: 0,
        })
    }

    /// Reads what the ring holds into this read's buffers; returns how many frames came.
    pub(super) fn read(&mut self, reader: &mut CaptureReader) -> usize {
        self.left.clear();
        self.right.clear();
        reader.read(&mut self.left, &mut self.right)
    }

    /// The progress so far, with the input's `peak` since the last status.
    pub(super) fn status(&self, reader: &CaptureReader, peak: f32) -> LiveStatus {
        let rate = self.rate;
        LiveStatus {
            captured_s: self.captured as f64 / f64::from(rate),
            frames: self.delivered,
            overruns: reader.overruns(),
            peak,
            xruns: reader.xruns(),
            backlog_ms: self.last_backlog_ms,
            caught_up_s: self.skipped as f64 / f64::from(rate),
            latency_ms: self.last_latency,
        }
    }

    /// One read that brought audio (in `left` and `right`): the backlog and catching up,
    /// the engine, the frames now final. Returns whether the session is done
    /// ([`LiveOptions::seconds`] captured).
    pub(super) fn step(
        &mut self,
        eng: &mut Engine,
        reader: &CaptureReader,
        sink: &SinkHandle,
    ) -> Result<bool, SessionError> {
        let t_block = Instant::now();
        // Overruns counted by now were frames the ring turned away while it was full
        // of this read's frames: they passed after this read's newest frame and
        // before the next read's oldest, and count from then on.
        let lost_now = reader.overruns().saturating_sub(self.lost);
        self.catch_up(reader);
        if let Some(l) = self.limit {
            let keep = l.saturating_sub(self.captured).min(self.left.len() as u64) as usize;
            self.left.truncate(keep);
            self.right.truncate(keep);
        }
        self.captured += self.left.len() as u64;
        self.out[0].clear();
        self.out[1].clear();
        self.rs.process(&[&self.left, &self.right], &mut self.out);
        eng.process(&self.out[0], &self.out[1], &[]);
        if let Some(e) = eng.take_separator_error() {
            return Err(e.into());
        }
        self.send_ready(eng, reader, sink);
        self.lost += lost_now;
        self.captured += lost_now;
        // live_frame still reads the slower features' and the pulses' bins.
        eng.discard_before(self.delivered.saturating_sub(eng.live_history_bins()));
        if !self.left.is_empty() {
            // Per 256-sample block at the engine rate.
            let blocks = self.left.len() as f64 * self.ratio / 256.0;
            self.block_times
                .record(t_block.elapsed().as_secs_f64() * 1e6 / blocks);
        }
        Ok(self.limit.is_some_and(|l| self.captured >= l))
    }

    /// The backlog of this read (see the module docs), and with
    /// [`LiveOptions::max_backlog`] set, the oldest audio dropped once it is over.
    fn catch_up(&mut self, reader: &CaptureReader) {
        let rate = self.rate;
        let (left, right) = (&mut self.left, &mut self.right);
        // The backlog: what waited in the ring (`read` drains it all) plus what
        // waited in the device beyond its usual delay (its buffer fills while this
        // process is stopped, then arrives in a burst).
        let mut excess_ms = self.delay_floor.excess(reader.input_delay_ms());
        let ring_ms = left.len() as f64 * 1e3 / f64::from(rate);
        // The capture clock's view of the same lag (see ClockLag).
        let mut clock_catch_up = false;
        if let (Some((t0, n0)), Some(max)) = (reader.first_callback(), self.max_backlog) {
            let newest = (self.captured + left.len() as u64).saturating_sub(n0);
            let (lag, catch_up) = self.clock_lag.update(
                t0.elapsed().as_secs_f64() * 1e3,
                newest as f64 * 1e3 / f64::from(rate),
                max as f64 * 1e3 / f64::from(rate),
            );
            if catch_up {
                excess_ms = excess_ms.max(lag);
                clock_catch_up = true;
            }
        }
        self.last_backlog_ms = ring_ms + excess_ms;
        self.backlogs.record(self.last_backlog_ms * 1e3);
        if let Some(max) = self.max_backlog {
            let max_ms = max as f64 * 1e3 / f64::from(rate);
            // The device's excess delay counts only with a burst in the ring (more
            // than an eighth of the bound arrived at once): a steady rise of the
            // device's delay is latency that reading faster cannot win back.
            if ring_ms > max_ms
                || clock_catch_up
                || (ring_ms > max_ms / 8.0 && self.last_backlog_ms > max_ms)
            {
                // Fallen behind: keep only audio younger than a quarter of the
                // bound (the newest sample is `excess_ms` older than usual).
                let keep_ms = (max_ms / 4.0 - excess_ms).max(0.0);
                let keep = ((keep_ms * f64::from(rate) / 1e3) as usize).min(left.len());
                let drop = left.len() - keep;
                if drop > 0 {
                    left.drain(..drop);
                    right.drain(..drop);
                    self.caught_up += 1;
                    self.skipped += drop as u64;
                    self.captured += drop as u64;
                }
            }
        }
    }

    /// Sends every frame now final: each finger group goes out as soon as it is final
    /// ([`Engine::live_frame`]), so a pitch tracker's look-ahead does not hold back the
    /// rhythm pins; records each frame's delay from its bin's end as captured.
    fn send_ready(&mut self, eng: &Engine, reader: &CaptureReader, sink: &SinkHandle) {
        let rate = self.rate;
        let (skipped, lost) = (self.skipped, self.lost);
        let ready = eng.live_ready_bins();
        let first = reader.first_callback();
        // Audio dropped to catch up counts in frame times and capture times (bins
        // finished just after a drop are placed as if they followed it).
        let skipped_ms = (skipped + lost) as f64 * 1e3 / f64::from(rate);
        while self.delivered < ready {
            let delivered = self.delivered;
            sink.send_frame(
                eng.live_frame(delivered),
                (delivered as f64 * f64::from(self.bin_ms) + skipped_ms) as u64 as u32,
            );
            if let Some((t0, n0)) = first {
                // The bin's last sample, in device frames, was captured about
                // (n − n0) / rate after the first callback (which brought n0 frames).
                let end = (delivered + 1) as f64 * self.bin_samples / self.ratio
                    + (skipped + lost) as f64;
                let captured_at = (end - n0 as f64) / f64::from(rate);
                let lat = t0.elapsed().as_secs_f64() * 1e3 - captured_at * 1e3;
                self.last_latency = Some(lat);
                if self.latencies.len() < self.latencies.capacity() {
                    self.latencies.push(lat);
                }
            }
            self.delivered += 1;
        }
    }

    /// The session's report once the loop has ended.
    pub(super) fn report(
        mut self,
        eng: &Engine,
        reader: &CaptureReader,
        opts: &LiveOptions,
    ) -> LiveReport {
        let rate = self.rate;
        let rs = &self.rs;
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
        let latencies = &mut self.latencies;
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
        LiveReport {
            captured_s: self.captured as f64 / f64::from(rate),
            frames: self.delivered,
            callbacks: reader.callbacks(),
            overruns: reader.overruns(),
            xruns: reader.xruns(),
            caught_up: (self.caught_up, self.skipped),
            backlog_ms: (
                self.backlogs.quantile_us(0.5) / 1e3,
                self.backlogs.quantile_us(0.99) / 1e3,
                self.backlogs.max_us() / 1e3,
                self.last_backlog_ms,
            ),
            block_times: self.block_times,
            capture_drift_ms: ((reader.frames().saturating_sub(wall.1)) as f64 / f64::from(rate)
                - wall.0)
                * 1e3,
            input_delay_ms: reader.input_delay_ms(),
            budget,
            paths,
            measured_ms,
            retained_values: eng.retained_values(),
        }
    }
}
