//! Step 8 of the module docs, the register prior: once enough voiced hops are decided, every
//! voiced candidate is weighed by a Gaussian around the running mean of the decided pitch.

use super::config::ShsConfig;
use super::hops::HopRing;

/// The register prior's state (see the module docs, "Register prior").
#[derive(Debug, Clone)]
pub(super) struct Register {
    /// `1 / (2 σ²)` in bins⁻²; 0 = off.
    k: f64,
    /// Weight floor of the running mean: `hop / register_s`.
    alpha: f64,
    /// Hops of evidence before the prior applies.
    min_n: usize,
    mean: f64,
    n: usize,
}

impl Register {
    pub(super) fn new(cfg: &ShsConfig) -> Register {
        Register {
            k: if cfg.register_sigma_st > 0.0 {
                let sigma = f64::from(cfg.register_sigma_st) * f64::from(cfg.bins_per_semitone);
                1.0 / (2.0 * sigma * sigma)
            } else {
                0.0
            },
            alpha: (cfg.hop as f64 / cfg.sample_rate as f64 / f64::from(cfg.register_s)).min(1.0),
            min_n: cfg.register_min_hops,
            mean: 0.0,
            n: 0,
        }
    }

    pub(super) fn reset(&mut self) {
        self.mean = 0.0;
        self.n = 0;
    }

    fn update(&mut self, state: usize) {
        self.n += 1;
        let w = (1.0 / self.n as f64).max(self.alpha);
        self.mean += w * (state as f64 - self.mean);
    }

    /// The running mean takes in the decided `state` of `hop` when it is voiced.
    pub(super) fn note(&mut self, hops: &HopRing, hop: usize, state: usize) {
        if self.k > 0.0 && state < hops.m && !hops.silent[hop % hops.ring] {
            self.update(state);
        }
    }

    /// The prior on the voiced observations `obs`.
    pub(super) fn apply(&self, obs: &mut [f32]) {
        let r = self;
        if r.k > 0.0 && r.n >= r.min_n {
            for (c, o) in obs.iter_mut().enumerate() {
                let d = c as f64 - r.mean;
                *o -= (r.k * d * d) as f32;
            }
        }
    }
}
