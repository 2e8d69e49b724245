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
}

impl Default for LiveOptions {
    fn default() -> Self {
        LiveOptions {
            seconds: None,
            lead_ms: i64::from(tactus_glove::PIN_RISE_MS),
            first_sample_timeout: Duration::from_secs(10),
            status_every: Duration::from_millis(100),
        }
    }
}

/// Progress, reported every [`LiveOptions::status_every`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiveStatus {
    /// Seconds of audio captured.
    pub captured_s: f64,
    /// Frames sent.
    pub frames: usize,
    /// Frames the ring dropped (it was full).
    pub overruns: u64,
    /// Peak |sample| since the last status.
    pub peak: f32,
}

/// What a live session did.
#[derive(Debug, Clone, PartialEq)]
pub struct LiveReport {
    /// Seconds of audio captured.
    pub captured_s: f64,
    /// Frames sent to the sink.
    pub frames: usize,
    /// Callbacks the capture ran.
    pub callbacks: u64,
    /// Frames the ring dropped.
    pub overruns: u64,
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
        let bin_ms = eng.config().bin_ms;
        let mut rs = StreamResampler::new(rate, ENGINE_RATE, 2)?;
        // Everything the loop touches is allocated here.
        let cap = reader.capacity();
        let (mut left, mut right) = (Vec::with_capacity(cap), Vec::with_capacity(cap));
        let ratio = f64::from(ENGINE_RATE) / f64::from(rate);
        let out_cap = (cap as f64 * ratio) as usize + 4 * rs.latency_samples() + 8192;
        let mut out = vec![Vec::with_capacity(out_cap), Vec::with_capacity(out_cap)];
        let mut latencies: Vec<f64> = Vec::with_capacity(1 << 16);
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
                if let Some(l) = limit {
                    let keep = (l - captured).min(left.len() as u64) as usize;
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
                while delivered < ready {
                    sink.send_frame(
                        eng.live_frame(delivered),
                        (delivered as u64 * u64::from(bin_ms)) as u32,
                    );
                    if let Some((t0, n0)) = first {
                        // The bin's last sample, in device frames, was captured about
                        // (n − n0) / rate after the first callback (which brought n0 frames).
                        let end = (delivered + 1) as f64 * bin_samples / ratio;
                        let captured_at = (end - n0 as f64) / f64::from(rate);
                        if latencies.len() < latencies.capacity() {
                            latencies.push(t0.elapsed().as_secs_f64() * 1e3 - captured_at * 1e3);
                        }
                    }
                    delivered += 1;
                }
                // live_frame still reads the slower features' and the pulses' bins.
                eng.discard_before(delivered.saturating_sub(eng.live_history_bins()));
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
