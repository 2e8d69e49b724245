//! Per-stem feature tracks: the chains of docs/design.md from a mono stem signal to bins.
//!
//! * [`PitchTrack`]: denoised melodic stem → pitch tracker (YIN or pYIN) + RMS per hop →
//!   RMS gate → Tukey fences → discretizer → level per bin.
//! * [`OnsetTrack`]: a band-passed drum signal (or a melodic stem, for note onsets) →
//!   spectral-flux onsets + RMS per hop → RMS gate → beat per bin.
//!
//! Both record their raw per-hop values, so that the same extraction serves the two
//! statistics modes: `streaming` post-processes every hop as it arrives with running
//! statistics (causal), `offline` post-processes the whole track at the end with global
//! statistics (the paper's behaviour). Extraction is identical in both modes.

mod denoise;
mod levels;
mod onset;
mod pitch;
mod tracker;

pub use crate::recipe::PitchMethod;
pub use denoise::{Decimator, Denoise};
pub(crate) use onset::onset_times;
pub use onset::{Beats, OnsetTrack};
pub use pitch::PitchTrack;

use tactus_dsp::Stem;
use tactus_glove::BinFeatures;

/// Statistics mode (docs/design.md "One engine, two drivers").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Mode {
    /// Whole-track fences, ranges and gate reference: paper-faithful, for `render`.
    #[default]
    Offline,
    /// Running statistics; nothing looks beyond the stated latency. Always used live.
    Streaming,
}

/// How a pitch track turns voiced pitch into levels (`docs/decisions/0003-levels-follow-the-line.md`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LevelRule {
    /// The paper's rule as first implemented: Tukey fences with k = 1.5 on the raw IQR, the
    /// level range = min and max of what the fences keep (streaming: the running min and max
    /// from the first note on).
    Paper,
    /// Fences with the IQR floored ([`crate::recipe::LevelRecipe::min_iqr_st`]: a bass line's real octave
    /// leaps are no longer cut), the range from the 1st to the 99th percentile of the voiced
    /// hops that the fences keep ([`crate::recipe::LevelRecipe::quantile`]: a few octave errors no longer
    /// stretch it);
    /// in streaming mode the same percentiles of every kept hop so far (an early octave error
    /// no longer shifts every later level), padded to a prior that fades, so the first notes
    /// do not sit on level 1 or 8: the instrument's register for the bass and the lead
    /// ([`crate::recipe::LevelRecipe::register_hz`]), a span ([`crate::recipe::LevelRecipe::prior_span_st`]) for the rest.
    /// Running percentiles of the fences' 10 s window were tried first: vocals levels ±1 fell
    /// from 0.76 to 0.68 on the tuned songs
    /// (`docs/decisions/0016-streaming-range-from-running-percentiles.md`,
    /// `docs/decisions/0022-streaming-levels-from-a-register-prior.md`).
    #[default]
    Follow,
}

/// Streaming gate reference decay (dB per second). Slow enough that a held note does not
/// re-open the gate on its own tail, fast enough that a quiet verse after a loud chorus
/// is heard within a few seconds.
pub(crate) const GATE_DECAY_DB_PER_S: f32 = 3.0;
/// Shared geometry of every track in one engine.
#[derive(Debug, Clone, Copy)]
pub struct Geometry {
    /// Engine sample rate in Hz.
    pub sample_rate: u32,
    /// Bin length in samples.
    pub bin_samples: usize,
    /// Pitch levels (default 8).
    pub levels: u8,
    /// Statistics mode.
    pub mode: Mode,
    /// How voiced pitch becomes levels.
    pub level_rule: LevelRule,
    /// Latency profile ([`crate::profile`]).
    pub profile: crate::profile::Profile,
}

/// What a track contributes to a frame: the live glove shows each as soon as it is final
/// ([`crate::Engine::live_frame`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Feature {
    /// Pitch level (cell 0 of a melodic finger).
    Level,
    /// Note onsets (cell 1 of a melodic finger).
    Notes,
    /// Drum beats (bands or classes).
    Beats,
}

impl Feature {
    /// Every feature.
    pub const ALL: [Feature; 3] = [Feature::Level, Feature::Notes, Feature::Beats];
}

/// One block of what a stem's chain hands its tracks: every track reads the part it needs.
#[derive(Clone, Copy)]
pub struct TrackInput<'a> {
    /// The denoised stem (empty at [`Track::finish`]).
    pub stem: &'a [f32],
    /// The same span of the separator's harmonic sum (vocals + bass + other), denoised like
    /// the stem, when the chain has it: a drum transcriber's backing, a pitch track's
    /// harmonic view.
    pub side: Option<&'a [f32]>,
    /// The stem's pitch track, after it took this block: what note onsets read.
    pub pitch: Option<&'a PitchTrack>,
}

impl<'a> TrackInput<'a> {
    /// A block of the stem alone.
    pub fn stem(stem: &'a [f32]) -> Self {
        TrackInput {
            stem,
            side: None,
            pitch: None,
        }
    }
}

/// The shape of every feature track the engine runs ([`PitchTrack`],
/// [`crate::notes::NoteTrack`], [`crate::drums::ClassTrack`] and the drum bands): a stream of
/// blocks in, one value per bin out. The engine drives and reads its tracks through it
/// alone; each track also keeps typed methods for callers that hold it.
pub trait Track: Send {
    /// Feeds one block (blocks of any size; the output does not depend on how the stream
    /// is cut).
    fn process(&mut self, input: &TrackInput<'_>);

    /// Ends the stream: flushes what the track holds back and, offline, computes the
    /// whole-track statistics. `input.stem` is empty.
    fn finish(&mut self, input: &TrackInput<'_>);

    /// Back to the just-constructed state.
    fn reset(&mut self);

    /// Input samples (engine rate) after which a bin's value is final, counted from the
    /// stem the chain feeds (for note onsets read from pitch, the pitch track's included).
    fn latency_samples(&self) -> usize;

    /// Streaming: forgets the first `bins` of the bins it holds and the per-hop values
    /// behind them ([`crate::Engine::discard_before`]); bin numbers then count from there.
    fn discard_before(&mut self, bins: usize);

    /// Which cell of a frame it fills.
    fn feature(&self) -> Feature;

    /// Bins whose value is final (counted from the first bin held).
    fn ready_bins(&self) -> usize;

    /// Writes its value of bin `bin` (counted like [`Track::ready_bins`]; a bin not held
    /// reads as silent) into `frame`, as the feature of `stem`; a beat or onset stays on for
    /// `hold` bins.
    fn read_bin(&self, bin: usize, hold: usize, stem: Stem, frame: &mut BinFeatures);

    /// Per-hop and per-bin values held ([`crate::Engine::retained_values`]).
    fn retained(&self) -> usize;
}

/// Whether any of the `hold` bins ending at `bin` is a beat (bins not held are silent).
pub(crate) fn held(bins: &[bool], bin: usize, hold: usize) -> bool {
    (bin.saturating_sub(hold - 1)..=bin).any(|j| bins.get(j).copied().unwrap_or(false))
}
