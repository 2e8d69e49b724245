//! Step 7 of the module docs, the contour voicing: a decided voiced hop is reported unvoiced
//! when the mean level of its contour lies far below the track's running level (after
//! Salamon & Gómez 2012).

use super::config::ShsConfig;
use super::hops::HopRing;

/// The contour voicing state (see the module docs, "Contour voicing").
#[derive(Debug, Clone)]
pub(super) struct ContourGate {
    gate_db: f64,
    jump: usize,
    /// Weight floor of the running mean: `hop / contour_ref_s`.
    alpha: f64,
    /// Last emitted decoded state (a bin, or `None` after an unvoiced or silent hop).
    prev: Option<usize>,
    sum: f64,
    n: usize,
    reference: f64,
    ref_n: usize,
}

impl ContourGate {
    pub(super) fn new(cfg: &ShsConfig) -> ContourGate {
        ContourGate {
            gate_db: cfg.contour_gate_db as f64,
            jump: cfg.contour_jump_bins,
            alpha: (cfg.hop as f64 / cfg.sample_rate as f64 / cfg.contour_ref_s as f64).min(1.0),
            prev: None,
            sum: 0.0,
            n: 0,
            reference: 0.0,
            ref_n: 0,
        }
    }

    pub(super) fn reset(&mut self) {
        self.prev = None;
        self.sum = 0.0;
        self.n = 0;
        self.reference = 0.0;
        self.ref_n = 0;
    }

    /// Contour voicing of the decoded `state` at `hop`, given the decoded states of the hops
    /// after it (`ahead`, oldest first). Updates the contour and the running reference;
    /// returns false when the hop is to be reported unvoiced.
    pub(super) fn voiced(
        &mut self,
        hops: &HopRing,
        hop: usize,
        state: usize,
        ahead: &[u16],
    ) -> bool {
        let slot = hop % hops.ring;
        if hops.silent[slot] || state >= hops.m {
            self.prev = None;
            return true;
        }
        let x = hops.level_db(hop, state);
        let g = self;
        let same = g.prev.is_some_and(|p| p.abs_diff(state) <= g.jump);
        if !same {
            g.sum = 0.0;
            g.n = 0;
        }
        g.sum += x;
        g.n += 1;
        g.prev = Some(state);
        g.ref_n += 1;
        let w = (1.0 / g.ref_n as f64).max(g.alpha);
        g.reference += w * (x - g.reference);
        if g.gate_db <= 0.0 {
            return true;
        }
        let (jump, reference, gate_db) = (g.jump, g.reference, g.gate_db);
        let (mut sum, mut n) = (g.sum, g.n);
        let mut last = state;
        for (k, &s) in ahead.iter().enumerate() {
            let s = s as usize;
            let h = hop + 1 + k;
            if s >= hops.m || hops.silent[h % hops.ring] || s.abs_diff(last) > jump {
                break;
            }
            sum += hops.level_db(h, s);
            n += 1;
            last = s;
        }
        sum / n as f64 >= reference - gate_db
    }
}
