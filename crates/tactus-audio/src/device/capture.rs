//! Capture for live input ([`Capture`]): the device's stream, at the rate and period the live
//! profile asks for where the device offers them ([`CaptureRequest`]), writing each block into
//! the capture ring ([`crate::ring`]) from the callback.

use cpal::traits::{DeviceTrait, StreamTrait};
use cpal::{FromSample, SampleFormat, SizedSample};

use super::{device_err, device_with_config, DeviceError, CAPTURE_RING_S, POLL_TIMEOUT};
use crate::ring::{capture_ring, CaptureReader, CaptureWriter};

/// A running capture stream; see the module docs.
pub struct Capture {
    _stream: cpal::Stream,
    reader: CaptureReader,
    rate: u32,
    channels: u16,
    device: String,
}

fn build_input<T>(
    device: &cpal::Device,
    config: cpal::StreamConfig,
    mut writer: CaptureWriter,
) -> Result<cpal::Stream, cpal::Error>
where
    T: SizedSample + Send + 'static,
    f32: FromSample<T>,
{
    let channels = usize::from(config.channels.max(1));
    let on_error = writer.error_flag();
    let on_xrun = writer.xrun_counter();
    device.build_input_stream::<T, _, _>(
        config,
        move |data: &[T], info: &cpal::InputCallbackInfo| {
            let ts = info.timestamp();
            let delay = ts.callback.saturating_duration_since(ts.capture);
            writer.write(data, channels, |x: T| x.to_sample::<f32>(), delay)
        },
        // An xrun (the device's buffer overflowed while nobody read it) is
        // counted, not an error: cpal recovers the stream and capture goes on.
        move |e: cpal::Error| {
            if e.kind() == cpal::ErrorKind::Xrun {
                on_xrun()
            } else {
                on_error()
            }
        },
        Some(POLL_TIMEOUT),
    )
}

/// What the live profile asks of the capture device
/// (`docs/decisions/0006-live-latency-profile.md`). Both are requests: a device that cannot
/// honour one keeps its default.
///
/// * `rate`: capture at the engine's rate where the device offers it, so no resampler
///   stands between the device and the engine (ours needs 40 ms of look-ahead for
///   48 → 44.1 kHz; PulseAudio's ALSA plugin converts with a few samples of delay).
/// * `period_frames`: the ALSA period: a short one hands each block to the engine as soon
///   as it exists (PulseAudio's default gave 512 frames at 48 kHz, the live profile's 256
///   asked gave 170 at 44.1 kHz; `benches/live_latency.py`).
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

impl Capture {
    /// Opens `name` (`None`: the default input device) with its default configuration and
    /// starts capturing into a ring of [`CAPTURE_RING_S`] seconds.
    ///
    /// Errors: no input device, an unknown name (the error lists the available ones), a
    /// sample format cpal cannot convert, or the device refusing to open.
    pub fn open(name: Option<&str>) -> Result<Capture, DeviceError> {
        Self::open_with(name, &CaptureRequest::default())
    }

    /// [`Capture::open`] asking for a rate and a period (the live profile; see
    /// [`CaptureRequest`]); what the device refuses falls back to its default.
    pub fn open_with(name: Option<&str>, req: &CaptureRequest) -> Result<Capture, DeviceError> {
        const WHAT: &str = "input";
        let (device, label, sc) = device_with_config(name, true)?;
        let (sc, config) = req.choose(&device, sc);
        let rate = config.sample_rate;
        let frames = ((rate as f64 * CAPTURE_RING_S) as usize).max(4096);
        let (w, reader) = capture_ring(frames);
        let stream = by_format!(
            sc.sample_format(),
            WHAT,
            label,
            build_input(&device, config, w)
        )
        .map_err(|e| device_err(WHAT, &label, "open", e))?;
        stream
            .play()
            .map_err(|e| device_err(WHAT, &label, "start", e))?;
        Ok(Capture {
            _stream: stream,
            reader,
            rate,
            channels: config.channels,
            device: label,
        })
    }

    /// The device's sample rate, Hz.
    pub fn rate(&self) -> u32 {
        self.rate
    }

    /// The device's channel count (the first two are kept).
    pub fn channels(&self) -> u16 {
        self.channels
    }

    /// The device's name.
    pub fn device(&self) -> &str {
        &self.device
    }

    /// The ring's reading end: samples and counters.
    pub fn reader(&mut self) -> &mut CaptureReader {
        &mut self.reader
    }
}
