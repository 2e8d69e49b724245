//! What the tracker keeps of each of the last `lag_hops + 1` hops until it is decided: the
//! salience per candidate, the frame's peak, band level and voicing, and whether it was
//! silent. The contour voicing, the register prior and the attack alignment read it.

use super::SILENT_DB;

/// The per-hop rings, hop `h` in slot `h % ring`.
#[derive(Debug)]
pub(super) struct HopRing {
    pub(super) ring: usize,
    /// Candidates per hop.
    pub(super) m: usize,
    /// Salience per hop (ring × m), for the f0 refinement.
    pub(super) sal: Vec<f32>,
    /// Frame peak per hop, so that the contour level is in the input's units.
    pub(super) peak: Vec<f32>,
    /// Band level per hop in dB, for the attack alignment (step 9).
    pub(super) level: Vec<f32>,
    pub(super) silent: Vec<bool>,
    pub(super) voicing: Vec<f32>,
}

impl HopRing {
    pub(super) fn new(m: usize, ring: usize) -> HopRing {
        HopRing {
            ring,
            m,
            sal: vec![0.0; ring * m],
            peak: vec![0.0; ring],
            level: vec![SILENT_DB; ring],
            silent: vec![true; ring],
            voicing: vec![0.0; ring],
        }
    }

    /// Level in dB of the harmonic sum of `state` at `hop` (in the input's units).
    pub(super) fn level_db(&self, hop: usize, state: usize) -> f64 {
        let slot = hop % self.ring;
        let a = f64::from(self.sal[slot * self.m + state]) * f64::from(self.peak[slot]);
        if a > 1e-12 {
            20.0 * a.log10()
        } else {
            -240.0
        }
    }
}
