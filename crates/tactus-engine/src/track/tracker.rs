//! The pitch trackers a [`super::PitchTrack`] runs, built from a recipe.

use tactus_dsp::pair::{VoicingPitchPair, WithVoicing};
use tactus_dsp::pyin::{Pyin, PyinConfig};
use tactus_dsp::shs::{Shs, ShsConfig, WithDecoded};
use tactus_dsp::tukey::SlidingTukey;
use tactus_dsp::yin::{PitchEstimate, Yin, YinConfig};
use tactus_dsp::{ConfigError, HopStage};

use crate::recipe::{Network, ShsTuning, TrackerRecipe};

/// The harmonic-sum tracker's configuration for `tuning` over the range and hops of `yc`:
/// the bass or the melody defaults of `tactus_dsp::shs`, then the tuning's settings.
pub(super) fn shs_config(tuning: &ShsTuning, yc: &YinConfig, lag_hops: usize) -> ShsConfig {
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
    sc.learned_live = tuning.network.live();
    if sc.learned_live {
        sc.frame = crate::profile::live_net_frame(rate, tuning.melody);
    }
    sc.learned_ensemble = tuning.network.ensemble();
    sc.learned_blend = tuning.learned_blend;
    sc.learned_voicing_nats = tuning.learned_voicing_nats;
    sc
}

/// The tracker of a [`PitchTrack`]: one; a voicing/pitch pair whose voicing tracker's own
/// pitch is kept beside the pair's ([`PitchTrack::voicing_f0`]); or a harmonic-sum tracker
/// with the attack alignment whose decoded pitch is kept beside its reported one
/// ([`PitchTrack::note_f0`]).
pub(super) enum Tracker {
    One(Box<dyn HopStage<Out = PitchEstimate>>),
    Pair(Box<WithVoicing>),
    Aligned(Box<WithDecoded>),
    /// The learned bass tracker whose network reads the harmonic view as its side input
    /// ([`HopStage::process_with`]).
    View(Box<Shs>),
}

impl Tracker {
    /// The tracker `recipe` names, over the range and hops of `yc` (the decimated rate),
    /// with a fixed Viterbi lag of `lag_hops` for pYIN and the harmonic-sum trackers.
    pub(super) fn new(
        recipe: &TrackerRecipe,
        yc: &YinConfig,
        lag_hops: usize,
    ) -> Result<Self, ConfigError> {
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
            TrackerRecipe::Aligned(t) => Tracker::Aligned(Box::new(shs(t)?.with_decoded())),
            TrackerRecipe::View(t) => Tracker::View(Box::new(shs(t)?)),
            TrackerRecipe::Pair { voicing, pitch } => Tracker::Pair(Box::new(
                VoicingPitchPair::new(Box::new(shs(voicing)?), Box::new(shs(pitch)?))?
                    .with_veto()
                    .with_voicing(),
            )),
        })
    }

    /// Feeds a block; `emit(hop, f0, side_f0, confidence)` per hop (`side_f0` for a pair or
    /// an aligned tracker; `confidence` = 1 − the estimate's aperiodicity, for a pair the
    /// learned tracker's confidence in its pitch). `view`: the same span of the harmonic
    /// view, which a pair's pitch tracker reads instead of `x` and a view tracker's network
    /// reads beside it (`None`: `x`).
    pub(super) fn process(
        &mut self,
        x: &[f32],
        view: Option<&[f32]>,
        emit: &mut dyn FnMut(usize, f32, Option<f32>, f32),
    ) {
        let c = |e: PitchEstimate| 1.0 - e.aperiodicity;
        match self {
            Tracker::One(t) => t.process(x, &mut |i, e| emit(i, e.f0_hz, None, c(e))),
            Tracker::Pair(p) => p.process_with(x, view, &mut |i, (e, v)| {
                emit(i, e.f0_hz, Some(v.f0_hz), c(e))
            }),
            Tracker::Aligned(t) => {
                t.process(x, &mut |i, (e, d)| emit(i, e.f0_hz, Some(d.f0_hz), c(e)))
            }
            Tracker::View(t) => t.process_with(x, Some(view.unwrap_or(x)), &mut |i, e| {
                emit(i, e.f0_hz, None, c(e))
            }),
        }
    }

    pub(super) fn finish(&mut self, emit: &mut dyn FnMut(usize, f32, Option<f32>, f32)) {
        let c = |e: PitchEstimate| 1.0 - e.aperiodicity;
        match self {
            Tracker::One(t) => t.finish(&mut |i, e| emit(i, e.f0_hz, None, c(e))),
            Tracker::Pair(p) => p.finish(&mut |i, (e, v)| emit(i, e.f0_hz, Some(v.f0_hz), c(e))),
            Tracker::Aligned(t) => t.finish(&mut |i, (e, d)| emit(i, e.f0_hz, Some(d.f0_hz), c(e))),
            Tracker::View(t) => t.finish(&mut |i, e| emit(i, e.f0_hz, None, c(e))),
        }
    }

    pub(super) fn reset(&mut self) {
        match self {
            Tracker::One(t) => t.reset(),
            Tracker::Pair(p) => p.reset(),
            Tracker::Aligned(t) => t.reset(),
            Tracker::View(t) => t.reset(),
        }
    }

    pub(super) fn latency_samples(&self) -> usize {
        match self {
            Tracker::One(t) => t.latency_samples(),
            Tracker::Pair(p) => p.latency_samples(),
            Tracker::Aligned(t) => t.latency_samples(),
            Tracker::View(t) => t.latency_samples(),
        }
    }
}

/// A pair's voicing-tracker pitch through the same gate decisions and its own fences
/// ([`PitchTrack::voicing_f0`]), against which the level range checks agreement.
pub(super) struct NoteSide {
    /// Raw voicing-tracker pitch per hop (kept like `PitchTrack::raw_f0`).
    pub(super) raw: Vec<f32>,
    pub(super) skipped: usize,
    pub(super) tukey: SlidingTukey,
    /// After gate and fences, like `PitchTrack::f0`.
    pub(super) f0: Vec<f32>,
}
