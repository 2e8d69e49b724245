//! Audio devices through cpal (feature `device`): capture for live input, playback fed by
//! the caller's samples, the audio clock, and the device listing. cpal's default host on
//! Linux is ALSA; with PulseAudio running, ALSA's `default` and `pulse` devices go through
//! the sound server.
//!
//! ## Capture ([`Capture`])
//! The input callback hands each block to [`crate::ring::CaptureWriter::write`]: stereo
//! kept, no allocation, no lock, no blocking. The engine thread drains the ring through
//! [`Capture::reader`].
//!
//! ## Output and the play clock ([`Playback`])
//! [`Playback::open`] returns the playback and its [`PlaybackFeed`]: the caller pushes the
//! song's samples at their own rate (the same decoded samples it feeds the engine, so a song
//! is decoded once); the feed resamples them to the device rate ([`StreamResampler`]), maps
//! them to the device's channels and pushes them into a ring of [`OUTPUT_RING_S`] = 0.5 s.
//! The output callback copies what the ring holds (silence on an underrun, counted) and
//! publishes, through a sequence lock of atomics, the callback time, the song frames written
//! before it, how many it wrote, and cpal's output latency for the block (`playback −
//! callback` instant). [`Playback::now_ms`] is the song time audible now:
//! `(written_before − pad) / rate + min(now − callback, written_now / rate) −
//! output_latency`, slew-limited to the wall clock's rate ± 5 %: it follows the device's
//! crystal, not the CPU's, over a song, but not the leaps and stalls of a sound server that
//! takes audio in bursts. When it is more than 40 ms ahead of the device (a sound server's
//! first burst) it waits instead. Before the first callback it is `None`.
//!
//! ## Latency
//! Capture adds the device period before the engine sees a sample; output adds nothing to
//! the frames (they are timed against the sound) but the song starts only after the ring is
//! prefilled and the device's first callback (about 1.5 s through PulseAudio).

use std::sync::atomic::{fence, AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use cpal::traits::{DeviceTrait, HostTrait, StreamTrait};
use cpal::{FromSample, Sample, SampleFormat, SizedSample};

use crate::resample::StreamResampler;

/// Seconds of audio the capture ring holds.
pub const CAPTURE_RING_S: f64 = 2.0;
/// Seconds of device audio the output ring holds (and is prefilled with).
pub const OUTPUT_RING_S: f64 = 0.5;
/// Largest rate difference between the play clock and the wall clock (see
/// [`Playback::now_ms`]).
const MAX_SLEW: f64 = 0.05;
/// A play clock this far ahead of the device's position stops until the sound catches up
/// (see [`Playback::now_ms`]); below it, it slews. Above a sound server's usual stalls
/// (10-30 ms through PulseAudio's ALSA plugin), far below its first burst.
const HOLD_MS: f64 = 40.0;

/// One step of the play clock: from `last` ms, `dt` ms of wall time later, towards the
/// device position `raw` ms. Runs at the wall clock's rate ± [`MAX_SLEW`], holds while it
/// is more than [`HOLD_MS`] ahead of `raw`, never goes back.
fn clock_step(last: f64, dt: f64, raw: f64) -> f64 {
    let predicted = last + dt;
    let ms = if raw < predicted - HOLD_MS {
        last
    } else {
        predicted + (raw - predicted).clamp(-MAX_SLEW * dt, MAX_SLEW * dt)
    };
    ms.max(last)
}

/// How long cpal's ALSA worker waits for the device before it checks the device's state
/// itself. PulseAudio's ALSA plugin sometimes wakes nobody after an underrun: with cpal's
/// usual 10 s the sound (and the play clock with it) then stopped for 9-10 s, several
/// times in a 3.5-minute song on a loaded machine (`benches/play_sync.py`); a timeout
/// with the device still running just polls again.
const POLL_TIMEOUT: Duration = Duration::from_millis(100);

/// Marks "not yet" in the time atomics.
const NONE: u64 = u64::MAX;

type Cause = Box<dyn std::error::Error + Send + Sync>;

/// Why a device could not be used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DeviceError {
    /// The host has no default device of this kind.
    #[error("no audio {what} device (no sound card or sound server; `tactus devices` lists what exists)")]
    NoDevice {
        /// "input" or "output".
        what: &'static str,
    },
    /// No device has this name.
    #[error("unknown {what} device {name:?}; available: {}", if available.is_empty() { "none".to_string() } else { available.join(", ") })]
    UnknownDevice {
        /// "input" or "output".
        what: &'static str,
        /// The name asked for.
        name: String,
        /// The names that exist.
        available: Vec<String>,
    },
    /// The device's sample format is one cpal cannot convert.
    #[error("{what} device {device}: unsupported sample format {format}")]
    Format {
        /// "input" or "output".
        what: &'static str,
        /// The device.
        device: String,
        /// cpal's name of the format.
        format: String,
    },
    /// The device refused a step (configuration, opening, starting).
    #[error("{what} device {device}: cannot {step}")]
    Device {
        /// "input" or "output".
        what: &'static str,
        /// The device.
        device: String,
        /// What failed: "read its configuration", "open", "start".
        step: &'static str,
        /// cpal's error.
        #[source]
        source: Cause,
    },
    /// A resampler to the device rate could not be built.
    #[error(transparent)]
    Resample(#[from] crate::resample::ResampleError),
}

/// `$build::<T>(args)` with `T` the device's sample type; an unsupported format returns
/// [`DeviceError::Format`] from the calling function.
macro_rules! by_format {
    ($format:expr, $what:expr, $label:expr, $build:ident($($arg:expr),*)) => {
        match $format {
            SampleFormat::F32 => $build::<f32>($($arg),*),
            SampleFormat::I16 => $build::<i16>($($arg),*),
            SampleFormat::I32 => $build::<i32>($($arg),*),
            SampleFormat::U16 => $build::<u16>($($arg),*),
            SampleFormat::U8 => $build::<u8>($($arg),*),
            SampleFormat::I8 => $build::<i8>($($arg),*),
            SampleFormat::F64 => $build::<f64>($($arg),*),
            other => {
                return Err(DeviceError::Format {
                    what: $what,
                    device: $label,
                    format: other.to_string(),
                })
            }
        }
    };
}

mod capture;

pub use capture::{Capture, CaptureRequest};

fn device_err(
    what: &'static str,
    device: &str,
    step: &'static str,
    e: impl std::error::Error + Send + Sync + 'static,
) -> DeviceError {
    DeviceError::Device {
        what,
        device: device.to_string(),
        step,
        source: Box::new(e),
    }
}

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

/// [`find_device`], with the device's id and its default configuration.
fn device_with_config(
    name: Option<&str>,
    input: bool,
) -> Result<(cpal::Device, String, cpal::SupportedStreamConfig), DeviceError> {
    let device = find_device(name, input)?;
    let label = device_id(&device);
    let (what, sc) = if input {
        ("input", device.default_input_config())
    } else {
        ("output", device.default_output_config())
    };
    let sc = sc.map_err(|e| device_err(what, &label, "read its configuration", e))?;
    Ok((device, label, sc))
}

/// Finds an input (`input`) or output device by name; `None` = the host's default.
fn find_device(name: Option<&str>, input: bool) -> Result<cpal::Device, DeviceError> {
    let host = cpal::default_host();
    let what = if input { "input" } else { "output" };
    let Some(name) = name else {
        let d = if input {
            host.default_input_device()
        } else {
            host.default_output_device()
        };
        return d.ok_or(DeviceError::NoDevice { what });
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
    Err(DeviceError::UnknownDevice {
        what,
        name: name.to_string(),
        available: devices.iter().map(device_id).collect(),
    })
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

/// Atomics shared with the output callback and the feed.
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
    /// Song frames the feed pushed in all; valid once `fed_all`.
    total: AtomicU64,
    fed_all: AtomicBool,
    /// The ring was full once (or the song ended): ready to start.
    prefilled: AtomicBool,
    feed_error: AtomicBool,
    /// Frames of silence before the song.
    pad: AtomicU64,
    /// The playback was dropped: the feed stops.
    closed: AtomicBool,
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
        Some(POLL_TIMEOUT),
    )
}

/// The feeding end of a [`Playback`]: the caller pushes the song's samples here at the
/// song's own rate; they are resampled to the device rate and mapped to its channels.
pub struct PlaybackFeed {
    ring: rtrb::Producer<f32>,
    shared: Arc<OutShared>,
    stop: Arc<AtomicBool>,
    rs: StreamResampler,
    channels: usize,
    out: Vec<Vec<f32>>,
    inter: Vec<f32>,
    total: u64,
    done: bool,
}

impl PlaybackFeed {
    /// Pushes interleaved device samples, waiting while the ring is full. False once the
    /// playback's stop flag is set (or the playback was dropped).
    fn push_all(&mut self, mut samples: &[f32]) -> bool {
        while !samples.is_empty() {
            let (_, rest) = self.ring.push_partial_slice(samples);
            samples = rest;
            if !samples.is_empty() {
                self.shared.prefilled.store(true, Ordering::Release);
                if self.stop.load(Ordering::Relaxed) || self.shared.closed.load(Ordering::Relaxed) {
                    return false;
                }
                std::thread::sleep(Duration::from_millis(2));
            }
        }
        true
    }

    fn push_out(&mut self) -> bool {
        let len = self.out[0].len().min(self.out[1].len());
        self.inter.clear();
        for (&l, &r) in self.out[0][..len].iter().zip(&self.out[1][..len]) {
            match self.channels {
                1 => self.inter.push(0.5 * (l + r)),
                c => {
                    self.inter.push(l);
                    self.inter.push(r);
                    self.inter.extend(std::iter::repeat_n(0.0, c - 2));
                }
            }
        }
        self.out[0].clear();
        self.out[1].clear();
        self.total += len as u64;
        let inter = std::mem::take(&mut self.inter);
        let ok = self.push_all(&inter);
        self.inter = inter;
        ok
    }

    /// Pushes one block of the song (planar stereo at the rate given to
    /// [`Playback::open`]), waiting while the ring is full. Returns false when the playback
    /// stopped: the caller stops feeding.
    pub fn push(&mut self, left: &[f32], right: &[f32]) -> bool {
        if self.done {
            return false;
        }
        self.rs.process(&[left, right], &mut self.out);
        self.push_out()
    }

    /// The song is complete: flushes the resampler and lets [`Playback::finished`] know
    /// the song's length.
    pub fn finish(&mut self) {
        if self.done {
            return;
        }
        self.rs.finish(&mut self.out);
        self.push_out();
        self.end(false);
    }

    /// Marks the feed as ended early because the song could not be decoded further.
    pub fn fail(&mut self) {
        self.shared.feed_error.store(true, Ordering::Relaxed);
        self.end(true);
    }

    fn end(&mut self, _failed: bool) {
        self.done = true;
        let pad = self.shared.pad.load(Ordering::Relaxed);
        self.shared.total.store(self.total + pad, Ordering::Relaxed);
        self.shared.fed_all.store(true, Ordering::Release);
        self.shared.prefilled.store(true, Ordering::Release);
    }
}

impl Drop for PlaybackFeed {
    fn drop(&mut self) {
        if !self.done {
            self.end(false);
        }
    }
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
    stop: Arc<AtomicBool>,
    rate: u32,
    device: String,
    last_ms: std::cell::Cell<f64>,
    /// When [`Playback::now_ms`] last ran (ns since `shared.base`).
    last_wall_ns: std::cell::Cell<Option<u64>>,
}

impl Playback {
    /// Opens the default output device for a song at `song_rate` Hz and returns it (paused)
    /// with its feed. Push the song into the feed (from any thread), wait for
    /// [`Playback::wait_prefilled`], then [`Playback::start`] the sound.
    ///
    /// `pad_ms` of silence precede the song (time 0 of [`Playback::now_ms`] is still the
    /// song's first sample), so frames due before the song starts go out on time. Setting
    /// `stop` makes the feed's [`PlaybackFeed::push`] return false.
    ///
    /// Errors: no output device, a sample format cpal cannot convert, the device refusing to
    /// open, or no resampler for the rate pair.
    pub fn open(
        song_rate: u32,
        pad_ms: u32,
        stop: Arc<AtomicBool>,
    ) -> Result<(Playback, PlaybackFeed), DeviceError> {
        const WHAT: &str = "output";
        let (device, label, sc) = device_with_config(None, false)?;
        let config = sc.config();
        let rate = config.sample_rate;
        let channels = usize::from(config.channels.max(1));
        let rs = StreamResampler::new(song_rate, rate, 2)?;
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
            closed: AtomicBool::new(false),
        });
        let s = shared.clone();
        let stream = by_format!(
            sc.sample_format(),
            WHAT,
            label,
            build_output(&device, config, consumer, s)
        )
        .map_err(|e| device_err(WHAT, &label, "open", e))?;
        let mut feed = PlaybackFeed {
            ring: producer,
            shared: shared.clone(),
            stop: stop.clone(),
            rs,
            channels,
            out: vec![Vec::new(), Vec::new()],
            inter: Vec::new(),
            total: 0,
            done: false,
        };
        let silence = vec![0.0; pad * channels];
        feed.push_all(&silence);
        Ok((
            Playback {
                stream,
                shared,
                stop,
                rate,
                device: label,
                last_ms: std::cell::Cell::new(f64::NEG_INFINITY),
                last_wall_ns: std::cell::Cell::new(None),
            },
            feed,
        ))
    }

    /// Waits (at most `timeout`, or until the stop flag) until the ring is full or the song
    /// is complete: the sound can start without an underrun.
    pub fn wait_prefilled(&self, timeout: Duration) {
        let t = Instant::now();
        while !self.shared.prefilled.load(Ordering::Acquire)
            && t.elapsed() < timeout
            && !self.stop.load(Ordering::Relaxed)
        {
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    /// Starts the sound.
    pub fn start(&self) -> Result<(), DeviceError> {
        self.stream
            .play()
            .map_err(|e| device_err("output", &self.device, "start", e))
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
        // The `pad` frames of silence before the song are not song time.
        let pad = self.shared.pad.load(Ordering::Relaxed) as f64;
        let pos = (s.start as f64 - pad) / rate + since.min(s.len as f64 / rate)
            - s.latency_ns as f64 / 1e9;
        let raw = pos * 1e3;
        // Slew-limited: the clock runs at the wall clock's rate ± MAX_SLEW and steers towards
        // the device position within that band. Sound servers accept audio in bursts (the
        // ALSA→PulseAudio plugin fills a large buffer, then stalls), so the raw position
        // leaps and stalls although the sound plays smoothly; frames timed on it would
        // arrive in bursts. Over a song the device's crystal still wins: any drift below
        // MAX_SLEW (5 %, far above real crystals' ±0.01 %) is followed.
        //
        // One exception: a clock more than HOLD_MS ahead of the device waits for it (runs
        // at rate 0). At the start a sound server takes a large first burst whose delay the
        // device does not report, so the first positions run ahead of the sound by up to a
        // second; slewing back at 5 % took 15-20 s, with every frame that early. Waiting
        // only delays frames (each carries the whole glove state), it never bunches them.
        //
        // The first reading is capped by the wall time since the first callback: the song
        // cannot be further along than that after its `pad` of silence, whatever the first
        // burst's positions say (they sent the first frames 0.9 s early). After the song's
        // last sample was written there is no position to follow: the clock runs on at the
        // wall clock's rate (otherwise it would stop at the end and frames due just after
        // it would never go).
        let ended = self.shared.fed_all.load(Ordering::Acquire)
            && s.start + s.len >= self.shared.total.load(Ordering::Relaxed);
        let ms = match self.last_wall_ns.get() {
            None => {
                let first = self.shared.first_cb_ns.load(Ordering::Relaxed);
                let since_first = now_ns.saturating_sub(first) as f64 / 1e6;
                raw.min(since_first - pad * 1e3 / rate)
            }
            Some(prev_ns) => {
                let dt = now_ns.saturating_sub(prev_ns) as f64 / 1e6;
                if ended {
                    self.last_ms.get() + dt
                } else {
                    clock_step(self.last_ms.get(), dt, raw)
                }
            }
        };
        let ms = ms.max(self.last_ms.get());
        self.last_wall_ns.set(Some(now_ns));
        self.last_ms.set(ms);
        Some(ms)
    }

    /// The song's length on the device, ms, once the feed has received all of it.
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
        self.shared.closed.store(true, Ordering::Relaxed);
        let _ = self.stream.pause();
    }
}

#[cfg(test)]
mod tests {
    use super::{clock_step, HOLD_MS, MAX_SLEW};

    /// Runs the clock every `dt` ms for `ms` ms against the device position `raw(t)`;
    /// returns (t, clock) pairs. The first reading is taken as it is, as in `now_ms`.
    fn run(ms: f64, dt: f64, raw: impl Fn(f64) -> f64) -> Vec<(f64, f64)> {
        let mut c = raw(0.0);
        let mut out = vec![(0.0, c)];
        let mut t = 0.0;
        while t < ms {
            t += dt;
            c = clock_step(c, dt, raw(t));
            out.push((t, c));
        }
        out
    }

    #[test]
    fn follows_a_steady_device_and_a_drifting_crystal() {
        for r in run(10_000.0, 5.0, |t| t) {
            assert!((r.1 - r.0).abs() < 1e-9, "{r:?}");
        }
        // A crystal 1 % fast (100 times a real one's error): caught within 2 s, then held.
        let v = run(10_000.0, 5.0, |t| 1.01 * t);
        for &(t, c) in v.iter().filter(|r| r.0 > 2_000.0) {
            assert!((c - 1.01 * t).abs() < 1.0, "at {t} ms: {c}");
        }
    }

    #[test]
    fn a_first_burst_is_waited_out_not_slewed() {
        // A sound server takes 800 ms at once and then plays; the device's position is
        // 800 ms ahead at first, flat until the sound reaches it, then true.
        let raw = |t: f64| if t < 800.0 { 800.0 } else { t };
        let v = run(20_000.0, 5.0, raw);
        // Never ahead of the sound by more than the first burst, and within HOLD_MS plus
        // one step of it once the device position is true; within 1 ms from 2 s on.
        for &(t, c) in &v {
            if t >= 800.0 {
                assert!(c - t <= HOLD_MS + 5.0 + 1e-9, "at {t} ms: {c}");
            }
            if t >= 2_000.0 {
                assert!((c - t).abs() < 1.0, "at {t} ms: {c}");
            }
        }
        // The slew alone would still be 700 ms ahead after 2 s (5 % of 2 s = 100 ms).
        let mut slewed = 800.0;
        for k in 1..=400 {
            let t = 5.0 * k as f64;
            let p = slewed + 5.0;
            slewed = p + (raw(t) - p).clamp(-MAX_SLEW * 5.0, MAX_SLEW * 5.0);
        }
        assert!(slewed - 2_000.0 > 650.0, "{slewed}");
    }

    #[test]
    fn short_stalls_and_leaps_are_smoothed() {
        // Every 200 ms the position stalls for 20 ms and then leaps back to the truth.
        let raw = |t: f64| {
            let ph = t % 200.0;
            if ph < 20.0 {
                t - ph
            } else {
                t
            }
        };
        let v = run(5_000.0, 1.0, raw);
        for w in v.windows(2) {
            let rate = (w[1].1 - w[0].1) / (w[1].0 - w[0].0);
            assert!(
                (1.0 - MAX_SLEW - 1e-9..=1.0 + MAX_SLEW + 1e-9).contains(&rate),
                "rate {rate} at {} ms",
                w[1].0
            );
            assert!((w[1].1 - w[1].0).abs() < 2.0, "{:?}", w[1]);
        }
    }

    #[test]
    fn never_goes_back() {
        let raw = |t: f64| if t < 1_000.0 { t } else { t - 500.0 };
        let v = run(3_000.0, 5.0, raw);
        for w in v.windows(2) {
            assert!(w[1].1 >= w[0].1);
        }
    }
}
