//! # tactus-engine: one streaming pipeline for offline rendering and live play
//!
//! ```text
//! source (symphonia) → resample (rubato) → separate → per-stem chains → bins → glove frames
//!                                             │  denoise: Butterworth HP + median
//!                                             ├─ melodic: YIN/pYIN + RMS gate + Tukey + levels
//!                                             └─ drums: 4 Butterworth bands → spectral-flux onsets + gate
//! ```
//! [`engine::Engine`] accepts blocks of any size; [`render::render`] drives it from a file.
#![forbid(unsafe_code)]

pub mod engine;
pub mod notes;
pub mod render;
pub mod resample;
pub mod source;
pub mod track;

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
    /// A stage was configured with impossible parameters.
    #[error("configuration: {0}")]
    Config(String),
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
