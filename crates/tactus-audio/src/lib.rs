//! # tactus-audio: bytes and devices to planar `f32`
//!
//! The edge of the pipeline, below the engine:
//!
//! | module | what |
//! |---|---|
//! | [`source`] | [`AudioSource`]: any supported file (WAV, FLAC, MP3, Ogg, M4A, ...) decoded packet by packet to planar stereo `f32` (symphonia), with the downmix rules and damage handling |
//! | [`resample`] | [`StreamResampler`]: streaming, delay-compensated, exact-length rate conversion (rubato's FFT resampler) |
//! | [`ring`] | the capture ring: what a capture callback writes (stereo kept, no allocation, no lock) and what the engine thread reads |
//! | `device` | feature `device`: cpal capture ([`device::Capture`]), playback fed by the caller's samples ([`device::Playback`]) and the audio clock |
//!
//! Conventions: planar buffers (one `Vec<f32>` per channel), samples in `[-1, 1]`, nothing
//! non-finite ever leaves this crate. Calls that allocate say so; `process` calls with
//! buffers reserved ahead do not.
//!
//! ## Tutorial
//!
//! ```
//! use tactus_audio::resample::StreamResampler;
//!
//! // One second of a 440 Hz tone at 48 kHz, converted to the engine's 44.1 kHz in blocks.
//! let tone: Vec<f32> = (0..48_000)
//!     .map(|i| (2.0 * std::f32::consts::PI * 440.0 * i as f32 / 48_000.0).sin())
//!     .collect();
//! let mut rs = StreamResampler::new(48_000, 44_100, 1).unwrap();
//! let mut out = vec![Vec::new()];
//! for block in tone.chunks(512) {
//!     rs.process(&[block], &mut out);
//! }
//! rs.finish(&mut out);
//! assert_eq!(out[0].len(), 44_100); // exact length: round(n · out / in)
//! ```
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod resample;
pub mod ring;
pub mod source;

#[cfg(feature = "device")]
pub mod device;

pub use resample::{ResampleError, StreamResampler};
pub use source::{AudioInfo, AudioSource, SourceError};
