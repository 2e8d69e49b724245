//! A pitch track's streaming post-processing: gate, fences, range, discretizer, binner.

use tactus_dsp::binner::LevelBinner;
use tactus_dsp::discretize::{narrow_range, Discretizer, HeldRange, RangePrior, RunningRange};
use tactus_dsp::rms::StreamingGate;
use tactus_dsp::tukey::SlidingTukey;
use tactus_dsp::{ConfigError, HopFilter};

use super::LevelRule;
use crate::recipe::{LevelRecipe, SureRule};

/// The streaming post-processing of a pitch track: per hop, its RMS and raw pitch through
/// the gate, the Tukey fences, the range (the paper's running range or the prior-padded
/// one, by the level rule) and the discretizer to a level, and the levels through the
/// binner to bins. Every stage is a [`HopFilter`]: one reset, latencies that add up.
pub(super) struct LevelChain {
    pub(super) gate: StreamingGate,
    pub(super) tukey: SlidingTukey,
    pub(super) range: RunningRange,
    pub(super) prior_range: HeldRange,
    /// The same range of the sure hops only, and the rule that narrows `prior_range` to it
    /// (a track with a [`SureRule`]; `docs/decisions/0040-streaming-ranges-narrowed-to-sure-hops.md`).
    pub(super) sure_range: Option<(HeldRange, SureRule)>,
    pub(super) rule: LevelRule,
    pub(super) disc: Discretizer,
    pub(super) binner: LevelBinner,
}

impl LevelChain {
    /// Hop `i`: returns its pitch after gate and fences and its level; completed bins go to
    /// `bins`.
    /// Hop `i`'s gate and fences: its pitch after both, and whether the gate is open.
    pub(super) fn fence(&mut self, rms_db: f32, raw_f0: f32) -> (f32, bool) {
        let open = self.gate.process(rms_db);
        (self.tukey.process(if open { raw_f0 } else { 0.0 }), open)
    }

    /// Hop `i`'s level from its fenced pitch `f0` (`trusted`: a second tracker agrees,
    /// [`HeldRange::update_trusted`]; `sure`: the learned tracker is sure of it, for a track
    /// with a [`SureRule`]); completed bins go to `bins`.
    pub(super) fn level(
        &mut self,
        i: usize,
        f0: f32,
        trusted: bool,
        sure: bool,
        bins: &mut Vec<u8>,
    ) -> u8 {
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

    pub(super) fn reset(&mut self) {
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
    pub(super) fn latency_samples(&self) -> usize {
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
pub(super) fn held_range(
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

/// [`HopFilter::reset`] for a chain whose stages have different value types.
trait Reset {
    fn reset(&mut self);
}

impl<F: HopFilter> Reset for F {
    fn reset(&mut self) {
        HopFilter::reset(self)
    }
}
