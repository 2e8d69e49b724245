//! Audio I/O at the edge (cargo feature `audio`): cpal capture for `tactus live`, cpal
//! output and the audio-output clock for `tactus play`, and the audio part of
//! `tactus devices`. cpal's default host on Linux is ALSA; with PulseAudio running, ALSA's
//! `default` and `pulse` devices go through the sound server (README, "Live audio").
//!
//! ## Capture ([`Capture`])
//! The input callback runs on cpal's audio thread and must never allocate, lock or block. It
//! downmixes each interleaved frame to mono (the mean of its channels), converts it to `f32`
//! and pushes it into a preallocated single-producer single-consumer lock-free ring
//! ([`rtrb`], [`CAPTURE_RING_S`] = 2 s of audio). Samples that do not fit are dropped and
//! counted as *overruns*; the callback also keeps the block's peak (input level) and the
//! time and size of the first callback in atomics. The engine thread drains the ring with
//! [`Capture::read`].
//!
//! ## Output and the play clock ([`Playback`])
//! A feeder thread decodes the song (symphonia), resamples it to the device rate
//! ([`StreamResampler`]), maps it to the device's channels and pushes it into a ring of
//! [`OUTPUT_RING_S`] = 0.5 s, filled before the stream starts. The output callback copies
//! what the ring holds (silence on an underrun, counted) and publishes, through a sequence
//! lock of atomics, the callback time, the song frames written before it, how many it wrote,
//! and cpal's output latency for the block (`playback − callback` instant).
//! [`Playback::now_ms`] is the song time audible now:
//! `written_before / rate + min(now − callback, written_now / rate) − output_latency`.
//! The clock that frames follow is that position slew-limited to the wall clock's rate
//! ± 5 %: it follows the device's crystal, not the CPU's, over a song, but not the leaps and
//! stalls of a sound server that takes audio in bursts. Before the first callback it is
//! `None`.
//!
//! ## Latency
//! Capture adds the device period plus at most one engine poll (2 ms) before the engine sees
//! a sample; output adds nothing to the frames (they are timed against the sound) but the
//! song starts only after the ring is prefilled and the device's first callback (about
//! 1.5 s through PulseAudio).

use std::path::Path;
use std::sync::atomic::{fence, AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};
use cpal::traits::{DeviceTrait, HostTrait, StreamTrait};
use cpal::{FromSample, Sample, SampleFormat, SizedSample};
use tactus_engine::resample::StreamResampler;
use tactus_engine::source::AudioSource;

/// Seconds of mono audio the capture ring holds.
pub const CAPTURE_RING_S: f64 = 2.0;
/// Seconds of device audio the output ring holds (and is prefilled with).
pub const OUTPUT_RING_S: f64 = 0.5;
/// Largest rate difference between the play clock and the wall clock (see
/// [`Playback::now_ms`]).
const MAX_SLEW: f64 = 0.05;
/// Marks "not yet" in the time atomics.
const NONE: u64 = u64::MAX;

/// A device's name as `--input` accepts it: the host's id (`default`, `pulse`, `hw:0,0`).
fn device_id(d: &cpal::Device) -> String {
    match d.id() {
        Ok(id) => id.id().to_string(),
        Err(_) => d.to_string(),
    }
}

fn device_label(d: &cpal::Device) -> String {
    let id = device_id(d);
    match d.description() {
        Ok(desc) if desc.name() != id => format!("{id}  ({})", desc.name()),
        _ => id,
    }
}

/// Finds an input (`input`) or output device by name; `None` = the host's default.
fn find_device(name: Option<&str>, input: bool) -> Result<cpal::Device> {
    let host = cpal::default_host();
    let what = if input { "input" } else { "output" };
    let Some(name) = name else {
        let d = if input {
            host.default_input_device()
        } else {
            host.default_output_device()
        };
        return d.ok_or_else(|| {
            anyhow!("no audio {what} device (no sound card or sound server; `tactus devices` lists what exists)")
        });
    };
    let devices: Vec<cpal::Device> = if input {
        host.input_devices()
            .map(|d| d.collect())
            .unwrap_or_default()
    } else {
        host.output_devices()
            .map(|d| d.collect())
            .unwrap_or_default()
    };
    let matches = |d: &cpal::Device| {
        let id = device_id(d);
        id == name
            || d.id().is_ok_and(|full| full.to_string() == name)
            || d.description().is_ok_and(|desc| desc.name() == name)
    };
    if let Some(i) = devices.iter().position(matches) {
        return Ok(devices.into_iter().nth(i).expect("index from position"));
    }
    let names: Vec<String> = devices.iter().map(device_id).collect();
    if names.is_empty() {
        bail!("unknown {what} device {name:?}: no {what} devices found");
    }
    bail!(
        "unknown {what} device {name:?}; available: {}",
        names.join(", ")
    )
}

/// The "Audio devices" section of `tactus devices`.
pub fn devices_report() -> String {
    use std::fmt::Write as _;
    let host = cpal::default_host();
    let mut out = format!("Audio devices (cpal, host {}):\n", host.id().name());
    for input in [true, false] {
        let (label, list) = if input {
            (
                "inputs (--input NAME)",
                host.input_devices().map(|d| d.collect::<Vec<_>>()),
            )
        } else {
            (
                "outputs",
                host.output_devices().map(|d| d.collect::<Vec<_>>()),
            )
        };
        let default = if input {
            host.default_input_device()
        } else {
            host.default_output_device()
        }
        .map(|d| device_id(&d));
        let _ = writeln!(out, "  {label}:");
        match list {
            Ok(v) if v.is_empty() => out.push_str("    (none found)\n"),
            Ok(v) => {
                for d in v {
                    let id = device_id(&d);
                    let mark = if default.as_deref() == Some(id.as_str()) {
                        "  [default]"
                    } else {
                        ""
                    };
                    let _ = writeln!(out, "    {}{mark}", device_label(&d));
                }
            }
            Err(e) => {
                let _ = writeln!(out, "    (cannot list: {e})");
            }
        }
    }
    out
}

/// Atomics shared with the input callback.
struct CaptureShared {
    base: Instant,
    first_cb_ns: AtomicU64,
    first_cb_frames: AtomicU64,
    /// cpal's `callback − capture` for the latest block, ns.
    input_delay_ns: AtomicU64,
    callbacks: AtomicU64,
    frames: AtomicU64,
    overruns: AtomicU64,
    /// Peak |sample| since the last [`Capture::take_peak`], as `f32` bits (non-negative
    /// floats order like their bits, so `fetch_max` works).
    peak_bits: AtomicU32,
    error: AtomicBool,
}

/// What the live profile asks of the capture device (issue 13). Both are requests: a
/// device that cannot honour one keeps its default.
///
/// * `rate`: capture at the engine's rate where the device offers it, so no resampler
///   stands between the device and the engine (ours needs 40 ms of look-ahead for
///   48 → 44.1 kHz; PulseAudio's ALSA plugin converts with a few samples of delay).
/// * `period_frames`: the ALSA period. The default of PulseAudio's ALSA plugin is large
///   (the capture path alone measured about 350 ms with it, `benches/live_latency.py`); a
///   short period hands each block to the engine as soon as it exists.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CaptureRequest {
    /// Sample rate to ask for, Hz.
    pub rate: Option<u32>,
    /// Period (callback block) to ask for, frames.
    pub period_frames: Option<u32>,
}

impl CaptureRequest {
    /// The device configuration to open: the default one with the requested rate (where a
    /// supported range of the default sample format and channel count contains it) and the
    /// requested period (clamped to what the range supports).
    fn choose(
        &self,
        device: &cpal::Device,
        default: cpal::SupportedStreamConfig,
    ) -> (cpal::SupportedStreamConfig, cpal::StreamConfig) {
        let mut sc = default;
        if let (Some(rate), Ok(ranges)) = (self.rate, device.supported_input_configs()) {
            let fits = ranges
                .filter(|r| {
                    r.sample_format() == sc.sample_format() && r.channels() == sc.channels()
                })
                .find_map(|r| r.try_with_sample_rate(rate));
            if let Some(c) = fits {
                sc = c;
            }
        }
        let mut config = sc.config();
        if let Some(p) = self.period_frames {
            let p = match *sc.buffer_size() {
                cpal::SupportedBufferSize::Range { min, max } => p.clamp(min, max),
                cpal::SupportedBufferSize::Unknown => p,
            };
            config.buffer_size = cpal::BufferSize::Fixed(p);
        }
        (sc, config)
    }
}

/// A running capture stream; see the module docs.
pub struct Capture {
    _stream: cpal::Stream,
    ring: rtrb::Consumer<f32>,
    shared: Arc<CaptureShared>,
    rate: u32,
    channels: u16,
    device: String,
}

/// The input callback: downmix, push, count. No allocation, no lock, no blocking.
fn capture_callback<T>(
    ring: &mut rtrb::Producer<f32>,
    shared: &CaptureShared,
    channels: usize,
    data: &[T],
    info: &cpal::InputCallbackInfo,
) where
    T: Sample,
    f32: FromSample<T>,
{
    let frames = data.len() / channels;
    // Issue 13: the device's own buffering (cpal's `callback − capture`), kept for every
    // block so the report shows the steady state, not the start-up.
    let ts = info.timestamp();
    let delay = ts.callback.saturating_duration_since(ts.capture);
    shared
        .input_delay_ns
        .store(delay.as_nanos() as u64, Ordering::Relaxed);
    if shared.first_cb_ns.load(Ordering::Relaxed) == NONE {
        shared
            .first_cb_frames
            .store(frames as u64, Ordering::Relaxed);
        shared
            .first_cb_ns
            .store(shared.base.elapsed().as_nanos() as u64, Ordering::Release);
    }
    let inv = 1.0 / channels as f32;
    let mut peak = 0.0f32;
    let mut dropped = 0u64;
    for frame in data.chunks_exact(channels) {
        let mut sum = 0.0f32;
        for &x in frame {
            sum += x.to_sample::<f32>();
        }
        let m = sum * inv;
        let m = if m.is_finite() { m } else { 0.0 };
        peak = peak.max(m.abs());
        if ring.push(m).is_err() {
            dropped += 1;
        }
    }
    if dropped > 0 {
        shared.overruns.fetch_add(dropped, Ordering::Relaxed);
    }
    shared
        .peak_bits
        .fetch_max(peak.to_bits(), Ordering::Relaxed);
    shared.frames.fetch_add(frames as u64, Ordering::Relaxed);
    shared.callbacks.fetch_add(1, Ordering::Relaxed);
}

fn build_input<T>(
    device: &cpal::Device,
    config: cpal::StreamConfig,
    mut ring: rtrb::Producer<f32>,
    shared: Arc<CaptureShared>,
) -> Result<cpal::Stream, cpal::Error>
where
    T: SizedSample + Send + 'static,
    f32: FromSample<T>,
{
    let channels = usize::from(config.channels.max(1));
    let err_shared = shared.clone();
    device.build_input_stream::<T, _, _>(
        config,
        move |data: &[T], info: &cpal::InputCallbackInfo| {
            capture_callback(&mut ring, &shared, channels, data, info)
        },
        move |_e| err_shared.error.store(true, Ordering::Relaxed),
        Some(Duration::from_secs(10)),
    )
}

impl Capture {
    /// Opens `name` (`None`: the default input device) with its default configuration and
    /// starts capturing.
    ///
    /// Errors: no input device, an unknown name (the message lists the available ones), a
    /// sample format cpal cannot convert, or the device refusing to open.
    ///
    /// Issue 13: `req` asks for a rate and a period (the live profile, see
    /// [`CaptureRequest`]); what the device refuses falls back to its default.
    pub fn open_with(name: Option<&str>, req: &CaptureRequest) -> Result<Capture> {
        let device = find_device(name, true)?;
        let label = device_id(&device);
        let sc = device
            .default_input_config()
            .with_context(|| format!("input device {label}"))?;
        let (sc, config) = req.choose(&device, sc);
        let rate = config.sample_rate;
        let capacity = ((rate as f64 * CAPTURE_RING_S) as usize).max(4096);
        let (producer, consumer) = rtrb::RingBuffer::new(capacity);
        let shared = Arc::new(CaptureShared {
            base: Instant::now(),
            first_cb_ns: AtomicU64::new(NONE),
            first_cb_frames: AtomicU64::new(0),
            input_delay_ns: AtomicU64::new(0),
            callbacks: AtomicU64::new(0),
            frames: AtomicU64::new(0),
            overruns: AtomicU64::new(0),
            peak_bits: AtomicU32::new(0),
            error: AtomicBool::new(false),
        });
        let s = shared.clone();
        let stream = match sc.sample_format() {
            SampleFormat::F32 => build_input::<f32>(&device, config, producer, s),
            SampleFormat::I16 => build_input::<i16>(&device, config, producer, s),
            SampleFormat::I32 => build_input::<i32>(&device, config, producer, s),
            SampleFormat::U16 => build_input::<u16>(&device, config, producer, s),
            SampleFormat::U8 => build_input::<u8>(&device, config, producer, s),
            SampleFormat::I8 => build_input::<i8>(&device, config, producer, s),
            SampleFormat::F64 => build_input::<f64>(&device, config, producer, s),
            other => bail!("input device {label}: unsupported sample format {other}"),
        }
        .with_context(|| format!("input device {label}: cannot open"))?;
        stream
            .play()
            .with_context(|| format!("input device {label}: cannot start"))?;
        Ok(Capture {
            _stream: stream,
            ring: consumer,
            shared,
            rate,
            channels: config.channels,
            device: label,
        })
    }

    /// The device's sample rate, Hz.
    pub fn rate(&self) -> u32 {
        self.rate
    }

    /// The device's channel count (downmixed to mono).
    pub fn channels(&self) -> u16 {
        self.channels
    }

    /// The device's name.
    pub fn device(&self) -> &str {
        &self.device
    }

    /// Ring capacity in samples: [`Capture::read`] never returns more.
    pub fn capacity(&self) -> usize {
        self.ring.buffer().capacity()
    }

    /// Appends every captured mono sample waiting in the ring to `out`, up to `out`'s spare
    /// capacity (reserve [`Capture::capacity`] to never allocate). Returns the count.
    pub fn read(&mut self, out: &mut Vec<f32>) -> usize {
        let n = self
            .ring
            .slots()
            .min(out.capacity().saturating_sub(out.len()));
        match self.ring.read_chunk(n) {
            Ok(chunk) => {
                let (a, b) = chunk.as_slices();
                out.extend_from_slice(a);
                out.extend_from_slice(b);
                chunk.commit_all();
                n
            }
            Err(_) => 0,
        }
    }

    /// When the first callback ran and how many frames it brought.
    pub fn first_callback(&self) -> Option<(Instant, u64)> {
        let ns = self.shared.first_cb_ns.load(Ordering::Acquire);
        (ns != NONE).then(|| {
            (
                self.shared.base + Duration::from_nanos(ns),
                self.shared.first_cb_frames.load(Ordering::Relaxed),
            )
        })
    }

    /// cpal's `callback − capture` delay of the latest block, ms.
    pub fn input_delay_ms(&self) -> f64 {
        self.shared.input_delay_ns.load(Ordering::Relaxed) as f64 / 1e6
    }

    /// Samples dropped because the ring was full.
    pub fn overruns(&self) -> u64 {
        self.shared.overruns.load(Ordering::Relaxed)
    }

    /// Callbacks so far.
    pub fn callbacks(&self) -> u64 {
        self.shared.callbacks.load(Ordering::Relaxed)
    }

    /// Frames delivered by the device so far.
    pub fn frames(&self) -> u64 {
        self.shared.frames.load(Ordering::Relaxed)
    }

    /// Whether cpal reported a stream error.
    pub fn had_error(&self) -> bool {
        self.shared.error.load(Ordering::Relaxed)
    }

    /// Peak |sample| since the last call.
    pub fn take_peak(&self) -> f32 {
        f32::from_bits(self.shared.peak_bits.swap(0, Ordering::Relaxed))
    }
}

/// Atomics shared with the output callback and the feeder.
struct OutShared {
    base: Instant,
    /// Sequence lock over the four `cb_*` fields: odd while the callback writes them.
    seq: AtomicU64,
    cb_ns: AtomicU64,
    cb_start: AtomicU64,
    cb_len: AtomicU64,
    cb_latency_ns: AtomicU64,
    first_cb_ns: AtomicU64,
    /// Song frames written to the device so far.
    written: AtomicU64,
    underruns: AtomicU64,
    /// Song frames the feeder pushed in all; valid once `fed_all`.
    total: AtomicU64,
    fed_all: AtomicBool,
    /// The ring was full once (or the song ended): ready to start.
    prefilled: AtomicBool,
    feed_error: AtomicBool,
    /// Frames of silence before the song.
    pad: AtomicU64,
}

/// What the output callback published last.
#[derive(Debug, Clone, Copy)]
struct OutSnapshot {
    cb_ns: u64,
    start: u64,
    len: u64,
    latency_ns: u64,
}

impl OutShared {
    fn snapshot(&self) -> Option<OutSnapshot> {
        loop {
            let s1 = self.seq.load(Ordering::Acquire);
            if s1 & 1 == 1 {
                std::hint::spin_loop();
                continue;
            }
            let snap = OutSnapshot {
                cb_ns: self.cb_ns.load(Ordering::Relaxed),
                start: self.cb_start.load(Ordering::Relaxed),
                len: self.cb_len.load(Ordering::Relaxed),
                latency_ns: self.cb_latency_ns.load(Ordering::Relaxed),
            };
            fence(Ordering::Acquire);
            if self.seq.load(Ordering::Relaxed) == s1 {
                return (snap.cb_ns != NONE).then_some(snap);
            }
        }
    }
}

/// The output callback: copy from the ring, count, publish the clock. No allocation, no
/// lock, no blocking.
fn output_callback<T>(
    ring: &mut rtrb::Consumer<f32>,
    shared: &OutShared,
    channels: usize,
    data: &mut [T],
    info: &cpal::OutputCallbackInfo,
) where
    T: Sample + FromSample<f32>,
{
    let now_ns = shared.base.elapsed().as_nanos() as u64;
    let want = data.len() - data.len() % channels;
    let avail = ring.slots();
    let n = want.min(avail - avail % channels);
    if let Ok(chunk) = ring.read_chunk(n) {
        let (a, b) = chunk.as_slices();
        for (o, &x) in data.iter_mut().zip(a.iter().chain(b)) {
            *o = T::from_sample(x);
        }
        chunk.commit_all();
    }
    for o in &mut data[n..] {
        *o = T::EQUILIBRIUM;
    }
    if n < want && !shared.fed_all.load(Ordering::Acquire) {
        shared.underruns.fetch_add(1, Ordering::Relaxed);
    }
    let frames = (n / channels) as u64;
    let ts = info.timestamp();
    let latency = ts.playback.saturating_duration_since(ts.callback);
    let start = shared.written.load(Ordering::Relaxed);
    shared.seq.fetch_add(1, Ordering::Relaxed);
    fence(Ordering::Release);
    shared.cb_ns.store(now_ns, Ordering::Relaxed);
    shared.cb_start.store(start, Ordering::Relaxed);
    shared.cb_len.store(frames, Ordering::Relaxed);
    shared
        .cb_latency_ns
        .store(latency.as_nanos() as u64, Ordering::Relaxed);
    shared.seq.fetch_add(1, Ordering::Release);
    shared.written.store(start + frames, Ordering::Release);
    if shared.first_cb_ns.load(Ordering::Relaxed) == NONE {
        shared.first_cb_ns.store(now_ns, Ordering::Relaxed);
    }
}

fn build_output<T>(
    device: &cpal::Device,
    config: cpal::StreamConfig,
    mut ring: rtrb::Consumer<f32>,
    shared: Arc<OutShared>,
) -> Result<cpal::Stream, cpal::Error>
where
    T: SizedSample + FromSample<f32> + Send + 'static,
{
    let channels = usize::from(config.channels.max(1));
    device.build_output_stream::<T, _, _>(
        config,
        move |data: &mut [T], info: &cpal::OutputCallbackInfo| {
            output_callback(&mut ring, &shared, channels, data, info)
        },
        |_e| {},
        Some(Duration::from_secs(10)),
    )
}

/// Pushes all of `samples` into the ring, waiting while it is full. False if `stop` was set.
fn push_all(
    ring: &mut rtrb::Producer<f32>,
    mut samples: &[f32],
    shared: &OutShared,
    stop: &AtomicBool,
) -> bool {
    while !samples.is_empty() {
        let (_, rest) = ring.push_partial_slice(samples);
        samples = rest;
        if !samples.is_empty() {
            shared.prefilled.store(true, Ordering::Release);
            if stop.load(Ordering::Relaxed) {
                return false;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    true
}

/// The feeder thread: decode, resample to the device rate, map to its channels, push.
fn feed(
    mut source: AudioSource,
    rate: u32,
    channels: usize,
    pad: usize,
    mut ring: rtrb::Producer<f32>,
    shared: Arc<OutShared>,
    stop: Arc<AtomicBool>,
) {
    shared.pad.store(pad as u64, Ordering::Relaxed);
    if !push_all(&mut ring, &vec![0.0; pad * channels], &shared, &stop) {
        shared.fed_all.store(true, Ordering::Release);
        shared.prefilled.store(true, Ordering::Release);
        return;
    }
    let in_rate = source.info().sample_rate;
    let mut rs = match StreamResampler::new(in_rate, rate, 2) {
        Ok(r) => r,
        Err(_) => {
            shared.feed_error.store(true, Ordering::Relaxed);
            shared.fed_all.store(true, Ordering::Release);
            shared.prefilled.store(true, Ordering::Release);
            return;
        }
    };
    let (mut left, mut right) = (Vec::new(), Vec::new());
    let mut out = vec![Vec::new(), Vec::new()];
    let mut inter = Vec::new();
    let mut total = 0u64;
    loop {
        left.clear();
        right.clear();
        let n = match source.read_block(&mut left, &mut right) {
            Ok(n) => n,
            Err(_) => {
                shared.feed_error.store(true, Ordering::Relaxed);
                0
            }
        };
        out[0].clear();
        out[1].clear();
        if n == 0 {
            rs.finish(&mut out);
        } else {
            rs.process(&[&left, &right], &mut out);
        }
        let len = out[0].len().min(out[1].len());
        inter.clear();
        for (&l, &r) in out[0][..len].iter().zip(&out[1][..len]) {
            match channels {
                1 => inter.push(0.5 * (l + r)),
                _ => {
                    inter.push(l);
                    inter.push(r);
                    inter.extend(std::iter::repeat_n(0.0, channels - 2));
                }
            }
        }
        if !push_all(&mut ring, &inter, &shared, &stop) {
            break;
        }
        total += len as u64;
        if n == 0 {
            break;
        }
    }
    shared.total.store(total + pad as u64, Ordering::Relaxed);
    shared.fed_all.store(true, Ordering::Release);
    shared.prefilled.store(true, Ordering::Release);
}

/// Counters of a playback.
#[derive(Debug, Clone, Copy)]
pub struct PlaybackStats {
    /// Output callbacks that found the ring short before the song was fully decoded.
    pub underruns: u64,
    /// Output latency cpal reported for the last block, ms.
    pub latency_ms: f64,
    /// When the first output callback ran.
    pub first_callback: Option<Instant>,
}

/// A song playing on an output device; see the module docs.
pub struct Playback {
    stream: cpal::Stream,
    shared: Arc<OutShared>,
    feeder: Option<JoinHandle<()>>,
    stop: Arc<AtomicBool>,
    rate: u32,
    device: String,
    last_ms: std::cell::Cell<f64>,
    /// When [`Playback::now_ms`] last ran (ns since `shared.base`).
    last_wall_ns: std::cell::Cell<Option<u64>>,
}

impl Playback {
    /// Opens the default output device, starts decoding `song` into the output ring and
    /// waits until the ring is full. The sound starts with [`Playback::start`].
    ///
    /// Errors: no output device, the song cannot be opened, or the device refuses to open.
    ///
    /// `pad_ms` of silence precede the song (time 0 of [`Playback::now_ms`] is still the
    /// song's first sample), so frames due before the song starts go out on time.
    pub fn open(song: &Path, pad_ms: u32, stop: Arc<AtomicBool>) -> Result<Playback> {
        let device = find_device(None, false)?;
        let label = device_id(&device);
        let sc = device
            .default_output_config()
            .with_context(|| format!("output device {label}"))?;
        let config = sc.config();
        let rate = config.sample_rate;
        let channels = usize::from(config.channels.max(1));
        let source = AudioSource::open(song)?;
        let pad = (u64::from(rate) * u64::from(pad_ms) / 1000) as usize;
        let capacity = ((rate as f64 * OUTPUT_RING_S) as usize * channels).max(4096 * channels);
        let (producer, consumer) = rtrb::RingBuffer::new(capacity);
        let shared = Arc::new(OutShared {
            base: Instant::now(),
            seq: AtomicU64::new(0),
            cb_ns: AtomicU64::new(NONE),
            cb_start: AtomicU64::new(0),
            cb_len: AtomicU64::new(0),
            cb_latency_ns: AtomicU64::new(0),
            first_cb_ns: AtomicU64::new(NONE),
            written: AtomicU64::new(0),
            underruns: AtomicU64::new(0),
            total: AtomicU64::new(0),
            fed_all: AtomicBool::new(false),
            prefilled: AtomicBool::new(false),
            feed_error: AtomicBool::new(false),
            pad: AtomicU64::new(pad as u64),
        });
        let feed_stop = Arc::new(AtomicBool::new(false));
        let feeder = {
            let (s, fs) = (shared.clone(), feed_stop.clone());
            std::thread::Builder::new()
                .name("tactus-audio-feed".into())
                .spawn(move || feed(source, rate, channels, pad, producer, s, fs))
                .context("starting the audio feeder")?
        };
        let t = Instant::now();
        while !shared.prefilled.load(Ordering::Acquire) && t.elapsed() < Duration::from_secs(5) {
            if stop.load(Ordering::Relaxed) {
                break;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        let s = shared.clone();
        let stream = match sc.sample_format() {
            SampleFormat::F32 => build_output::<f32>(&device, config, consumer, s),
            SampleFormat::I16 => build_output::<i16>(&device, config, consumer, s),
            SampleFormat::I32 => build_output::<i32>(&device, config, consumer, s),
            SampleFormat::U16 => build_output::<u16>(&device, config, consumer, s),
            SampleFormat::U8 => build_output::<u8>(&device, config, consumer, s),
            SampleFormat::I8 => build_output::<i8>(&device, config, consumer, s),
            SampleFormat::F64 => build_output::<f64>(&device, config, consumer, s),
            other => {
                feed_stop.store(true, Ordering::Relaxed);
                bail!("output device {label}: unsupported sample format {other}")
            }
        };
        let stream = match stream {
            Ok(s) => s,
            Err(e) => {
                feed_stop.store(true, Ordering::Relaxed);
                return Err(anyhow!("output device {label}: cannot open: {e}"));
            }
        };
        Ok(Playback {
            stream,
            shared,
            feeder: Some(feeder),
            stop: feed_stop,
            rate,
            device: label,
            last_ms: std::cell::Cell::new(f64::NEG_INFINITY),
            last_wall_ns: std::cell::Cell::new(None),
        })
    }

    /// Starts the sound.
    pub fn start(&self) -> Result<()> {
        self.stream
            .play()
            .with_context(|| format!("output device {}: cannot start", self.device))
    }

    /// The output device's name.
    pub fn device(&self) -> &str {
        &self.device
    }

    /// The device's sample rate, Hz.
    pub fn rate(&self) -> u32 {
        self.rate
    }

    /// The song time audible now, ms (see the module docs); `None` before the first
    /// callback. Never decreases.
    pub fn now_ms(&self) -> Option<f64> {
        let s = self.shared.snapshot()?;
        let now_ns = self.shared.base.elapsed().as_nanos() as u64;
        let rate = f64::from(self.rate);
        let since = now_ns.saturating_sub(s.cb_ns) as f64 / 1e9;
        let pos =
            s.start as f64 / rate + since.min(s.len as f64 / rate) - s.latency_ns as f64 / 1e9;
        let raw = pos * 1e3;
        // Slew-limited: the clock runs at the wall clock's rate ± MAX_SLEW and steers towards
        // the device position within that band. Sound servers accept audio in bursts (the
        // ALSA→PulseAudio plugin fills a large buffer, then stalls), so the raw position
        // leaps and stalls although the sound plays smoothly; frames timed on it would
        // arrive in bursts. Over a song the device's crystal still wins: any drift below
        // MAX_SLEW (5 %, far above real crystals' ±0.01 %) is followed.
        let ms = match self.last_wall_ns.get() {
            None => raw,
            Some(prev_ns) => {
                let dt = now_ns.saturating_sub(prev_ns) as f64 / 1e6;
                let predicted = self.last_ms.get() + dt;
                predicted + (raw - predicted).clamp(-MAX_SLEW * dt, MAX_SLEW * dt)
            }
        };
        let ms = ms.max(self.last_ms.get());
        self.last_wall_ns.set(Some(now_ns));
        self.last_ms.set(ms);
        Some(ms)
    }

    /// The song's length on the device, ms, once the feeder has decoded all of it.
    pub fn duration_ms(&self) -> Option<f64> {
        self.shared.fed_all.load(Ordering::Acquire).then(|| {
            let song =
                self.shared.total.load(Ordering::Relaxed) - self.shared.pad.load(Ordering::Relaxed);
            song as f64 * 1e3 / f64::from(self.rate)
        })
    }

    /// Whether the whole song has been written to the device and its end is audible.
    pub fn finished(&self) -> bool {
        match (self.duration_ms(), self.now_ms()) {
            (Some(d), Some(t)) => {
                self.shared.written.load(Ordering::Acquire)
                    >= self.shared.total.load(Ordering::Relaxed)
                    && t >= d
            }
            _ => false,
        }
    }

    /// Whether decoding the song failed part-way.
    pub fn feed_failed(&self) -> bool {
        self.shared.feed_error.load(Ordering::Relaxed)
    }

    /// Counters so far.
    pub fn stats(&self) -> PlaybackStats {
        let first = self.shared.first_cb_ns.load(Ordering::Relaxed);
        PlaybackStats {
            underruns: self.shared.underruns.load(Ordering::Relaxed),
            latency_ms: self.shared.cb_latency_ns.load(Ordering::Relaxed) as f64 / 1e6,
            first_callback: (first != NONE).then(|| self.shared.base + Duration::from_nanos(first)),
        }
    }
}

impl Drop for Playback {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        let _ = self.stream.pause();
        if let Some(f) = self.feeder.take() {
            let _ = f.join();
        }
    }
}
