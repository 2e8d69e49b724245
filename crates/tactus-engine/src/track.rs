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

use tactus_dsp::binner::{bin_beats, bin_levels, BeatBinner, LevelBinner};
use tactus_dsp::discretize::{
    agree_mask, narrow_range, pitches_agree, range_offline, range_quantiles_kept_or_sure,
    Discretizer, HeldRange, RangePrior, RunningRange, Scale,
};
use tactus_dsp::flux::{OnsetConfig, OnsetDetector, OnsetFrame};
use tactus_dsp::median::MedianFilter;
use tactus_dsp::pair::VoicingPitchPair;
use tactus_dsp::pyin::{Pyin, PyinConfig};
use tactus_dsp::rms::{gate_offline, Rms, StreamingGate, GATE_BELOW_DB};
use tactus_dsp::shs::{Shs, ShsConfig};
use tactus_dsp::sos::{Response, SosFilter};
use tactus_dsp::tukey::{reject_outliers_offline_min_iqr, SlidingTukey, TUKEY_K};
use tactus_dsp::twoframe::TwoFrameYin;
use tactus_dsp::yin::{PitchEstimate, Yin, YinConfig};
use tactus_dsp::{ConfigError, HopFilter, HopStage, SampleStage, Stem};
use tactus_glove::BinFeatures;

pub use crate::recipe::PitchMethod;
use crate::recipe::{LevelRecipe, Network, Recipe, ShsTuning, SureRule, TrackerRecipe};

/// Statistics mode (docs/design.md "One engine, two drivers").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Mode {
    /// Whole-track fences, ranges and gate reference: paper-faithful, for `render`.
    #[default]
    Offline,
    /// Running statistics; nothing looks beyond the stated latency. Always used live.
    Streaming,
}

/// How a pitch track turns voiced pitch into levels (issue 16, "levels that follow the truth").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LevelRule {
    /// The paper's rule as first implemented: Tukey fences with k = 1.5 on the raw IQR, the
    /// level range = min and max of what the fences keep (streaming: the running min and max
    /// from the first note on).
    Paper,
    /// Fences with the IQR floored ([`LevelRecipe::min_iqr_st`]: a bass line's real octave
    /// leaps are no longer cut), the range from the 1st to the 99th percentile of the voiced
    /// hops that the fences keep ([`LevelRecipe::quantile`]: a few octave errors no longer
    /// stretch it);
    /// in streaming mode the same percentiles of every kept hop so far
    /// ([`tactus_dsp::discretize::PriorRange::with_quantile`]: an early octave error no longer shifts every later
    /// level), padded to a prior that fades, so the first notes do not sit on level 1 or 8:
    /// the instrument's register for the bass and the lead ([`LevelRecipe::register_hz`]), a
    /// span ([`LevelRecipe::prior_span_st`]) for the rest. (Running percentiles of the fences' 10 s window were tried
    /// first: vocals levels ±1 fell from 0.76 to 0.68 on the tuned songs; the running min
    /// and max were the streaming range until 2026-11-24.)
    #[default]
    Follow,
}

/// Streaming gate reference decay (dB per second). Slow enough that a held note does not
/// re-open the gate on its own tail, fast enough that a quiet verse after a loud chorus
/// is heard within a few seconds.
pub(crate) const GATE_DECAY_DB_PER_S: f32 = 3.0;
/// Window of the streaming Tukey fences, in hops (10 s at 10 ms hops).
const TUKEY_WINDOW_HOPS: usize = 1000;
/// Voiced values the streaming fences need before they reject anything.
const TUKEY_MIN_COUNT: usize = 20;
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

/// Denoising front end of a stem (docs/design.md: Butterworth high-pass order 4, then a
/// 3-sample median).
pub struct Denoise {
    hp: SosFilter,
    median: MedianFilter,
}

impl Denoise {
    /// A high-pass at `cutoff_hz` then a 3-sample median.
    pub fn new(cutoff_hz: f64, sample_rate: u32) -> Result<Self, ConfigError> {
        Ok(Denoise {
            hp: SosFilter::highpass(cutoff_hz, 4, sample_rate)?,
            median: MedianFilter::new(3)?,
        })
    }

    /// Denoises a block in place.
    pub fn process_inplace(&mut self, block: &mut [f32]) {
        self.hp.process_inplace(block);
        self.median.process_inplace(block);
    }

    /// Samples of delay the median adds.
    pub fn latency_samples(&self) -> usize {
        self.hp.latency_samples() + self.median.latency_samples()
    }

    /// Back to the initial state.
    pub fn reset(&mut self) {
        self.hp.reset();
        self.median.reset();
    }
}

/// Anti-aliased integer decimation in front of a pitch tracker: a stem whose highest
/// pitch is 400 Hz does not need 44.1 kHz. The rate after decimation keeps 10 ms hops
/// whole (`rate / factor` divisible by 100) and stays at least 7 × fmax, where YIN keeps
/// its ≤ 5 cent accuracy (tactus-dsp's pitch tests hold to sr/8 for sines).
/// An order-8 Butterworth low-pass at 0.4 × the new rate removes what would alias.
pub struct Decimator {
    lp: SosFilter,
    factor: usize,
    /// Input samples to skip before the next kept one.
    skip: usize,
    scratch: Vec<f32>,
    out: Vec<f32>,
}

impl Decimator {
    /// The largest factor that keeps `rate / factor` ≥ 7·fmax with whole 10 ms hops.
    pub fn factor_for(rate: u32, fmax_hz: f32) -> usize {
        (1..=32usize)
            .rev()
            .find(|&f| {
                (rate as usize).is_multiple_of(f)
                    && (rate as usize / f).is_multiple_of(100)
                    && (rate as usize / f) as f32 >= 7.0 * fmax_hz
            })
            .unwrap_or(1)
    }

    /// A decimator by `factor` for input at `rate`.
    pub fn new(rate: u32, factor: usize) -> Result<Self, ConfigError> {
        let out_rate = rate as f64 / factor as f64;
        let lp = SosFilter::butterworth(
            8,
            Response::LowPass {
                cutoff_hz: 0.4 * out_rate,
            },
            rate,
        )?;
        Ok(Decimator {
            lp,
            factor,
            skip: 0,
            scratch: Vec::with_capacity(1 << 16),
            out: Vec::with_capacity(1 << 16),
        })
    }

    /// Filters and decimates `block`; the result is in [`Decimator::output`].
    pub fn process(&mut self, block: &[f32]) {
        self.out.clear();
        if self.factor == 1 {
            self.out.extend_from_slice(block);
            return;
        }
        self.scratch.clear();
        self.scratch.extend_from_slice(block);
        self.lp.process_inplace(&mut self.scratch);
        let mut i = self.skip;
        while i < self.scratch.len() {
            self.out.push(self.scratch[i]);
            i += self.factor;
        }
        self.skip = i - self.scratch.len();
    }

    /// The decimated samples of the last block.
    pub fn output(&self) -> &[f32] {
        &self.out
    }

    /// Back to the initial state.
    pub fn reset(&mut self) {
        self.lp.reset();
        self.skip = 0;
        self.out.clear();
    }
}

/// The streaming post-processing of a pitch track: per hop, its RMS and raw pitch through
/// the gate, the Tukey fences, the range (the paper's running range or the prior-padded
/// one, by the level rule) and the discretizer to a level, and the levels through the
/// binner to bins. Every stage is a [`HopFilter`]: one reset, latencies that add up.
struct LevelChain {
    gate: StreamingGate,
    tukey: SlidingTukey,
    range: RunningRange,
    prior_range: HeldRange,
    /// The same range of the sure hops only, and the rule that narrows `prior_range` to it
    /// (a track with a [`SureRule`]; README, "The mix's lead range narrowed to sure hops").
    sure_range: Option<(HeldRange, SureRule)>,
    rule: LevelRule,
    disc: Discretizer,
    binner: LevelBinner,
}

impl LevelChain {
    /// Hop `i`: returns its pitch after gate and fences and its level; completed bins go to
    /// `bins`.
    /// Hop `i`'s gate and fences: its pitch after both, and whether the gate is open.
    fn fence(&mut self, rms_db: f32, raw_f0: f32) -> (f32, bool) {
        let open = self.gate.process(rms_db);
        (self.tukey.process(if open { raw_f0 } else { 0.0 }), open)
    }

    /// Hop `i`'s level from its fenced pitch `f0` (`trusted`: a second tracker agrees,
    /// [`HeldRange::update_trusted`]; `sure`: the learned tracker is sure of it, for a track
    /// with a [`SureRule`]); completed bins go to `bins`.
    fn level(&mut self, i: usize, f0: f32, trusted: bool, sure: bool, bins: &mut Vec<u8>) -> u8 {
        let range = match self.rule {
            LevelRule::Paper => self.range.update(f0),
            LevelRule::Follow => {
                let r = self.prior_range.update_trusted(f0, trusted);
                match &mut self.sure_range {
                    // Narrowed once the sure hops hold a range of their own.
                    Some((sr, rule)) => {
                        let s = sr.update_sure(f0, trusted, sure);
                        if sr.holds() {
                            narrow_range(r, s, rule.below_st, rule.above_st)
                        } else {
                            r
                        }
                    }
                    None => r,
                }
            }
        };
        let level = range.map_or(0, |r| self.disc.level(f0, r));
        self.binner.push(i, level, &mut |_, l| bins.push(l));
        level
    }

    fn reset(&mut self) {
        let stages: [&mut dyn Reset; 6] = [
            &mut self.gate,
            &mut self.tukey,
            &mut self.range,
            &mut self.prior_range,
            &mut self.disc,
            &mut self.binner,
        ];
        stages.into_iter().for_each(|s| s.reset());
        if let Some((sr, _)) = &mut self.sure_range {
            sr.reset();
        }
    }

    /// The sum of the latencies of the stages a hop goes through.
    fn latency_samples(&self) -> usize {
        let range = match self.rule {
            LevelRule::Paper => self.range.latency_samples(),
            LevelRule::Follow => self.prior_range.latency_samples(),
        };
        self.gate.latency_samples()
            + self.tukey.latency_samples()
            + range
            + self.disc.latency_samples()
            + self.binner.latency_samples()
    }
}

/// The streaming level range of a track: `prior` (and its fade) padding the quantile-`p`
/// range of the hops held as `levels` says, octave shadows within its window left out.
fn held_range(
    levels: &LevelRecipe,
    prior: (RangePrior, f32),
    p: f32,
) -> Result<HeldRange, ConfigError> {
    HeldRange::with_prior(
        prior.0,
        prior.1,
        p,
        levels.held_hops,
        levels.held_tol_st,
        levels.held_min_share,
        levels.held_min_hops,
    )?
    .with_shadow(levels.shadow_hops)
}

/// The harmonic-sum tracker's configuration for `tuning` over the range and hops of `yc`:
/// the bass or the melody defaults of `tactus_dsp::shs`, then the tuning's settings.
fn shs_config(tuning: &ShsTuning, yc: &YinConfig, lag_hops: usize) -> ShsConfig {
    let (rate, fmin_hz, fmax_hz) = (yc.sample_rate, yc.fmin_hz, yc.fmax_hz);
    let mut sc = if tuning.melody {
        ShsConfig::melody(rate, fmin_hz, fmax_hz)
    } else {
        ShsConfig::new(rate, fmin_hz, fmax_hz)
    };
    sc.hop = yc.hop;
    sc.lag_hops = lag_hops;
    if let Some(h) = tuning.harmonics {
        sc.harmonics = h;
    }
    sc.fundamental_ratio = tuning.fundamental_ratio;
    sc.contour_gate_db = tuning.contour_gate_db;
    sc.register_sigma_st = tuning.register_sigma_st;
    sc.attack_rise_db = tuning.attack_rise_db;
    sc.attack_salience_ratio = tuning.attack_salience_ratio;
    sc.learned = tuning.network != Network::None;
    sc.learned_harmonic = tuning.network.harmonic();
    sc.learned_ensemble = tuning.network.ensemble();
    sc.learned_blend = tuning.learned_blend;
    sc.learned_voicing_nats = tuning.learned_voicing_nats;
    sc
}

/// [`HopFilter::reset`] for a chain whose stages have different value types.
trait Reset {
    fn reset(&mut self);
}

impl<F: HopFilter> Reset for F {
    fn reset(&mut self) {
        HopFilter::reset(self)
    }
}

/// The tracker of a [`PitchTrack`]: one; a voicing/pitch pair whose voicing tracker's own
/// pitch is kept beside the pair's ([`PitchTrack::voicing_f0`]); or a harmonic-sum tracker
/// with the attack alignment whose decoded pitch is kept beside its reported one
/// ([`PitchTrack::note_f0`]).
enum Tracker {
    One(Box<dyn HopStage<Out = PitchEstimate>>),
    Pair(Box<VoicingPitchPair>),
    Aligned(Box<Shs>),
    /// The learned bass tracker whose network reads the harmonic view
    /// ([`tactus_dsp::shs::Shs::process_view`]).
    View(Box<Shs>),
}

impl Tracker {
    /// The tracker `recipe` names, over the range and hops of `yc` (the decimated rate),
    /// with a fixed Viterbi lag of `lag_hops` for pYIN and the harmonic-sum trackers.
    fn new(recipe: &TrackerRecipe, yc: &YinConfig, lag_hops: usize) -> Result<Self, ConfigError> {
        let shs = |t: &ShsTuning| Shs::new(shs_config(t, yc, lag_hops));
        Ok(match recipe {
            TrackerRecipe::Yin => Tracker::One(Box::new(Yin::new(yc.clone())?)),
            TrackerRecipe::Pyin => {
                let mut pc = PyinConfig::new(yc.sample_rate, yc.fmin_hz, yc.fmax_hz);
                pc.yin = yc.clone();
                pc.lag_hops = lag_hops;
                Tracker::One(Box::new(Pyin::new(pc)?))
            }
            TrackerRecipe::Shs(t) => Tracker::One(Box::new(shs(t)?)),
            TrackerRecipe::Aligned(t) => Tracker::Aligned(Box::new(shs(t)?)),
            TrackerRecipe::View(t) => Tracker::View(Box::new(shs(t)?)),
            TrackerRecipe::Pair { voicing, pitch } => Tracker::Pair(Box::new(
                VoicingPitchPair::new(Box::new(shs(voicing)?), Box::new(shs(pitch)?))?.with_veto(),
            )),
        })
    }

    /// Feeds a block; `emit(f0, side_f0, confidence)` per hop (`side_f0` for a pair or an
    /// aligned tracker; `confidence` = 1 − the estimate's aperiodicity, for a pair the
    /// learned tracker's confidence in its pitch). `view`: the same span of the harmonic view, which a pair's pitch tracker
    /// reads instead of `x` and a view tracker's network reads beside it (`None`: `x`).
    fn process(
        &mut self,
        x: &[f32],
        view: Option<&[f32]>,
        emit: &mut dyn FnMut(f32, Option<f32>, f32),
    ) {
        let c = |e: PitchEstimate| 1.0 - e.aperiodicity;
        match self {
            Tracker::One(t) => t.process(x, &mut |_, e| emit(e.f0_hz, None, c(e))),
            Tracker::Pair(p) => p.process_two(x, view.unwrap_or(x), &mut |_, e, v| {
                emit(e.f0_hz, Some(v.f0_hz), c(e))
            }),
            Tracker::Aligned(t) => {
                t.process_both(x, &mut |_, e, d| emit(e.f0_hz, Some(d.f0_hz), c(e)))
            }
            Tracker::View(t) => t.process_view(x, view.unwrap_or(x), &mut |_, e, _| {
                emit(e.f0_hz, None, c(e))
            }),
        }
    }

    fn finish(&mut self, emit: &mut dyn FnMut(f32, Option<f32>, f32)) {
        let c = |e: PitchEstimate| 1.0 - e.aperiodicity;
        match self {
            Tracker::One(t) => t.finish(&mut |_, e| emit(e.f0_hz, None, c(e))),
            Tracker::Pair(p) => p.finish_both(&mut |_, e, v| emit(e.f0_hz, Some(v.f0_hz), c(e))),
            Tracker::Aligned(t) => t.finish_both(&mut |_, e, d| emit(e.f0_hz, Some(d.f0_hz), c(e))),
            Tracker::View(t) => t.finish_view(&mut |_, e, _| emit(e.f0_hz, None, c(e))),
        }
    }

    fn reset(&mut self) {
        match self {
            Tracker::One(t) => t.reset(),
            Tracker::Pair(p) => p.reset(),
            Tracker::Aligned(t) | Tracker::View(t) => t.reset(),
        }
    }

    fn latency_samples(&self) -> usize {
        match self {
            Tracker::One(t) => t.latency_samples(),
            Tracker::Pair(p) => p.latency_samples(),
            Tracker::Aligned(t) | Tracker::View(t) => t.latency_samples(),
        }
    }
}

/// A pair's voicing-tracker pitch through the same gate decisions and its own fences
/// ([`PitchTrack::voicing_f0`]), against which the level range checks agreement.
struct NoteSide {
    /// Raw voicing-tracker pitch per hop (kept like `PitchTrack::raw_f0`).
    raw: Vec<f32>,
    skipped: usize,
    tukey: SlidingTukey,
    /// After gate and fences, like `PitchTrack::f0`.
    f0: Vec<f32>,
}

/// Pitch feature track of one melodic stem.
pub struct PitchTrack {
    decimator: Decimator,
    /// The harmonic view's decimator ([`PitchTrack::new_harmonic_view`]): the pair's pitch
    /// tracker reads the separator's harmonic sum, decimated like the stem.
    view: Option<Decimator>,
    tracker: Tracker,
    /// With a pair: the voicing tracker's pitch for note onsets.
    note_side: Option<NoteSide>,
    rms: Rms,
    hop: usize,
    geo: Geometry,
    /// Raw tracker output per hop (Hz, 0 = unvoiced): every hop offline, only the hops not
    /// yet consumed in streaming mode.
    pub raw_f0: Vec<f32>,
    /// RMS per hop in dBFS (kept like `raw_f0`).
    pub raw_rms: Vec<f32>,
    /// Streaming: the next hop for the chain.
    next: usize,
    chain: LevelChain,
    /// IQR floor of the fences (0 under the paper's rule).
    min_iqr_st: f32,
    /// How the level range is chosen (held hops, octave shadows, agreement, ...).
    levels: LevelRecipe,
    /// The tracker's confidence in its pitch per hop (`1 −` aperiodicity; kept like
    /// `raw_f0`, only for a track with a [`SureRule`], [`PitchTrack::sure_rule`]).
    raw_conf: Vec<f32>,
    skipped_conf: usize,
    /// f0 per hop after gate and fences (streaming: filled as hops arrive; offline: at the end).
    pub f0: Vec<f32>,
    /// The stem's RMS per hop in dBFS, beside `f0` (same hops, before the gate): what note
    /// onsets read for re-attacks.
    pub level_db: Vec<f32>,
    /// Level per hop.
    pub hop_levels: Vec<u8>,
    /// Level per bin.
    pub bins: Vec<u8>,
    /// Hops of the tracker's (and the RMS's) output dropped at the start and padded at the
    /// end ([`PitchTrack::set_advance_hops`]).
    advance: usize,
    skipped_f0: usize,
    skipped_rms: usize,
}

impl PitchTrack {
    /// A pitch track as `recipe` says: its search range, tracker, level range and advance
    /// ([`crate::recipe`]). A track whose recipe reads the harmonic view
    /// ([`Recipe::harmonic_view`]: the separator's harmonic sum, vocals + bass + other) is fed
    /// it beside the stem through [`PitchTrack::process_view`], decimated the same way;
    /// [`PitchTrack::process`] feeds the stem as its own view.
    pub fn new(geo: Geometry, recipe: &Recipe) -> Result<Self, ConfigError> {
        let (fmin_hz, fmax_hz) = recipe.range_hz;
        let factor = Decimator::factor_for(geo.sample_rate, fmax_hz);
        let rate = geo.sample_rate / factor as u32;
        let mut yc = YinConfig::new(rate, fmin_hz, fmax_hz);
        // The live profile: two periods of fmin per frame (and, from the recipe, a short
        // Viterbi lag).
        let live = geo.profile == crate::profile::Profile::Live;
        if live {
            yc.frame = crate::profile::pitch_frame(rate, fmin_hz);
        }
        // The tracker and the RMS run at the decimated rate; the binner and the time
        // stamps use engine-rate samples (`hop = yc.hop * factor`).
        let hop = yc.hop * factor;
        // Live YIN over more than an octave: a short frame for all but the lowest octave
        // (`tactus_dsp::twoframe`); its frame also sets the level's window below.
        let split_hz = crate::profile::TWO_FRAME_SPLIT * fmin_hz;
        let two_frame = live && recipe.tracker == TrackerRecipe::Yin && split_hz < fmax_hz;
        let short_frame = crate::profile::pitch_frame(rate, split_hz);
        let frame = if two_frame { short_frame } else { yc.frame };
        let tracker = if two_frame {
            Tracker::One(Box::new(TwoFrameYin::new(
                yc.clone(),
                split_hz,
                short_frame,
            )?))
        } else {
            Tracker::new(&recipe.tracker, &yc, recipe.lag_hops)?
        };
        let hop_s = hop as f32 / geo.sample_rate as f32;
        let levels = recipe.levels.clone();
        // The streaming range's prior: under the follow rule the instrument's register where
        // it has one, otherwise a span around the first notes.
        let prior = match (geo.level_rule, levels.register_hz) {
            (LevelRule::Follow, Some((lo, hi))) => {
                (RangePrior::Register(lo, hi), levels.register_fade_hops)
            }
            _ => (
                RangePrior::Span(levels.prior_span_st),
                levels.prior_fade_hops,
            ),
        };
        let min_iqr_st = match geo.level_rule {
            LevelRule::Paper => 0.0,
            LevelRule::Follow => levels.min_iqr_st,
        };
        let note_side = match tracker {
            Tracker::Pair(_) | Tracker::Aligned(_) => Some(NoteSide {
                raw: Vec::new(),
                skipped: 0,
                tukey: SlidingTukey::new(TUKEY_WINDOW_HOPS, TUKEY_K, TUKEY_MIN_COUNT)?
                    .with_min_iqr(min_iqr_st),
                f0: Vec::new(),
            }),
            Tracker::One(_) | Tracker::View(_) => None,
        };
        Ok(PitchTrack {
            decimator: Decimator::new(geo.sample_rate, factor)?,
            view: if recipe.harmonic_view {
                Some(Decimator::new(geo.sample_rate, factor)?)
            } else {
                None
            },
            tracker,
            note_side,
            rms: Rms::new(frame.min(4 * yc.hop).max(yc.hop), yc.hop)?,
            hop,
            geo,
            raw_f0: Vec::new(),
            raw_rms: Vec::new(),
            next: 0,
            chain: LevelChain {
                gate: StreamingGate::new(GATE_BELOW_DB, GATE_DECAY_DB_PER_S, hop_s)?,
                tukey: SlidingTukey::new(TUKEY_WINDOW_HOPS, TUKEY_K, TUKEY_MIN_COUNT)?
                    .with_min_iqr(min_iqr_st),
                range: RunningRange::new(),
                prior_range: held_range(&levels, prior, levels.quantile)?,
                sure_range: match levels.sure {
                    Some(rule) => Some((held_range(&levels, prior, rule.quantile)?, rule)),
                    None => None,
                },
                rule: geo.level_rule,
                disc: Discretizer::new(geo.levels, Scale::Semitones)?,
                binner: LevelBinner::new(hop, geo.bin_samples)?,
            },
            min_iqr_st,
            levels,
            raw_conf: Vec::new(),
            skipped_conf: 0,
            f0: Vec::new(),
            level_db: Vec::new(),
            hop_levels: Vec::new(),
            bins: Vec::new(),
            advance: recipe.advance_hops,
            skipped_f0: 0,
            skipped_rms: 0,
        })
    }

    /// Leans the streaming range ([`LevelRule::Follow`]) on an instrument's register
    /// `(lo_hz, hi_hz)` instead of the prior span ([`RangePrior::Register`], fading over
    /// [`LevelRecipe::register_fade_hops`]). Offline output is unchanged. Call before the
    /// first block. (The engine's tracks get their register from their recipe.)
    pub fn set_register_prior(&mut self, register_hz: (f32, f32)) -> Result<(), ConfigError> {
        let prior = (
            RangePrior::Register(register_hz.0, register_hz.1),
            self.levels.register_fade_hops,
        );
        self.chain.prior_range = held_range(&self.levels, prior, self.levels.quantile)?;
        if let Some((sr, rule)) = &mut self.chain.sure_range {
            *sr = held_range(&self.levels, prior, rule.quantile)?;
        }
        Ok(())
    }

    /// Moves the whole track `hops` hops earlier: what the tracker reports for hop
    /// `i + hops` is hop `i` (the last `hops` hops are unvoiced). For a stem whose separator
    /// delays notes more than its stated latency ([`SPECTRAL_PITCH_ADVANCE_HOPS`]); the
    /// track's latency grows by as much. Call before the first block.
    pub fn set_advance_hops(&mut self, hops: usize) {
        self.advance = hops;
    }

    /// Hops the track is moved earlier ([`PitchTrack::set_advance_hops`]).
    pub fn advance_hops(&self) -> usize {
        self.advance
    }

    /// Samples between hops.
    pub fn hop(&self) -> usize {
        self.hop
    }

    /// Input samples (engine rate) of look-ahead this track needs before hop `i` is final.
    pub fn latency_samples(&self) -> usize {
        self.tracker
            .latency_samples()
            .max(self.rms.latency_samples())
            * self.decimator.factor
            + self.advance * self.hop
    }

    /// Samples the streaming post-processing (gate → fences → range → discretizer →
    /// binner) holds a hop back, summed from its stages: the binner's wait for the rest of
    /// a bin.
    pub fn level_latency_samples(&self) -> usize {
        self.chain.latency_samples()
    }

    /// Decimation factor in front of the tracker.
    pub fn decimation(&self) -> usize {
        self.decimator.factor
    }

    /// Feeds a block of the (denoised) stem. A harmonic-view track
    /// ([`PitchTrack::new_harmonic_view`]) fed this way reads the stem as its view too.
    pub fn process(&mut self, block: &[f32]) {
        self.process_view(block, block);
    }

    /// Feeds a block of the (denoised) stem and, for a harmonic-view track, the same span
    /// of its view (the separator's harmonic sum, denoised like the stem; as many samples).
    /// Other tracks ignore `view`.
    pub fn process_view(&mut self, block: &[f32], view: &[f32]) {
        self.decimator.process(block);
        let block = self.decimator.output();
        let view = match &mut self.view {
            Some(d) => {
                d.process(view);
                Some(d.output())
            }
            None => None,
        };
        let (raw_f0, skipped, advance) = (&mut self.raw_f0, &mut self.skipped_f0, self.advance);
        let side = &mut self.note_side;
        let (conf, skipped_conf) = (&mut self.raw_conf, &mut self.skipped_conf);
        let keep_conf = self.chain.sure_range.is_some();
        self.tracker.process(block, view, &mut |f, nf, c| {
            advanced_push(raw_f0, skipped, advance, f);
            if keep_conf {
                advanced_push(conf, skipped_conf, advance, c);
            }
            if let (Some(s), Some(nf)) = (side.as_mut(), nf) {
                advanced_push(&mut s.raw, &mut s.skipped, advance, nf);
            }
        });
        let (raw_rms, skipped) = (&mut self.raw_rms, &mut self.skipped_rms);
        self.rms.process(block, &mut |_, r| {
            advanced_push(raw_rms, skipped, advance, r)
        });
        self.post_streaming();
    }

    /// Ends the stream (and, offline, computes the whole-track statistics).
    pub fn finish(&mut self) {
        let (raw_f0, skipped, advance) = (&mut self.raw_f0, &mut self.skipped_f0, self.advance);
        let side = &mut self.note_side;
        let (conf, skipped_conf) = (&mut self.raw_conf, &mut self.skipped_conf);
        let keep_conf = self.chain.sure_range.is_some();
        self.tracker.finish(&mut |f, nf, c| {
            advanced_push(raw_f0, skipped, advance, f);
            if keep_conf {
                advanced_push(conf, skipped_conf, advance, c);
            }
            if let (Some(s), Some(nf)) = (side.as_mut(), nf) {
                advanced_push(&mut s.raw, &mut s.skipped, advance, nf);
            }
        });
        // The advanced track ends as long as it would have: the dropped hops come back
        // unvoiced and silent at the end.
        raw_f0.extend(std::iter::repeat_n(0.0, *skipped));
        if let Some(s) = side {
            s.raw.extend(std::iter::repeat_n(0.0, s.skipped));
        }
        if keep_conf {
            conf.extend(std::iter::repeat_n(0.0, *skipped_conf));
        }
        let (raw_rms, skipped) = (&mut self.raw_rms, &mut self.skipped_rms);
        self.rms
            .finish(&mut |_, r| advanced_push(raw_rms, skipped, advance, r));
        raw_rms.extend(std::iter::repeat_n(ADVANCE_PAD_DB, *skipped));
        self.post_streaming();
        let bins = &mut self.bins;
        self.chain.binner.finish(&mut |_, l| bins.push(l));
        if self.geo.mode == Mode::Offline {
            self.post_offline();
        }
    }

    fn post_streaming(&mut self) {
        if self.geo.mode != Mode::Streaming {
            return;
        }
        // Streaming keeps only the raw hops not yet consumed (memory stays flat however
        // long the stream): `raw_*[j]` is hop `next + j`.
        let ready = self.raw_f0.len().min(self.raw_rms.len());
        for j in 0..ready {
            let (f0, open) = self.chain.fence(self.raw_rms[j], self.raw_f0[j]);
            let mut trusted = false;
            if let Some(s) = &mut self.note_side {
                let nf = s.raw.get(j).copied().unwrap_or(0.0);
                let nf = s.tukey.process(if open { nf } else { 0.0 });
                s.f0.push(nf);
                trusted = self
                    .levels
                    .agree_tol_st
                    .is_some_and(|tol| pitches_agree(f0, nf, tol));
            }
            let sure = self
                .sure_rule()
                .is_some_and(|r| self.raw_conf.get(j).copied().unwrap_or(0.0) >= r.min_conf);
            let level = self
                .chain
                .level(self.next, f0, trusted, sure, &mut self.bins);
            self.f0.push(f0);
            self.level_db.push(self.raw_rms[j]);
            self.hop_levels.push(level);
            self.next += 1;
        }
        self.raw_f0.drain(..ready);
        self.raw_rms.drain(..ready);
        if let Some(s) = &mut self.note_side {
            s.raw.drain(..ready.min(s.raw.len()));
        }
        self.raw_conf.drain(..ready.min(self.raw_conf.len()));
    }

    fn post_offline(&mut self) {
        let n = self.raw_f0.len().min(self.raw_rms.len());
        let mut open = vec![false; n];
        gate_offline(&self.raw_rms[..n], GATE_BELOW_DB, &mut open);
        let mut f0: Vec<f32> = (0..n)
            .map(|i| if open[i] { self.raw_f0[i] } else { 0.0 })
            .collect();
        reject_outliers_offline_min_iqr(&mut f0, TUKEY_K, self.min_iqr_st);
        if let Some(s) = &mut self.note_side {
            let mut nf: Vec<f32> = (0..n)
                .map(|i| {
                    if open[i] {
                        s.raw.get(i).copied().unwrap_or(0.0)
                    } else {
                        0.0
                    }
                })
                .collect();
            reject_outliers_offline_min_iqr(&mut nf, TUKEY_K, self.min_iqr_st);
            s.f0 = nf;
        }
        let trusted = match (&self.note_side, self.levels.agree_tol_st) {
            (Some(s), Some(tol)) => agree_mask(&f0, &s.f0, tol),
            _ => Vec::new(),
        };
        let kept = |sure: &[bool], p: f32| {
            range_quantiles_kept_or_sure(
                &f0,
                &trusted,
                sure,
                p,
                self.levels.held_hops,
                self.levels.held_tol_st,
                self.levels.shadow_hops,
                self.levels.held_min_share,
                self.levels.held_min_hops,
            )
        };
        let r = match (self.geo.level_rule, self.sure_rule()) {
            (LevelRule::Paper, _) => range_offline(&f0),
            // Narrowed to the hops the learned tracker is sure of ([`MIX_LEAD_SURE`],
            // [`MIX_BASS_SURE`]).
            (LevelRule::Follow, Some(rule)) => {
                let sure: Vec<bool> = (0..n)
                    .map(|i| self.raw_conf.get(i).copied().unwrap_or(0.0) >= rule.min_conf)
                    .collect();
                narrow_range(
                    kept(&[], self.levels.quantile),
                    kept(&sure, rule.quantile),
                    rule.below_st,
                    rule.above_st,
                )
            }
            (LevelRule::Follow, None) => kept(&[], self.levels.quantile),
        };
        let levels: Vec<u8> = match r {
            Some(r) => f0.iter().map(|&f| self.chain.disc.level(f, r)).collect(),
            None => vec![0; n],
        };
        self.bins = bin_levels(&levels, self.hop, self.geo.bin_samples);
        self.f0 = f0;
        self.level_db = self.raw_rms[..n].to_vec();
        self.hop_levels = levels;
    }

    /// The rule that narrows this track's level range to its sure hops ([`MIX_LEAD_SURE`],
    /// [`MIX_BASS_SURE`]), kept with the streaming range it narrows to.
    fn sure_rule(&self) -> Option<SureRule> {
        self.chain.sure_range.as_ref().map(|&(_, r)| r)
    }

    /// Per-hop and per-bin values held (what [`crate::Engine::retained_values`] sums).
    pub fn retained(&self) -> usize {
        self.bins.len()
            + self.f0.len()
            + self.level_db.len()
            + self.hop_levels.len()
            + self.raw_f0.len()
            + self.raw_rms.len()
            + self
                .note_side
                .as_ref()
                .map_or(0, |s| s.raw.len() + s.f0.len())
            + self.raw_conf.len()
    }

    /// For a voicing/pitch pair its voicing tracker's own pitch, per hop (after gate and
    /// fences), which the lead's level range compares with [`PitchTrack::f0`] ("agreed
    /// hops"); for any other tracker, [`PitchTrack::f0`]. Note onsets read
    /// [`PitchTrack::note_f0`]: the pair's pitch (since 2026-11-28,
    /// `benches/trials/RULE_lead_onsets_pair.md`), or an aligned tracker's decoded pitch.
    pub fn voicing_f0(&self) -> &[f32] {
        match (&self.tracker, &self.note_side) {
            (Tracker::Pair(_), Some(s)) => &s.f0,
            _ => &self.f0,
        }
    }

    /// For a track whose level range is narrowed to sure hops (a mixture's lead
    /// through the pair, [`MIX_LEAD_SURE`]; a mixture's learned bass, [`MIX_BASS_SURE`]),
    /// the learned tracker's confidence in its pitch per hop (`1 −` the estimate's
    /// aperiodicity, `tactus_dsp::shs` module docs, "Learned salience"; for the pair the
    /// merged estimate's, which is the pitch tracker's), as the tracker gave it, before gate
    /// and fences: offline every hop, streaming only the hops not yet consumed. Empty for
    /// any other track.
    pub fn pitch_confidence(&self) -> &[f32] {
        &self.raw_conf
    }

    /// The pitch the note onsets read, per hop (after gate and fences): for a tracker with
    /// the attack alignment its decoded pitch, before the alignment (the note detector
    /// looks for the attack itself); otherwise [`PitchTrack::f0`].
    pub fn note_f0(&self) -> &[f32] {
        match (&self.tracker, &self.note_side) {
            (Tracker::Aligned(_), Some(s)) => &s.f0,
            _ => &self.f0,
        }
    }

    /// The guide pitch of the note onsets, per hop (after gate and fences;
    /// `tactus_dsp::notes::NoteConfig::guide_back_hops`): for a tracker with the attack alignment
    /// its aligned pitch ([`PitchTrack::f0`]), beside the decoded one that
    /// [`PitchTrack::note_f0`] gives; empty for any other tracker.
    pub fn note_guide(&self) -> &[f32] {
        match (&self.tracker, &self.note_side) {
            (Tracker::Aligned(_), Some(_)) => &self.f0,
            _ => &[],
        }
    }

    /// Back to the initial state.
    pub fn reset(&mut self) {
        self.decimator.reset();
        if let Some(d) = &mut self.view {
            d.reset();
        }
        self.tracker.reset();
        self.rms.reset();
        self.raw_f0.clear();
        self.raw_rms.clear();
        self.next = 0;
        self.chain.reset();
        self.f0.clear();
        self.level_db.clear();
        self.hop_levels.clear();
        self.bins.clear();
        self.skipped_f0 = 0;
        self.skipped_rms = 0;
        if let Some(s) = &mut self.note_side {
            s.raw.clear();
            s.skipped = 0;
            s.tukey.reset();
            s.f0.clear();
        }
    }
}

impl Track for PitchTrack {
    fn process(&mut self, input: &TrackInput<'_>) {
        self.process_view(input.stem, input.side.unwrap_or(input.stem));
    }

    fn finish(&mut self, _: &TrackInput<'_>) {
        PitchTrack::finish(self);
    }

    fn reset(&mut self) {
        PitchTrack::reset(self);
    }

    fn latency_samples(&self) -> usize {
        PitchTrack::latency_samples(self)
    }

    fn discard_before(&mut self, bins: usize) {
        self.bins.drain(..bins.min(self.bins.len()));
        self.f0.clear();
        if let Some(s) = &mut self.note_side {
            s.f0.clear();
        }
        self.level_db.clear();
        self.hop_levels.clear();
    }

    fn feature(&self) -> Feature {
        Feature::Level
    }

    fn ready_bins(&self) -> usize {
        self.bins.len()
    }

    fn read_bin(&self, bin: usize, _hold: usize, stem: Stem, frame: &mut BinFeatures) {
        frame.level[stem as usize] = self.bins.get(bin).copied().unwrap_or(0);
    }

    fn retained(&self) -> usize {
        PitchTrack::retained(self)
    }
}

/// Level (dBFS) of the hops that an advanced track pads at its end: below any gate.
const ADVANCE_PAD_DB: f32 = -200.0;

/// Pushes `v` unless it is one of the first `advance` values (counted in `skipped`).
fn advanced_push(out: &mut Vec<f32>, skipped: &mut usize, advance: usize, v: f32) {
    if *skipped < advance {
        *skipped += 1;
    } else {
        out.push(v);
    }
}

/// Onset feature track: a drum band, or note onsets of a melodic stem.
pub struct OnsetTrack {
    det: OnsetDetector,
    rms: Rms,
    hop: usize,
    geo: Geometry,
    /// Raw onset flag per hop: every hop offline, only the hops not yet consumed in
    /// streaming mode.
    pub raw_onset: Vec<bool>,
    /// RMS per hop in dBFS (kept like `raw_onset`).
    pub raw_rms: Vec<f32>,
    next: usize,
    gate: StreamingGate,
    /// The live profile's rise test: the levels of the last [`RISE_HOPS`] hops (dBFS).
    recent_rms: [f32; RISE_HOPS],
    /// Gated onset flags per hop and beats per bin.
    pub beats: Beats,
}

impl OnsetTrack {
    /// An onset track with the causal (streaming) or look-ahead (offline) detector, its
    /// flux restricted to `band_hz` when given (a drum band's own bins).
    pub fn new(geo: Geometry, band_hz: Option<(f32, f32)>) -> Result<Self, ConfigError> {
        let mut cfg = match geo.mode {
            Mode::Streaming => OnsetConfig::causal(geo.sample_rate),
            Mode::Offline => OnsetConfig::lookahead(geo.sample_rate),
        };
        cfg.band_hz = band_hz;
        let hop = cfg.hop;
        let frame = cfg.frame;
        let hop_s = hop as f32 / geo.sample_rate as f32;
        // The gate's level: over the flux frame, or in the live profile over two hops
        // centred on the hop (latency one hop, 5 ms, instead of half the frame, 11.6 ms;
        // the hop after an onset still holds the hit's energy).
        let rms_frame = match geo.profile {
            crate::profile::Profile::Full => frame.max(hop),
            crate::profile::Profile::Live => 2 * hop,
        };
        Ok(OnsetTrack {
            det: OnsetDetector::new(cfg)?,
            rms: Rms::new(rms_frame, hop)?,
            hop,
            geo,
            raw_onset: Vec::new(),
            raw_rms: Vec::new(),
            next: 0,
            gate: StreamingGate::new(GATE_BELOW_DB, GATE_DECAY_DB_PER_S, hop_s)?,
            recent_rms: [tactus_dsp::rms::SILENCE_DB; RISE_HOPS],
            beats: Beats::new(hop, geo.bin_samples)?,
        })
    }

    /// Samples between hops.
    pub fn hop(&self) -> usize {
        self.hop
    }

    /// Input samples of look-ahead this track needs.
    pub fn latency_samples(&self) -> usize {
        self.det.latency_samples().max(self.rms.latency_samples())
    }

    /// Feeds a block.
    pub fn process(&mut self, block: &[f32]) {
        let raw = &mut self.raw_onset;
        self.det
            .process(block, &mut |_, f: OnsetFrame| raw.push(f.onset));
        let raw_rms = &mut self.raw_rms;
        self.rms.process(block, &mut |_, r| raw_rms.push(r));
        self.post_streaming();
    }

    /// Ends the stream.
    pub fn finish(&mut self) {
        let raw = &mut self.raw_onset;
        self.det.finish(&mut |_, f: OnsetFrame| raw.push(f.onset));
        let raw_rms = &mut self.raw_rms;
        self.rms.finish(&mut |_, r| raw_rms.push(r));
        self.post_streaming();
        self.beats.finish();
        if self.geo.mode == Mode::Offline {
            let n = self.raw_onset.len().min(self.raw_rms.len());
            let mut open = vec![false; n];
            gate_offline(&self.raw_rms[..n], GATE_BELOW_DB, &mut open);
            let onsets = (0..n).map(|i| self.raw_onset[i] && open[i]).collect();
            self.beats
                .set_offline(onsets, self.hop, self.geo.bin_samples);
        }
    }

    fn post_streaming(&mut self) {
        if self.geo.mode != Mode::Streaming {
            return;
        }
        // As in `PitchTrack`: only unconsumed raw hops are kept; `raw_*[j]` is hop `next + j`.
        let ready = self.raw_onset.len().min(self.raw_rms.len());
        let live = self.geo.profile == crate::profile::Profile::Live;
        for j in 0..ready {
            let i = self.next;
            let level = self.raw_rms[j];
            let open = self.gate.process(level);
            // The live profile's rise test: an onset is where the level rises, at least
            // RISE_DB above the quietest of the last RISE_HOPS hops. Its short gate level
            // (two hops) lets the causal picker fire again in a hit's decaying tail (the
            // flux threshold's 100 ms mean forgets the hit); the tail never rises.
            let rises = !live
                || level - self.recent_rms.iter().fold(f32::INFINITY, |a, &b| a.min(b)) >= RISE_DB;
            self.recent_rms[i % RISE_HOPS] = level;
            self.beats.push(i, open && self.raw_onset[j] && rises);
            self.next += 1;
        }
        self.raw_onset.drain(..ready);
        self.raw_rms.drain(..ready);
    }

    /// Onset times in seconds (after the gate).
    pub fn onset_times(&self) -> Vec<f64> {
        onset_times(&self.beats.onsets, self.hop, self.geo.sample_rate)
    }

    /// Per-hop and per-bin values held.
    pub fn retained(&self) -> usize {
        self.beats.retained() + self.raw_onset.len() + self.raw_rms.len()
    }

    /// Streaming: forgets the first `d` bins and the per-hop onsets already binned.
    pub fn discard(&mut self, d: usize) {
        self.beats.discard(d);
    }

    /// Back to the initial state.
    pub fn reset(&mut self) {
        self.det.reset();
        self.rms.reset();
        self.raw_onset.clear();
        self.raw_rms.clear();
        self.next = 0;
        self.gate.reset();
        self.recent_rms = [tactus_dsp::rms::SILENCE_DB; RISE_HOPS];
        self.beats.reset();
    }
}

/// Onset flags per hop and the beats they make per bin (a bin is a beat when one of its
/// hops is an onset): what an onset track and a stem's note onsets keep.
pub struct Beats {
    binner: BeatBinner,
    /// Onset flag per hop (streaming: the hops not yet discarded).
    pub onsets: Vec<bool>,
    /// Beat per bin.
    pub bins: Vec<bool>,
}

impl Beats {
    /// Hops of `hop` samples into bins of `bin_samples`.
    pub fn new(hop: usize, bin_samples: usize) -> Result<Self, ConfigError> {
        Ok(Beats {
            binner: BeatBinner::new(hop, bin_samples)?,
            onsets: Vec::new(),
            bins: Vec::new(),
        })
    }

    /// Streaming: hop `i`'s onset flag; a bin it completes is added.
    pub fn push(&mut self, i: usize, onset: bool) {
        self.onsets.push(onset);
        let bins = &mut self.bins;
        self.binner.push(i, onset, &mut |_, b| bins.push(b));
    }

    /// Streaming: adds the last, partial bin.
    pub fn finish(&mut self) {
        let bins = &mut self.bins;
        self.binner.finish(&mut |_, b| bins.push(b));
    }

    /// Offline: every hop's flag at once, binned in one go.
    pub fn set_offline(&mut self, onsets: Vec<bool>, hop: usize, bin_samples: usize) {
        self.bins = bin_beats(&onsets, hop, bin_samples);
        self.onsets = onsets;
    }

    /// Per-hop and per-bin values held.
    pub fn retained(&self) -> usize {
        self.bins.len() + self.onsets.len()
    }

    /// Streaming: forgets the first `d` bins and the onsets already binned.
    pub fn discard(&mut self, d: usize) {
        self.bins.drain(..d.min(self.bins.len()));
        self.onsets.clear();
    }

    /// Back to the just-constructed state.
    pub fn reset(&mut self) {
        self.binner.reset();
        self.onsets.clear();
        self.bins.clear();
    }
}

/// Hops the live profile's onset rise test looks back (4 × 5 ms).
const RISE_HOPS: usize = 4;
/// Level rise (dB) over the quietest of the last [`RISE_HOPS`] hops that the live
/// profile's onsets need.
const RISE_DB: f32 = 3.0;

/// The times, in seconds, of the hops flagged in `onsets` (hops of `hop` samples at `rate`).
pub(crate) fn onset_times(onsets: &[bool], hop: usize, rate: u32) -> Vec<f64> {
    let hop_s = hop as f64 / rate as f64;
    onsets
        .iter()
        .enumerate()
        .filter(|(_, &o)| o)
        .map(|(i, _)| i as f64 * hop_s)
        .collect()
}
