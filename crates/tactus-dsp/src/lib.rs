//! # tactus-dsp: the paper's signal kernels, streaming, exact and fast
//!
//! Pure DSP for Tactus. No I/O, no threads, and no allocation after construction.
//! Every stage has the same streaming shape:
//!
//! * `process(&mut self, input, ...)` accepts a block of **any** length (including 0);
//! * `reset(&mut self)` returns the stage to its just-constructed state;
//! * `latency_samples(&self)` says how many input samples the stage's output lags behind.
//!
//! Processing a signal in arbitrary chunks gives exactly the same output as processing it
//! in one block; the property tests in `tests/` check this for every stage.
//!
//! ## Tutorial
//!
//! YIN on a 220 Hz tone, fed in blocks of any size; one estimate per hop comes back through
//! the callback:
//!
//! ```
//! use tactus_dsp::yin::{Yin, YinConfig};
//! use tactus_dsp::HopStage;
//!
//! let rate = 44_100;
//! let tone: Vec<f32> = (0..rate)
//!     .map(|i| (2.0 * std::f32::consts::PI * 220.0 * i as f32 / rate as f32).sin())
//!     .collect();
//! let mut yin = Yin::new(YinConfig::new(rate, 50.0, 1000.0)).unwrap();
//! let mut f0 = Vec::new();
//! for block in tone.chunks(300) {
//!     yin.process(block, &mut |_, e| f0.push(e.f0_hz));
//! }
//! yin.finish(&mut |_, e| f0.push(e.f0_hz));
//! let mid = f0[f0.len() / 2];
//! assert!((mid - 220.0).abs() < 0.5, "{mid}");
//! ```
//!
//! ## Conventions shared by every stage
//!
//! * Samples are `f32`, mono. Sample rates are `u32` in Hz.
//! * **Sample-domain stages** (filters, median) map `input[i] -> output[i]`, same length.
//! * **Hop-domain stages** (YIN, pYIN, spectral flux, RMS) produce one value per hop.
//!   Hop `i` describes the frame *centred* on sample `i * hop`, i.e. the stage behaves as if
//!   `frame / 2` zeros preceded the input (librosa's `center=True`). Its time stamp is
//!   `i * hop / sample_rate` seconds. A stream of `n` samples has `n.div_ceil(hop)` hops.
//!   They push results through a callback `emit(hop_index, value)`, so nothing allocates.
//!   `finish(emit)` flushes the last hops as if zeros followed the input; call `reset()`
//!   before reusing a finished stage. See [`framer::Framer`], which they all build on.
//! * The shapes are three traits ([`stage`]): [`SampleStage`], [`HopStage`] and, above the
//!   kernels, [`HopFilter`] (one value per hop in). A hop-domain stage that reads a second
//!   signal of the same span (a learned tracker's harmonic view, a drum signal's backing)
//!   takes it as the optional side input of [`HopStage::process_with`]; `process` is the
//!   same call without one. A stage with two estimates per hop emits them as its `Out`
//!   ([`shs::WithDecoded`], [`pair::WithVoicing`]).
//! * Non-finite input samples never reach the arithmetic: they are replaced by 0 and
//!   counted (see [`sanitize`]).
//!
//! ## Modules
//! | module | algorithm | source |
//! |---|---|---|
//! | [`sos`] | Butterworth low/high/band-pass as second-order sections, f64 state | bilinear transform with prewarping |
//! | [`median`] | running median over an odd window | — |
//! | [`yin`] | YIN pitch, FFT difference function, CMND, parabolic interpolation | de Cheveigné & Kawahara 2002 |
//! | [`pyin`] | probabilistic YIN with Viterbi tracking | Mauch & Dixon 2014 |
//! | [`flux`] | half-wave-rectified spectral flux, adaptive-threshold peak picking | Dixon 2006; Böck et al. 2012 |
//! | [`rms`] | frame RMS in dB and the 35 dB gate | the paper, §3 |
//! | [`tukey`] | Tukey's fences (k = 1.5) on voiced pitch in semitones | Tukey 1977 |
//! | [`discretize`] | N pitch levels over the stem's non-zero range | the paper, §3 |
//! | [`binner`] | per-hop values into bins of B ms | the paper, §3 |
//! | [`melbank`] | log mel-band power with a chosen look-ahead | HTK mel scale |
//! | [`drums`] | per-instrument drum transcription (kick, snare, toms, cymbals): mel context, a small MLP, causal peak picking | frame-wise ADT (Vogl et al. 2017; Southall et al. 2017) |
//! | [`shs`] | harmonic-sum (subharmonic summation) salience with fixed-lag Viterbi, for a bass line or a lead in a mixture | Hermes 1988; Klapuri 2006; Goto 2004 |
//! | [`bassnet`] | a learned bass salience over a log-frequency spectrum (small MLP), decoded by [`shs`] times the harmonic sum | deep salience (Bittner et al. 2017), product of experts |
//! | [`pair`] | two pitch trackers over one stream: one decides whether, the other which pitch | ours |
//! | [`nn`] | the embedded networks' pieces: dense and convolutional layers, their weight files, the forward pass (AVX2 where the CPU has it) | — |
// `unsafe` lives in two modules, `simd` (the run-time AVX2 check and the Viterbi steps
// compiled for AVX2) and `nn::simd` (the AVX2 dense layer), which allow it and say why.
#![deny(unsafe_code)]

pub mod bassnet;
pub mod binner;
pub mod dc;
pub mod discretize;
pub mod drums;
pub mod flux;
pub mod framer;
pub mod median;
pub mod melbank;
pub mod nn;
pub mod notes;
pub mod pair;
pub mod plain;
pub mod pyin;
pub mod rms;
pub mod sanitize;
pub mod sdr;
pub mod shs;
mod simd;
pub mod sos;
mod spectrum;
pub mod stage;
pub mod tukey;
pub mod twoframe;
mod viterbi;
pub mod yin;

pub use stage::{HopFilter, HopStage, SampleStage};

/// Errors raised when a stage is constructed with impossible parameters.
/// Processing itself never fails.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// A parameter is outside its valid range.
    #[error("invalid {name}: {reason}")]
    Invalid {
        /// The parameter's name.
        name: &'static str,
        /// Why it is rejected.
        reason: String,
    },
}

impl ConfigError {
    /// Shorthand for [`ConfigError::Invalid`].
    pub fn invalid(name: &'static str, reason: impl Into<String>) -> Self {
        ConfigError::Invalid {
            name,
            reason: reason.into(),
        }
    }

    /// `Ok(())` when `ok`, else [`ConfigError::Invalid`] for `name`: one line per check in a
    /// config's validation.
    pub fn require(ok: bool, name: &'static str, reason: &str) -> Result<(), Self> {
        if ok {
            Ok(())
        } else {
            Err(ConfigError::invalid(name, reason))
        }
    }
}

/// `acc.max(x)` for a running maximum `acc` that is never NaN and values `x` that are never
/// −0 (powers, magnitudes, absolute values): `x` when it is greater, else `acc`, so a NaN
/// `x` is skipped as `f32::max` skips it. One compare-and-select (`maxss`) where `f32::max`
/// needs four instructions to sort out NaN, which made the spectra's band maxima the front
/// ends' hot loop; the same values (`tests::max_skip_nan_is_max`).
#[inline(always)]
pub(crate) fn max_skip_nan(acc: f32, x: f32) -> f32 {
    if x > acc {
        x
    } else {
        acc
    }
}

/// Converts a frequency in Hz to (fractional) MIDI semitones: A4 = 440 Hz = 69.
#[inline]
pub fn hz_to_semitones(hz: f32) -> f32 {
    69.0 + 12.0 * (hz / 440.0).log2()
}

/// Converts (fractional) MIDI semitones to Hz.
#[inline]
pub fn semitones_to_hz(st: f32) -> f32 {
    440.0 * ((st - 69.0) / 12.0).exp2()
}

/// A separated instrument stem, in the order Demucs uses for its 4-stem models.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Stem {
    /// Percussion; split further into [`Band`]s.
    Drums,
    /// Bass line (melodic).
    Bass,
    /// Lead voice (melodic).
    Vocals,
    /// Everything else (melodic, often polyphonic).
    Other,
}

impl Stem {
    /// All stems, in canonical order.
    pub const ALL: [Stem; 4] = [Stem::Drums, Stem::Bass, Stem::Vocals, Stem::Other];
    /// The melodic stems, which get pitch tracking.
    pub const MELODIC: [Stem; 3] = [Stem::Bass, Stem::Vocals, Stem::Other];

    /// Lower-case name used in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Stem::Drums => "drums",
            Stem::Bass => "bass",
            Stem::Vocals => "vocals",
            Stem::Other => "other",
        }
    }

    /// Parses a lower-case name.
    pub fn from_name(s: &str) -> Option<Stem> {
        Stem::ALL.into_iter().find(|x| x.name() == s)
    }

    /// Default pitch search range in Hz (docs/design.md: bass 35–400, vocals 70–1400, other 50–2000).
    /// `None` for drums, which get onset detection instead of pitch.
    pub fn pitch_range_hz(self) -> Option<(f32, f32)> {
        match self {
            Stem::Drums => None,
            Stem::Bass => Some((35.0, 400.0)),
            Stem::Vocals => Some((70.0, 1400.0)),
            Stem::Other => Some((50.0, 2000.0)),
        }
    }
}

/// A drum frequency band (the paper's Butterworth split of the drum stem).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Band {
    /// 30–150 Hz.
    Kick,
    /// 150–800 Hz.
    Snare,
    /// 800–5000 Hz.
    Toms,
    /// 5000–12000 Hz.
    Cymbals,
}

impl Band {
    /// All bands, low to high.
    pub const ALL: [Band; 4] = [Band::Kick, Band::Snare, Band::Toms, Band::Cymbals];

    /// Lower-case name used in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Band::Kick => "kick",
            Band::Snare => "snare",
            Band::Toms => "toms",
            Band::Cymbals => "cymbals",
        }
    }

    /// Parses a lower-case name.
    pub fn from_name(s: &str) -> Option<Band> {
        Band::ALL.into_iter().find(|x| x.name() == s)
    }

    /// The paper's nominal band edges in Hz, before any clamping to the sample rate.
    pub fn edges_hz(self) -> (f64, f64) {
        match self {
            Band::Kick => (30.0, 150.0),
            Band::Snare => (150.0, 800.0),
            Band::Toms => (800.0, 5000.0),
            Band::Cymbals => (5000.0, 12000.0),
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn max_skip_nan_is_max() {
        // Running maxima as the front ends keep them: from 0, over non-negative values,
        // NaN among them; every order of a small set gives `f32::max`'s bits.
        let vals = [0.0f32, 1.5, f32::NAN, 1e-30, 3.0, f32::INFINITY, 2.0, 1.5];
        for start in 0..vals.len() {
            let (mut a, mut b) = (0.0f32, 0.0f32);
            for k in 0..vals.len() {
                let x = vals[(start + k * 3) % vals.len()];
                a = a.max(x);
                b = super::max_skip_nan(b, x);
                assert_eq!(a.to_bits(), b.to_bits(), "start {start} step {k}");
            }
        }
    }
}
