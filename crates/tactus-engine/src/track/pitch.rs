//! The pitch track of a melodic stem: tracker + RMS per hop → gate → fences → levels.

use tactus_dsp::binner::{bin_levels, LevelBinner};
use tactus_dsp::discretize::{
    agree_mask, narrow_range, pitches_agree, range_offline, range_quantiles_kept_or_sure,
    Discretizer, RangePrior, RunningRange, Scale,
};
use tactus_dsp::plain::PlainGuard;
use tactus_dsp::rms::{gate_offline, Rms, StreamingGate, GATE_BELOW_DB};
use tactus_dsp::tukey::{reject_outliers_offline_min_iqr, SlidingTukey, TUKEY_K};
use tactus_dsp::twoframe::TwoFrameYin;
use tactus_dsp::yin::YinConfig;
use tactus_dsp::{ConfigError, HopStage, Stem};
use tactus_glove::BinFeatures;

use super::denoise::Decimator;
use super::levels::{held_range, LevelChain};
use super::tracker::{NoteSide, Tracker};
use super::{Feature, Geometry, LevelRule, Mode, Track, TrackInput, GATE_DECAY_DB_PER_S};
use crate::recipe::{LevelRecipe, Recipe, SureRule, TrackerRecipe};

/// Window of the streaming Tukey fences, in hops (10 s at 10 ms hops).
const TUKEY_WINDOW_HOPS: usize = 1000;
/// Voiced values the streaming fences need before they reject anything.
const TUKEY_MIN_COUNT: usize = 20;
/// Pitch feature track of one melodic stem.
pub struct PitchTrack {
    decimator: Decimator,
    /// The harmonic view's decimator ([`PitchTrack::new_harmonic_view`]): the pair's pitch
    /// tracker reads the separator's harmonic sum, decimated like the stem.
    view: Option<Decimator>,
    tracker: Tracker,
    /// YIN behind a learned tracker on plain tones ([`Recipe::plain_guard`]).
    plain: Option<PlainGuard>,
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
            // The guard reads the stem as the tracker does: decimated, on the same hops.
            plain: if let Some(ceiling_hz) = recipe.plain_guard {
                let tracker_hops = tracker.latency_samples().div_ceil(yc.hop);
                Some(PlainGuard::new(&yc, ceiling_hz, tracker_hops + 4)?)
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
    /// delays notes more than its stated latency ([`Recipe::advance_hops`]); the
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
            .max(self.plain.as_ref().map_or(0, PlainGuard::latency_samples))
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
    /// ([`Recipe::harmonic_view`]) fed this way reads the stem as its view too.
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
        if let Some(g) = self.plain.as_mut() {
            g.process(block);
        }
        let mut sink = hop_sink!(self);
        self.tracker
            .process(block, view, &mut |i, f, nf, c| sink.push(i, f, nf, c));
        let advance = self.advance;
        let (raw_rms, skipped) = (&mut self.raw_rms, &mut self.skipped_rms);
        self.rms.process(block, &mut |_, r| {
            advanced_push(raw_rms, skipped, advance, r)
        });
        self.post_streaming();
    }

    /// Ends the stream (and, offline, computes the whole-track statistics).
    pub fn finish(&mut self) {
        if let Some(g) = self.plain.as_mut() {
            g.finish();
        }
        let mut sink = hop_sink!(self);
        self.tracker
            .finish(&mut |i, f, nf, c| sink.push(i, f, nf, c));
        // The advanced track ends as long as it would have: the dropped hops come back
        // unvoiced and silent at the end.
        sink.pad_end();
        let advance = self.advance;
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
            // Narrowed to the hops the learned tracker is sure of (the recipe's sure rule).
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

    /// The rule that narrows this track's level range to its sure hops
    /// ([`crate::recipe::LevelRecipe::sure`]), kept with the streaming range it narrows to.
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
    /// [`PitchTrack::note_f0`]: the pair's pitch
    /// (`docs/decisions/0034-mix-lead-note-onsets-from-the-pair.md`), or an aligned tracker's
    /// decoded pitch.
    pub fn voicing_f0(&self) -> &[f32] {
        match (&self.tracker, &self.note_side) {
            (Tracker::Pair(_), Some(s)) => &s.f0,
            _ => &self.f0,
        }
    }

    /// For a track whose level range is narrowed to sure hops (a mixture's lead
    /// through the pair, a mixture's learned bass: [`crate::recipe::LevelRecipe::sure`]),
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
        if let Some(g) = &mut self.plain {
            g.reset();
        }
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

/// The [`HopSink`] of a [`PitchTrack`], borrowing only the fields it writes: a macro, so
/// that the tracker and the decimators' outputs stay free to borrow beside it.
macro_rules! hop_sink {
    ($t:expr) => {
        HopSink {
            plain: &mut $t.plain,
            f0: (&mut $t.raw_f0, &mut $t.skipped_f0),
            conf: $t
                .chain
                .sure_range
                .is_some()
                .then_some((&mut $t.raw_conf, &mut $t.skipped_conf)),
            side: &mut $t.note_side,
            advance: $t.advance,
        }
    };
}
use hop_sink;

/// Where the tracker's hops go: through the plain guard, then into the raw tracks, each
/// moved `advance` hops earlier ([`PitchTrack::set_advance_hops`]).
struct HopSink<'a> {
    plain: &'a mut Option<PlainGuard>,
    /// The raw f0 track and the hops of it dropped so far.
    f0: (&'a mut Vec<f32>, &'a mut usize),
    /// The confidence track, kept for a track with a sure rule.
    conf: Option<(&'a mut Vec<f32>, &'a mut usize)>,
    side: &'a mut Option<NoteSide>,
    advance: usize,
}

impl HopSink<'_> {
    /// The tracker's hop `i` (`f0`, side pitch, confidence), or what the guard makes of it
    /// ([`PlainGuard::resolve`]): YIN's f0 (the side pitch too), or unvoiced. The confidence
    /// stays the tracker's: what the level range trusts is still the learned tracker's word
    /// (a kick's decaying body is a plain tone too).
    fn push(&mut self, i: usize, f0: f32, side: Option<f32>, conf: f32) {
        let (f0, side) = match self.plain.as_mut().and_then(|g| g.resolve(i, f0)) {
            Some(f) => (f, side.map(|_| f)),
            None => (f0, side),
        };
        let advance = self.advance;
        advanced_push(self.f0.0, self.f0.1, advance, f0);
        if let Some((c, skipped)) = &mut self.conf {
            advanced_push(c, skipped, advance, conf);
        }
        if let (Some(s), Some(nf)) = (self.side.as_mut(), side) {
            advanced_push(&mut s.raw, &mut s.skipped, advance, nf);
        }
    }

    /// At the end of the stream: the hops dropped at the start come back unvoiced (with no
    /// confidence) at the end.
    fn pad_end(&mut self) {
        self.f0.0.extend(std::iter::repeat_n(0.0, *self.f0.1));
        if let Some(s) = self.side.as_mut() {
            s.raw.extend(std::iter::repeat_n(0.0, s.skipped));
        }
        if let Some((c, skipped)) = &mut self.conf {
            c.extend(std::iter::repeat_n(0.0, **skipped));
        }
    }
}
