//! # tactus-session: the real-time programs as library calls
//!
//! | call | what |
//! |---|---|
//! | [`live::live`] | capture → engine → sink, as it plays; memory stays flat however long it runs |
//! | [`play::play_song`] | a song rendered frame by frame as it plays (decoded once for the engine and the speakers) |
//! | [`play::play_song_whole`] | a song rendered whole first (offline: every level range the song's own from its first note), then played like a pattern |
//! | [`play::play_pattern`] | a pattern's frames, on its song's audio clock or the caller's clock |
//! | [`view::with_view`] | any of them with the terminal glove view drawn live beside it |
//!
//! Each takes a source, an engine configuration (or frames), a sink
//! ([`tactus_transport::SinkHandle`]) and a clock ([`tactus_transport::Clock`]), and returns
//! a report; none prints. Any program can run Tactus live this way: the `tactus` binary, a
//! notebook, a study harness. The device side (capture, speakers, the audio clock) is behind
//! the `device` feature; without it a capture ring can still be fed by anything, such as a
//! file, which is how the tests run a live session with the null sink.
//!
//! ## Tutorial
//!
//! A live session fed from a synthetic signal through a capture ring, frames to the null
//! sink:
//!
//! ```
//! use std::sync::atomic::AtomicBool;
//! use std::time::Duration;
//! use tactus_audio::ring::capture_ring;
//! use tactus_engine::{EngineConfig, Mode};
//! use tactus_session::live::{live, LiveInput, LiveOptions};
//! use tactus_transport::{open_sink, SinkOptions, SinkSpec};
//!
//! let (mut writer, mut reader) = capture_ring(48_000);
//! // One second of clicks at 48 kHz, mono, written as a capture callback would.
//! let clicks: Vec<f32> = (0..48_000).map(|i| if i % 12_000 < 64 { 0.8 } else { 0.0 }).collect();
//! writer.write(&clicks, 1, |x| x, Duration::ZERO);
//! drop(writer); // the input ends once the ring is drained
//!
//! let sink = open_sink(&SinkSpec::Null, &SinkOptions::default()).unwrap();
//! let config = EngineConfig { mode: Mode::Streaming, bin_ms: 25, ..EngineConfig::default() };
//! let input = LiveInput { reader: &mut reader, rate: 48_000, name: "clicks".into() };
//! let stop = AtomicBool::new(false);
//! let report = live(input, config, &sink, &LiveOptions::default(), &stop, &mut |_| {}).unwrap();
//! assert!(report.frames > 0);
//! sink.close();
//! ```
#![forbid(unsafe_code)]
#![warn(missing_docs)]

#[cfg(feature = "device")]
pub mod device;
pub mod live;
pub mod play;
pub mod view;

pub use live::{
    live, BlockTimes, LiveEngine, LiveInput, LiveOptions, LiveReport, LiveStatus, MAX_BACKLOG,
};
pub use play::{
    pattern_song, play_pattern, play_song, play_song_whole, Late, PlayOptions, PlayReport,
    SoundReport,
};

/// Why a session stopped with an error. Each message is one line a user understands; the
/// cause stays reachable through [`std::error::Error::source`].
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SessionError {
    /// The engine could not be built or failed while running.
    #[error(transparent)]
    Engine(#[from] tactus_engine::EngineError),
    /// The song could not be opened or decoded.
    #[error(transparent)]
    Source(#[from] tactus_audio::SourceError),
    /// A resampler could not be built.
    #[error(transparent)]
    Resample(#[from] tactus_audio::ResampleError),
    /// An audio device failed.
    #[cfg(feature = "device")]
    #[error(transparent)]
    Device(#[from] tactus_audio::device::DeviceError),
    /// The input delivered nothing.
    #[error("input device {device} delivered no audio in {seconds} s")]
    NoAudio {
        /// The input.
        device: String,
        /// How long it was given.
        seconds: f64,
    },
    /// The input device reported an error before its first sample.
    #[error("input device {device} failed")]
    DeviceFailed {
        /// The input.
        device: String,
    },
    /// The play clock stopped moving.
    #[error(
        "the play clock stopped for {seconds} s (audio output stalled?); rerun with --no-audio"
    )]
    ClockStalled {
        /// How long it stood still.
        seconds: f64,
    },
    /// A pattern's song is neither where the pattern says nor beside the pattern.
    #[error(
        "the pattern's song {} was not found (nor beside the pattern): pass --audio FILE, or --no-audio to play without sound",
        .0.display()
    )]
    SongNotFound(std::path::PathBuf),
    /// A pattern's song is another file than the one it was rendered from.
    #[error(
        "{}: SHA-256 {sha256} does not match the pattern's {want} (a different file?): pass the song it was rendered from with --audio FILE, or --no-audio",
        .path.display()
    )]
    SongMismatch {
        /// The file found.
        path: std::path::PathBuf,
        /// Its SHA-256.
        sha256: String,
        /// The pattern's.
        want: String,
    },
    /// A file could not be read.
    #[error("reading {}", .0.display())]
    Io(std::path::PathBuf, #[source] std::io::Error),
    /// A thread of the session could not be started.
    #[error("starting the {what}: {source}")]
    Spawn {
        /// Which thread (`audio feeder`, ...).
        what: &'static str,
        /// The system's error.
        #[source]
        source: std::io::Error,
    },
    /// The rendering or feeding thread could not run.
    #[error("{0}")]
    Renderer(String),
}

/// A source that cannot fail (a pattern's frames) fails a session never.
impl From<std::convert::Infallible> for SessionError {
    fn from(never: std::convert::Infallible) -> SessionError {
        match never {}
    }
}
