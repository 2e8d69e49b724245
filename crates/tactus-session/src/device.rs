//! `live` on a real input device (the `device` feature): the engine built first (a bad
//! configuration fails before any device opens), real-time scheduling for the engine's
//! thread, the capture device opened as the latency profile asks, then [`LiveEngine::run`]
//! on its ring.
//!
//! ```no_run
//! use std::sync::atomic::AtomicBool;
//! use tactus_engine::{EngineConfig, Mode, Profile};
//! use tactus_session::{device::LiveDevice, LiveOptions};
//! use tactus_transport::{open_sink, SinkOptions, SinkSpec};
//!
//! let config = EngineConfig { mode: Mode::Streaming, profile: Profile::Live, ..EngineConfig::default() };
//! let mut device = LiveDevice::open(None, config).unwrap();
//! let sink = open_sink(&SinkSpec::Null, &SinkOptions::default()).unwrap();
//! let opts = LiveOptions { seconds: Some(5.0), ..LiveOptions::default() };
//! let report = device.run(&sink, &opts, &AtomicBool::new(false), &mut |_| {}).unwrap();
//! println!("{} frames", report.frames);
//! ```

use std::sync::atomic::AtomicBool;

use tactus_audio::device::{Capture, CaptureRequest};
use tactus_engine::{EngineConfig, Profile, ENGINE_RATE};
use tactus_transport::SinkHandle;

use crate::{LiveEngine, LiveInput, LiveOptions, LiveReport, LiveStatus, SessionError};

/// Capture period the live profile asks for (`docs/decisions/0006-live-latency-profile.md`):
/// 256 frames, 5.8 ms at 44.1 kHz.
pub const LIVE_PERIOD_FRAMES: u32 = 256;

/// An open capture device, with the calling thread's scheduling settled.
pub struct LiveDevice {
    engine: Option<LiveEngine>,
    capture: Capture,
    realtime: Result<audio_thread_priority::RtPriorityHandle, String>,
}

impl LiveDevice {
    /// Builds the engine for `config`, asks real-time scheduling for the calling thread
    /// (the one that will run the engine;
    /// the capture and sink threads started after it inherit it), then opens `input`
    /// (`None`: the default input). With the live profile the device is asked for the
    /// engine's rate (no resampler) and a [`LIVE_PERIOD_FRAMES`] period.
    ///
    /// On a loaded machine a normal thread waited up to 300 ms for the CPU
    /// (benches/live_latency.py at load 10-16). Real-time scheduling refused (no
    /// RLIMIT_RTPRIO or CAP_SYS_NICE) is not an error: [`LiveDevice::realtime`] says why.
    pub fn open(input: Option<&str>, config: EngineConfig) -> Result<LiveDevice, SessionError> {
        let live = config.profile == Profile::Live;
        let engine = Some(LiveEngine::new(config)?);
        let realtime = audio_thread_priority::promote_current_thread_to_real_time(
            LIVE_PERIOD_FRAMES,
            ENGINE_RATE,
        )
        .map_err(|e| e.to_string());
        let request = CaptureRequest {
            rate: live.then_some(ENGINE_RATE),
            period_frames: live.then_some(LIVE_PERIOD_FRAMES),
        };
        let capture = Capture::open_with(input, &request)?;
        Ok(LiveDevice {
            engine,
            capture,
            realtime,
        })
    }

    /// The device's rate, Hz.
    pub fn rate(&self) -> u32 {
        self.capture.rate()
    }

    /// The device's channel count.
    pub fn channels(&self) -> u16 {
        self.capture.channels()
    }

    /// The device's name.
    pub fn name(&self) -> &str {
        self.capture.device()
    }

    /// `Ok` when the engine's thread runs at real-time priority, else why not.
    pub fn realtime(&self) -> Result<(), &str> {
        self.realtime.as_ref().map(|_| ()).map_err(|e| e.as_str())
    }

    /// The device's period (frames in its first callback), 0 before any.
    pub fn period_frames(&mut self) -> u64 {
        self.capture.reader().first_callback().map_or(0, |(_, n)| n)
    }

    /// Runs the engine on what the device captures ([`LiveEngine::run`]); once only (a
    /// second call is an error).
    pub fn run(
        &mut self,
        sink: &SinkHandle,
        opts: &LiveOptions,
        stop: &AtomicBool,
        status: &mut dyn FnMut(&LiveStatus),
    ) -> Result<LiveReport, SessionError> {
        let engine = self
            .engine
            .take()
            .ok_or_else(|| SessionError::Renderer("this live device has run already".into()))?;
        let (rate, name) = (self.rate(), self.name().to_string());
        let input = LiveInput {
            reader: self.capture.reader(),
            rate,
            name,
        };
        engine.run(input, sink, opts, stop, status)
    }
}
