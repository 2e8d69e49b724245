//! Steps 4 and 5 of the module docs: the hidden Markov model over the candidates and the
//! unvoiced state, and one Viterbi step in the log domain (the decoding's back-pointers are
//! read by the tracker, [`crate::viterbi`]).

use super::config::ShsConfig;

/// The Viterbi's scores, transitions and back-pointers.
#[derive(Debug)]
pub(super) struct Hmm {
    /// Voiced states (candidates); state `m` is unvoiced.
    pub(super) m: usize,
    max_jump: usize,
    l_stay: f32,
    l_switch: f32,
    l_enter: f32,
    /// `ln` of the triangular transition weight for a jump of `d` bins (normalised).
    l_jump: Vec<f32>,
    /// The current hop's observation log-probabilities of the voiced states.
    pub(super) obs: Vec<f32>,
    /// Viterbi scores: `delta[..m]` voiced bins, `delta[m]` unvoiced.
    delta: Vec<f32>,
    next: Vec<f32>,
    /// Scratch of [`Hmm::step`]: per voiced bin, the best predecessor's score and index.
    best_in: Vec<f32>,
    /// The best predecessor's offset `src − k`.
    /// The best offset per voiced bin, an `i32` stored as its bits.
    arg_in: Vec<u32>,
    /// Backpointers, `ring × (m + 1)`.
    pub(super) bp: Vec<u16>,
}

impl crate::simd::ViterbiStep for Hmm {
    #[inline(always)]
    fn step(&mut self, slot: usize, l_unvoiced: f32) {
        Hmm::step(self, slot, l_unvoiced);
    }
}

impl Hmm {
    /// The model of `cfg` over `m` candidates, with `ring` hops of back-pointers (`bp`).
    pub(super) fn new(cfg: &ShsConfig, m: usize, ring: usize) -> Hmm {
        let j = cfg.max_jump_bins;
        // Peak-normalised (staying costs nothing): the unvoiced state has no pitch to choose,
        // so a voiced state must not pay for choosing one either.
        let l_jump = (0..=j)
            .map(|d| ((j + 1 - d) as f32 / (j + 1) as f32).ln())
            .collect();
        Hmm {
            m,
            max_jump: j,
            l_stay: (1.0 - cfg.switch_prob).ln(),
            l_switch: cfg.switch_prob.ln(),
            l_enter: cfg.switch_prob.ln(),
            l_jump,
            obs: vec![0.0; m],
            delta: vec![0.0; m + 1],
            next: vec![0.0; m + 1],
            best_in: vec![0.0; m],
            arg_in: vec![0; m],
            bp: vec![0; ring * (m + 1)],
        }
    }

    /// The first hop: the scores are its observations.
    pub(super) fn start(&mut self, l_unvoiced: f32) {
        let m = self.m;
        self.delta[..m].copy_from_slice(&self.obs);
        self.delta[m] = l_unvoiced;
    }

    /// One Viterbi step into `next` (then swapped into `delta`), backpointers into `slot`.
    #[allow(clippy::needless_range_loop)] // k indexes delta, next, obs and bp alike
    #[inline(always)] // compiled inside `simd::viterbi_step`'s AVX2 frame
    pub(super) fn step(&mut self, slot: usize, l_unvoiced: f32) {
        let m = self.m;
        let j = self.max_jump;
        let bp = &mut self.bp[slot * (m + 1)..(slot + 1) * (m + 1)];
        let du = self.delta[m];
        // The best predecessor of every voiced bin k among src = k + d, |d| ≤ j: the same
        // sums and the same first-wins comparisons as a loop over src for each k (src
        // ascending), but run one offset d at a time over every k, which vectorises.
        self.best_in.fill(f32::NEG_INFINITY);
        self.arg_in.fill(0);
        for d in -(j.min(m - 1) as isize)..=(j.min(m - 1) as isize) {
            let w = self.l_jump[d.unsigned_abs()];
            let (k_lo, k_hi) = if d < 0 {
                (d.unsigned_abs(), m)
            } else {
                (0, m - d as usize)
            };
            let src_lo = (k_lo as isize + d) as usize;
            let src = &self.delta[src_lo..src_lo + (k_hi - k_lo)];
            let bv = &mut self.best_in[k_lo..k_hi];
            let arg = &mut self.arg_in[k_lo..k_hi];
            crate::simd::relax(bv, arg, src, w, d as i32 as u32);
        }
        let mut best = f32::NEG_INFINITY;
        for k in 0..m {
            let (bv, arg) = (
                self.best_in[k],
                (k as isize + self.arg_in[k] as i32 as isize) as usize,
            );
            let stay = bv + self.l_stay;
            let enter = du + self.l_enter;
            let (sv, pv) = if stay >= enter {
                (stay, arg)
            } else {
                (enter, m)
            };
            self.next[k] = sv + self.obs[k];
            bp[k] = pv as u16;
            best = best.max(self.next[k]);
        }
        // Into the unvoiced state: from itself or from the best voiced bin.
        let mut bv = f32::NEG_INFINITY;
        let mut arg = 0;
        for (src, &d) in self.delta[..m].iter().enumerate() {
            if d > bv {
                bv = d;
                arg = src;
            }
        }
        let (su, pu) = if du + self.l_stay >= bv + self.l_switch {
            (du + self.l_stay, m)
        } else {
            (bv + self.l_switch, arg)
        };
        self.next[m] = su + l_unvoiced;
        bp[m] = pu as u16;
        best = best.max(self.next[m]);
        if best.is_finite() {
            for v in self.next.iter_mut() {
                *v -= best;
            }
        }
        std::mem::swap(&mut self.delta, &mut self.next);
    }

    pub(super) fn best_state(&self) -> usize {
        crate::viterbi::best_state(&self.delta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`Hmm::step`] written the obvious way (a loop over the sources of each voiced
    /// bin, first best wins, as it was before the offset-major form), normalised the same.
    fn step_by_hand(t: &Hmm, l_unvoiced: f32) -> (Vec<f32>, Vec<u16>) {
        let (m, j) = (t.m, t.max_jump);
        let du = t.delta[m];
        let mut next = vec![0.0f32; m + 1];
        let mut bp = vec![0u16; m + 1];
        for k in 0..m {
            let (lo, hi) = (k.saturating_sub(j), (k + j).min(m - 1));
            let (mut bv, mut arg) = (f32::NEG_INFINITY, k);
            for src in lo..=hi {
                let v = t.delta[src] + t.l_jump[src.abs_diff(k)];
                if v > bv {
                    bv = v;
                    arg = src;
                }
            }
            let (stay, enter) = (bv + t.l_stay, du + t.l_enter);
            let (sv, pv) = if stay >= enter {
                (stay, arg)
            } else {
                (enter, m)
            };
            next[k] = sv + t.obs[k];
            bp[k] = pv as u16;
        }
        let (mut bv, mut arg) = (f32::NEG_INFINITY, 0);
        for (src, &d) in t.delta[..m].iter().enumerate() {
            if d > bv {
                bv = d;
                arg = src;
            }
        }
        let (su, pu) = if du + t.l_stay >= bv + t.l_switch {
            (du + t.l_stay, m)
        } else {
            (bv + t.l_switch, arg)
        };
        next[m] = su + l_unvoiced;
        bp[m] = pu as u16;
        let best = next.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        for v in next.iter_mut() {
            *v -= best;
        }
        (next, bp)
    }

    #[test]
    fn the_offset_major_viterbi_step_equals_the_source_loop_bit_for_bit() {
        let mut seed = 0x9e37_79b9u32;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32
        };
        for (fmin, fmax, jump) in [(35.0, 400.0, 36), (70.0, 1400.0, 36), (70.0, 1400.0, 3)] {
            let mut cfg = ShsConfig::new(14_700, fmin, fmax);
            cfg.max_jump_bins = jump;
            let m = cfg.n_bins().unwrap();
            let mut t = Hmm::new(&cfg, m, cfg.lag_hops + 1);
            for trial in 0..20 {
                // Scores with ties (quantised) so that the first-wins rule is exercised.
                for d in t.delta.iter_mut() {
                    *d = -(rnd() * 8.0).floor();
                }
                for o in t.obs.iter_mut() {
                    *o = (rnd() * 4.0).ln();
                }
                let (want, want_bp) = step_by_hand(&t, -1.0);
                let slot = trial % (cfg.lag_hops + 1);
                // Both builds of the step: as compiled for the baseline CPU, and inside
                // `simd::viterbi_step`, as the tracker runs it (the same frame as the
                // first where the CPU lacks AVX2).
                let delta = t.delta.clone();
                for path in ["baseline", "viterbi_step"] {
                    t.delta.copy_from_slice(&delta);
                    if path == "baseline" {
                        t.step(slot, -1.0);
                    } else {
                        crate::simd::viterbi_step(&mut t, slot, -1.0);
                    }
                    let bp = &t.bp[slot * (m + 1)..(slot + 1) * (m + 1)];
                    assert_eq!(
                        bp,
                        &want_bp[..],
                        "{path} {fmin}-{fmax} jump {jump} trial {trial}"
                    );
                    for (k, (w, d)) in want.iter().zip(&t.delta).enumerate() {
                        assert_eq!(w.to_bits(), d.to_bits(), "{path} bin {k}");
                    }
                }
            }
        }
    }
}
