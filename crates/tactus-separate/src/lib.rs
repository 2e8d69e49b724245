//! # tactus-separate: split a mix into drums, bass, vocals and other
//!
//! Every backend implements one streaming trait, [`Separator`]: feed planar stereo blocks
//! of any size to [`Separator::process`], end the stream with [`Separator::finish`], and
//! read one **mono** signal per requested [`Stem`] from a caller-owned [`StemOutput`].
//! Over a whole stream, `process` + `finish` append exactly as many samples per stem as
//! were input, aligned with the input: output sample `j` belongs to input sample `j`.
//! While streaming, the output lags the input by at most [`Separator::latency_samples`].
//!
//! | backend | what it does | latency |
//! |---|---|---|
//! | [`none::NoneSeparator`] | every stem is the mono mix `(L + R) / 2` | 0 |
//! | [`spectral::SpectralSeparator`] | median-filter HPSS + crossover + stereo-centre masks (pure Rust, default) | `n_fft - 1 + lookahead * hop` (93 ms by default at 44.1 kHz) |
//!
//! The STFT / overlap-add machinery the spectral backend (and later the ONNX backends)
//! build on lives in [`stft`]. [`sdr`] scores an estimate against a reference.
//!
//! ```
//! use tactus_separate::{Separator, Stem, StemOutput, StemSet};
//! use tactus_separate::spectral::{SpectralConfig, SpectralSeparator};
//!
//! let stems = StemSet::default().with(Stem::Drums).with(Stem::Bass);
//! let mut sep = SpectralSeparator::new(44_100, stems, SpectralConfig::default()).unwrap();
//! let left = vec![0.0f32; 4410];
//! let right = left.clone();
//! // Reserve once (input length + one block of latency): then process never allocates.
//! let mut out = StemOutput::with_capacity(stems, left.len());
//! sep.process(&left, &right, &mut out);
//! sep.finish(&mut out);
//! assert_eq!(out.get(Stem::Drums).len(), 4410);
//! assert!(out.get(Stem::Vocals).is_empty());
//! ```
#![forbid(unsafe_code)]

pub mod lowband;
pub mod none;
#[cfg(feature = "onnx")]
pub mod onnx;
pub mod spectral;
pub mod stft;

pub use tactus_dsp::Stem;

use std::time::Duration;

use tactus_dsp::ConfigError;

/// A set of [`Stem`]s (a bit set over [`Stem::ALL`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct StemSet(u8);

/// Position of a stem in [`Stem::ALL`] (0..4).
#[inline]
pub fn stem_index(stem: Stem) -> usize {
    match stem {
        Stem::Drums => 0,
        Stem::Bass => 1,
        Stem::Vocals => 2,
        Stem::Other => 3,
    }
}

impl StemSet {
    /// The empty set.
    pub const EMPTY: StemSet = StemSet(0);

    /// All four stems.
    pub fn all() -> Self {
        StemSet(0b1111)
    }

    /// This set plus `stem`.
    #[must_use]
    pub fn with(self, stem: Stem) -> Self {
        StemSet(self.0 | 1 << stem_index(stem))
    }

    /// Whether `stem` is in the set.
    pub fn contains(self, stem: Stem) -> bool {
        self.0 & (1 << stem_index(stem)) != 0
    }

    /// Whether the set is empty.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Number of stems in the set.
    pub fn len(self) -> usize {
        self.0.count_ones() as usize
    }

    /// The union of two sets.
    #[must_use]
    pub fn union(self, other: StemSet) -> Self {
        StemSet(self.0 | other.0)
    }

    /// The stems in the set, in canonical order ([`Stem::ALL`]).
    pub fn iter(self) -> impl Iterator<Item = Stem> {
        Stem::ALL.into_iter().filter(move |&s| self.contains(s))
    }
}

impl FromIterator<Stem> for StemSet {
    fn from_iter<I: IntoIterator<Item = Stem>>(iter: I) -> Self {
        iter.into_iter().fold(StemSet::EMPTY, StemSet::with)
    }
}

/// Caller-owned output of a [`Separator`]: one mono `Vec<f32>` per stem.
///
/// Separators only append. A stem is *present* once a separator asked for it has written
/// to the output (even zero samples); [`StemOutput::get`] returns an empty slice for an
/// absent stem. Pushing within reserved capacity does not allocate: reserve the input
/// length plus the separator's latency ([`StemOutput::with_capacity`] /
/// [`StemOutput::reserve`]) to keep `process` allocation-free.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StemOutput {
    present: StemSet,
    data: [Vec<f32>; 4],
}

impl StemOutput {
    /// An empty output that has not allocated anything.
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty output with room for `n` samples of each stem in `stems`.
    pub fn with_capacity(stems: StemSet, n: usize) -> Self {
        let mut out = Self::default();
        out.reserve(stems, n);
        out
    }

    /// Makes room for `n` more samples of each stem in `stems`.
    pub fn reserve(&mut self, stems: StemSet, n: usize) {
        for s in stems.iter() {
            self.data[stem_index(s)].reserve(n);
        }
    }

    /// The samples of `stem` so far (empty if the stem is absent).
    pub fn get(&self, stem: Stem) -> &[f32] {
        &self.data[stem_index(stem)]
    }

    /// Moves the samples of `stem` out, leaving it empty (and absent).
    pub fn take(&mut self, stem: Stem) -> Vec<f32> {
        self.present = StemSet(self.present.0 & !(1 << stem_index(stem)));
        std::mem::take(&mut self.data[stem_index(stem)])
    }

    /// The stems that a separator has written to since the last [`StemOutput::clear`].
    pub fn present(&self) -> StemSet {
        self.present
    }

    /// Empties every stem, keeping the capacity; no stem is present afterwards.
    pub fn clear(&mut self) {
        self.present = StemSet::EMPTY;
        for v in &mut self.data {
            v.clear();
        }
    }

    /// Marks `stems` as present (a separator calls this for what it outputs).
    pub fn declare(&mut self, stems: StemSet) {
        self.present = self.present.union(stems);
    }

    /// Appends samples to `stem` and marks it present.
    pub fn extend(&mut self, stem: Stem, samples: &[f32]) {
        self.present = self.present.with(stem);
        self.data[stem_index(stem)].extend_from_slice(samples);
    }

    /// Appends one sample to `stem` and marks it present.
    #[inline]
    pub fn push(&mut self, stem: Stem, sample: f32) {
        self.present = self.present.with(stem);
        self.data[stem_index(stem)].push(sample);
    }
}

/// A streaming source separator. See the crate docs for the contract.
pub trait Separator: Send {
    /// Short backend name (`"spectral"`, `"none"`, ...).
    fn name(&self) -> &'static str;
    /// The sample rate the separator was built for, in Hz.
    fn sample_rate(&self) -> u32;
    /// The stems it outputs (= the stems it was asked for).
    fn stems(&self) -> StemSet;
    /// Planar stereo input (pass the same slice twice for mono). Appends mono stem
    /// signals to `out`. `left` and `right` should have the same length; if they do not,
    /// only the common prefix is used. Non-finite samples are treated as 0.
    fn process(&mut self, left: &[f32], right: &[f32], out: &mut StemOutput);
    /// Flushes: over a whole stream, `process` + `finish` append exactly as many samples
    /// per stem as were input, aligned with the input (output sample `j` belongs to input
    /// sample `j`). Call [`Separator::reset`] before feeding a new stream.
    fn finish(&mut self, out: &mut StemOutput);
    /// Back to the just-constructed state.
    fn reset(&mut self);
    /// How far the output lags the input while streaming (worst case, in samples): after
    /// `n` input samples, at least `n - latency_samples()` output samples were appended.
    fn latency_samples(&self) -> usize;
    /// Timing of the network segments since construction or the last
    /// [`Separator::reset`], for backends that run a network in segments (the ONNX
    /// backends); `None` for the others.
    fn segment_stats(&self) -> Option<SegmentStats> {
        None
    }
    /// Takes the error of a step that failed since the last call (a network call that
    /// ONNX Runtime refused, an output of the wrong shape), if any. **Contract**: a backend
    /// that cannot fail returns `None` (the default); one that can keeps appending
    /// samples so the stream lengths still hold (the failed span is silent or unseparated,
    /// so not to be used), and reports the failure here. Callers check after every
    /// [`Separator::process`] and [`Separator::finish`] and end the stream on `Some`.
    fn take_error(&mut self) -> Option<SeparateError> {
        None
    }
}

/// Per-segment instrumentation of a separator that runs a network in segments.
///
/// Collected with two `Instant` reads per network call and two per `process` / `finish`
/// call; no allocation. "Outside the network" is everything else the separator does in
/// `process` and `finish`: STFT, iSTFT, overlap-add, masks, blending, copies.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SegmentStats {
    /// Network calls (segments) so far.
    pub segments: u64,
    /// Time inside the network calls, summed.
    pub network: Duration,
    /// Shortest network call (zero before the first).
    pub network_min: Duration,
    /// Longest network call.
    pub network_max: Duration,
    /// Time inside `process` and `finish`, network included.
    pub busy: Duration,
    /// Inverse FFTs computed (one per synthesised channel and STFT frame): shows which
    /// stems were synthesised.
    pub inverse_ffts: u64,
    /// Input samples between the starts of consecutive segments (44.1 kHz).
    pub stride_samples: usize,
}

impl SegmentStats {
    /// Stats for segments that start every `stride_samples` input samples.
    pub fn new(stride_samples: usize) -> Self {
        SegmentStats {
            stride_samples,
            ..Self::default()
        }
    }

    /// Records one network call that took `d`.
    #[inline]
    pub fn record_network(&mut self, d: Duration) {
        self.network_min = if self.segments == 0 {
            d
        } else {
            self.network_min.min(d)
        };
        self.network_max = self.network_max.max(d);
        self.network += d;
        self.segments += 1;
    }

    /// Mean network time per segment (zero before the first).
    pub fn network_mean(&self) -> Duration {
        if self.segments == 0 {
            Duration::ZERO
        } else {
            self.network.div_f64(self.segments as f64)
        }
    }

    /// Time spent outside the network: `busy - network`.
    pub fn outside(&self) -> Duration {
        self.busy.saturating_sub(self.network)
    }

    /// [`SegmentStats::outside`] as a fraction of the network's time (0 when the network
    /// has not run).
    pub fn outside_share(&self) -> f64 {
        let net = self.network.as_secs_f64();
        if net > 0.0 {
            self.outside().as_secs_f64() / net
        } else {
            0.0
        }
    }

    /// Segments a stream of `samples` input samples needs, about (`⌈samples / stride⌉`,
    /// at least 1): for a progress bar.
    pub fn expected_segments(&self, samples: u64) -> u64 {
        samples.div_ceil(self.stride_samples.max(1) as u64).max(1)
    }
}

/// Errors raised when a separator is constructed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SeparateError {
    /// A parameter is outside its valid range.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The separator was asked for no stems at all.
    #[error("no stems requested")]
    NoStems,
    /// The backend cannot run at this sample rate.
    #[error("unsupported sample rate {0} Hz")]
    SampleRate(u32),
    /// A processing step failed at run time ([`Separator::take_error`]).
    #[error("separation ({backend}) failed: {message}")]
    Failed {
        /// The backend (`"htdemucs"`, `"spleeter"`, ...).
        backend: &'static str,
        /// What failed and why, in one line.
        message: String,
    },
}

/// Plain signal-to-distortion ratio in dB ([`tactus_dsp::sdr::sdr_db`]): any gain error
/// counts as distortion, a shorter estimate's missing tail as zeros; `+∞` when the error is
/// zero, `−∞` when the reference is silent but the estimate is not.
pub fn sdr(reference: &[f32], estimate: &[f32]) -> f32 {
    tactus_dsp::sdr::sdr_db(reference, estimate) as f32
}

/// The common prefix of `left` and `right` in blocks of at most `block` samples (the
/// per-block loop of the STFT backends' `process`).
pub(crate) fn stereo_blocks<'a>(
    left: &'a [f32],
    right: &'a [f32],
    block: usize,
) -> impl Iterator<Item = (&'a [f32], &'a [f32])> {
    let n = left.len().min(right.len());
    left[..n].chunks(block).zip(right[..n].chunks(block))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stem_set_ops() {
        let s = StemSet::default().with(Stem::Vocals).with(Stem::Drums);
        assert!(s.contains(Stem::Vocals) && s.contains(Stem::Drums));
        assert!(!s.contains(Stem::Bass) && !s.contains(Stem::Other));
        assert_eq!(
            s.iter().collect::<Vec<_>>(),
            vec![Stem::Drums, Stem::Vocals]
        );
        assert_eq!(s.len(), 2);
        assert!(StemSet::default().is_empty());
        assert_eq!(StemSet::all().iter().count(), 4);
        assert_eq!(Stem::ALL.into_iter().collect::<StemSet>(), StemSet::all());
    }

    #[test]
    fn sdr_known_values() {
        let s = [1.0f32, -1.0, 1.0, -1.0];
        let half: Vec<f32> = s.iter().map(|x| x * 0.5).collect();
        // error = s/2, so |s|²/|e|² = 4 -> 6.02 dB
        assert!((sdr(&s, &half) - 6.0206).abs() < 1e-3);
        assert_eq!(sdr(&s, &s), f32::INFINITY);
        assert_eq!(sdr(&[0.0; 4], &s), f32::NEG_INFINITY);
    }

    #[test]
    fn stem_output_presence() {
        let mut o = StemOutput::with_capacity(StemSet::all(), 8);
        assert!(o.present().is_empty());
        o.push(Stem::Bass, 1.0);
        o.extend(Stem::Bass, &[2.0, 3.0]);
        assert_eq!(o.get(Stem::Bass), &[1.0, 2.0, 3.0]);
        assert_eq!(o.present(), StemSet::default().with(Stem::Bass));
        assert!(o.get(Stem::Drums).is_empty());
        o.clear();
        assert!(o.present().is_empty() && o.get(Stem::Bass).is_empty());
    }
}
