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
#![forbid(unsafe_code)]

pub mod drums;
pub mod engine;
pub mod notes;
pub mod render;
pub mod track;

/// Decoding and resampling moved to `tactus-audio`; re-exported under their old paths.
pub use tactus_audio::{resample, source};

pub use drums::DrumMethod;
pub use engine::{Engine, EngineConfig, SeparatorChoice, ENGINE_RATE};
pub use track::{LevelRule, Mode, PitchMethod};

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
    /// A stage was configured with impossible parameters (the message says which).
    #[error("{0}")]
    Config(String),
    /// The separator failed while running (an ONNX Runtime error, a model output of the
    /// wrong shape): the stems it produced cannot be trusted.
    #[error(transparent)]
    Separator(tactus_separate::SeparateError),
    /// The ADTLib drum transcriber's network failed while running.
    #[error("drum transcription (adtlib) failed: {0}")]
    Drums(String),
    /// Reading a file failed.
    #[error("{path}: {source}", path = .0.display(), source = .1)]
    Io(PathBuf, std::io::Error),
    /// The caller's frame callback asked to stop ([`render::render_with`]).
    #[error("rendering was stopped")]
    Cancelled,
}

impl From<tactus_dsp::ConfigError> for EngineError {
    fn from(e: tactus_dsp::ConfigError) -> Self {
        EngineError::Config(e.to_string())
    }
}
