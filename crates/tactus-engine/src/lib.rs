//! # tactus-engine: one streaming pipeline for offline rendering and live play
//!
//! ```text
//! source (symphonia) → resample (rubato) → separate → per-stem chains → bins → glove frames
//!                                             │  denoise: Butterworth HP + median
//!                                             ├─ melodic: YIN/pYIN + RMS gate + Tukey + levels
//!                                             └─ drums: per-instrument transcriber (log-mel + MLP) + gate,
//!                                                       or the paper's 4 Butterworth bands → spectral-flux onsets
//! ```
//! [`engine::Engine`] accepts blocks of any size; [`render::render`] drives it from a file.
//! Decoding and resampling live in `tactus-audio` (re-exported here as [`source`] and
//! [`resample`]); the real-time drivers (`play`, `live`) in `tactus-session`.
//!
//! ## Tutorial
//!
//! Two seconds of kick-like clicks through the streaming engine, in blocks, to glove frames:
//!
//! ```
//! use tactus_engine::{Engine, EngineConfig, Mode, ENGINE_RATE};
//!
//! let n = 2 * ENGINE_RATE as usize;
//! let clicks: Vec<f32> = (0..n)
//!     .map(|i| {
//!         let t = (i % 22_050) as f32 / ENGINE_RATE as f32; // every 0.5 s
//!         if t < 0.03 { 0.8 * (2.0 * std::f32::consts::PI * 60.0 * t).sin() } else { 0.0 }
//!     })
//!     .collect();
//! let cfg = EngineConfig { mode: Mode::Streaming, bin_ms: 100, ..EngineConfig::default() };
//! let mut engine = Engine::new(cfg).unwrap();
//! for block in clicks.chunks(512) {
//!     engine.process(block, block, &[]); // mono: the same slice twice
//! }
//! engine.finish();
//! let frames = engine.frames();
//! assert_eq!(frames.len(), 20); // 2 s of 100 ms bins
//! println!("latency budget: {:?}", engine.latency_budget());
//! ```
#![forbid(unsafe_code)]

pub mod drums;
pub mod engine;
pub mod notes;
pub mod profile;
pub mod recipe;
pub mod render;
pub mod track;

/// Decoding and resampling moved to `tactus-audio`; re-exported under their old paths.
pub use tactus_audio::{resample, source};

pub use drums::DrumMethod;
pub use engine::{Engine, EngineConfig, SeparatorChoice, ENGINE_RATE};
pub use notes::NoteRule;
pub use profile::Profile;
pub use recipe::{PitchMethod, Role, Source};
pub use track::{LevelRule, Mode};

use std::path::PathBuf;

/// Everything that can stop the engine. Each message is one line a user understands.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EngineError {
    /// The input could not be decoded.
    #[error(transparent)]
    Source(#[from] source::SourceError),
    /// Resampler construction failed.
    #[error(transparent)]
    Resample(#[from] resample::ResampleError),
    /// A configuration the engine refuses (the message says which and why; no cause).
    #[error("{0}")]
    Config(String),
    /// A DSP stage was configured with impossible parameters.
    #[error(transparent)]
    Dsp(#[from] tactus_dsp::ConfigError),
    /// The separator could not be built.
    #[error("{0}")]
    SeparatorSetup(#[source] tactus_separate::SeparateError),
    /// An ONNX separator (htdemucs, spleeter) could not be built.
    #[cfg(feature = "onnx")]
    #[error("{0}")]
    Onnx(#[source] tactus_separate::onnx::OnnxError),
    /// The ADTLib drum transcriber could not be built.
    #[cfg(feature = "onnx")]
    #[error("ADTLib: {0}")]
    AdtLib(#[source] tactus_separate::onnx::adtlib::AdtLibError),
    /// A worker thread of the engine's panicked (a bug: please report it).
    #[error("the {0} thread panicked")]
    Panicked(&'static str),
    /// The separator failed while running (an ONNX Runtime error, a model output of the
    /// wrong shape): the stems it produced cannot be trusted.
    #[error(transparent)]
    Separator(tactus_separate::SeparateError),
    /// The ADTLib drum transcriber's network failed while running.
    #[error("drum transcription (adtlib) failed: {0}")]
    Drums(String),
    /// Reading a file failed.
    #[error("{path}: {source}", path = .0.display(), source = .1)]
    Io(PathBuf, #[source] std::io::Error),
    /// The caller's frame callback asked to stop ([`render::render_with`]).
    #[error("rendering was stopped")]
    Cancelled,
}
