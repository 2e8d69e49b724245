//! pYIN: probabilistic YIN with HMM pitch tracking (Mauch & Dixon, "pYIN: a fundamental
//! frequency estimator using probabilistic threshold distributions", ICASSP 2014).
//!
//! ## Algorithm
//! 1. **Candidates.** Each frame's CMND comes from the same FFT YIN as [`crate::yin`]. Instead
//!    of one threshold, the 100 thresholds `s = 0.01, 0.02, …, 1.00` carry a prior
//!    `P(s) ∝ Beta(s; 2, 2/m − 2)` with mean `m = prior_mean` (0.1, the paper's Beta(2, 18)).
//!    For each threshold, YIN's absolute-threshold rule picks a trough; the trough gets
//!    probability `P(s)`. Thresholds for which no CMND value dips below give
//!    `no_dip_weight × P(s)` (paper: 0.01) to the global minimum. All 100 thresholds are
//!    resolved in one pass over the lags: the trough chosen for `s` is the first trough whose
//!    running prefix minimum falls below `s`. A candidate is (parabolically interpolated f0,
//!    probability); the probabilities sum to at most 1, the frame's *voicing probability*.
//! 2. **HMM.** States: pitch bins of `100 / bins_per_semitone` cents (default 20 cents) over
//!    `[fmin, fmax]`, each voiced or unvoiced (2M states). Observation: voiced bin `k` gets
//!    `yin_trust × (candidate mass in bin k)`, each unvoiced bin `(1 − yin_trust × mass)/M`
//!    (paper: trust 0.5). Transitions: a triangular window of ±`max_jump_bins` (default 25
//!    bins = 5 semitones) between pitch bins, times `1 − switch_prob` to keep the voicing or
//!    `switch_prob` (0.01) to change it. Unvoiced states keep a pitch bin, so the tracker
//!    remembers the pitch across short gaps.
//! 3. **Decoding.** Viterbi in the log domain, cost O(M × window) per hop.
//!    * [`pyin_offline`] decodes the whole track (backtrack from the best final state).
//!    * [`Pyin`] streams with **fixed-lag Viterbi**: once hop `t` is observed, hop `t − lag`
//!      is decided by backtracking `lag` steps from the currently best state through a ring
//!      of backpointers. With `lag ≥ track length` this is exactly offline Viterbi.
//! 4. **Output.** A voiced decision reports the f0 of the frame's candidate in the decoded
//!    bin (or a neighbouring bin), so the cents accuracy is YIN's interpolated lag, not the
//!    20-cent grid; if no candidate is that close, the bin centre. `voiced_prob` is the frame's
//!    candidate mass, `aperiodicity` the CMND of the reported candidate (else the frame's
//!    minimum CMND, 1 when silent).
//!
//! ## Latency
//! Framer latency (`frame − frame/2`) + `lag_hops × hop` samples. Default `lag_hops` = 20
//! (200 ms at 10 ms hops); see the tests for streaming-vs-offline agreement per lag.
//!
//! No allocation after [`Pyin::new`]: backpointers (u16 per state per hop), candidates and the
//! backtracking path live in rings of `lag_hops + 1` hops allocated up front.

use crate::framer::Framer;
use crate::yin::{PitchEstimate, YinConfig, YinCore};
use crate::{ConfigError, HopStage};

/// Candidates kept per hop for the f0 refinement (the most probable ones).
const CANDIDATES_PER_HOP: usize = 16;
/// Number of thresholds in the prior (0.01 … 1.00, as in the paper).
const N_THRESHOLDS: usize = 100;
/// Floor for observation probabilities before the logarithm.
const OBS_FLOOR: f32 = 1e-30;

/// pYIN parameters. Build with [`PyinConfig::new`]; [`Pyin::new`] validates.
#[derive(Clone, Debug, PartialEq)]
pub struct PyinConfig {
    /// The underlying YIN analysis (frame, hop, range). `threshold` is unused by pYIN.
    pub yin: YinConfig,
    /// Fixed Viterbi lag in hops (streaming latency = framer latency + lag × hop).
    pub lag_hops: usize,
    /// Pitch bins per semitone (5 = 20-cent bins).
    pub bins_per_semitone: u32,
    /// Largest pitch change between consecutive hops, in bins (triangular window).
    pub max_jump_bins: usize,
    /// Probability of switching voiced ↔ unvoiced between hops.
    pub switch_prob: f32,
    /// Weight given to YIN's candidates in the observation model (paper: 0.5).
    pub yin_trust: f32,
    /// Mean of the Beta threshold prior (paper: 0.1, 0.15 or 0.2).
    pub prior_mean: f32,
    /// Weight of thresholds with no dip, given to the global minimum (paper: 0.01).
    pub no_dip_weight: f32,
}

impl PyinConfig {
    /// Defaults from the paper (20-cent bins, ±25 bins, switch 0.01, trust 0.5, Beta(2, 18),
    /// no-dip weight 0.01) with [`YinConfig::new`]'s frame and hop, and a 20-hop lag.
    pub fn new(sample_rate: u32, fmin_hz: f32, fmax_hz: f32) -> Self {
        PyinConfig {
            yin: YinConfig::new(sample_rate, fmin_hz, fmax_hz),
            lag_hops: 20,
            bins_per_semitone: 5,
            max_jump_bins: 25,
            switch_prob: 0.01,
            yin_trust: 0.5,
            prior_mean: 0.1,
            no_dip_weight: 0.01,
        }
    }

    fn n_bins(&self) -> Result<usize, ConfigError> {
        if !(1..=100).contains(&self.bins_per_semitone) {
            return Err(ConfigError::invalid(
                "bins_per_semitone",
                "must be in 1..=100",
            ));
        }
        let span = 12.0
            * self.bins_per_semitone as f64
            * (self.yin.fmax_hz as f64 / self.yin.fmin_hz as f64).log2();
        let m = span.floor() as usize + 1;
        if 2 * m > u16::MAX as usize {
            return Err(ConfigError::invalid(
                "bins_per_semitone",
                "too many pitch bins (2 × bins must fit u16)",
            ));
        }
        Ok(m)
    }
}

#[derive(Clone, Copy, Debug, Default)]
struct Candidate {
    f0: f32,
    cmnd: f32,
    mass: f32,
    bin: u32,
}

#[derive(Clone, Copy, Debug, Default)]
struct HopInfo {
    silent: bool,
    total_mass: f32,
    min_cmnd: f32,
    n_cands: usize,
}

/// Everything except the framer, so that the framer's callback can borrow it.
#[derive(Debug)]
struct Tracker {
    core: YinCore,
    lag: usize,
    ring: usize,
    n_bins: usize,
    fmin: f32,
    bins_per_octave: f32,
    max_jump: usize,
    trust: f32,
    no_dip_weight: f32,
    l_stay: f32,
    l_switch: f32,
    /// `ln` of the triangular pitch-transition weight for a jump of `d` bins.
    l_jump: Vec<f32>,
    /// `prior_cum[k]` = prior mass of thresholds `0.01 … k/100`.
    prior_cum: Vec<f32>,
    frame_cands: Vec<Candidate>,
    obs_voiced: Vec<f32>,
    delta: Vec<f32>,
    next: Vec<f32>,
    /// Viterbi scratch: best predecessor score and its offset index (`0..=2j`, source bin
    /// = target + index − j) per target bin, for the voiced and the unvoiced layer.
    best_v: Vec<f32>,
    arg_v: Vec<u32>,
    best_u: Vec<f32>,
    arg_u: Vec<u32>,
    /// Backpointers, `ring × 2M`: the best predecessor of each state at each hop.
    bp: Vec<u16>,
    cands: Vec<Candidate>,
    info: Vec<HopInfo>,
    path: Vec<u16>,
    hops_seen: usize,
    next_emit: usize,
}

impl Tracker {
    fn new(cfg: &PyinConfig, lag: usize) -> Result<Self, ConfigError> {
        let core = YinCore::new(&cfg.yin)?;
        let n_bins = cfg.n_bins()?;
        if !(cfg.switch_prob > 0.0 && cfg.switch_prob < 1.0) {
            return Err(ConfigError::invalid("switch_prob", "must be in (0, 1)"));
        }
        if !(cfg.yin_trust > 0.0 && cfg.yin_trust < 1.0) {
            return Err(ConfigError::invalid("yin_trust", "must be in (0, 1)"));
        }
        if !(cfg.prior_mean > 0.0 && cfg.prior_mean <= 0.5) {
            return Err(ConfigError::invalid("prior_mean", "must be in (0, 0.5]"));
        }
        if !(cfg.no_dip_weight >= 0.0 && cfg.no_dip_weight <= 1.0) {
            return Err(ConfigError::invalid("no_dip_weight", "must be in [0, 1]"));
        }
        if cfg.max_jump_bins > n_bins {
            return Err(ConfigError::invalid(
                "max_jump_bins",
                "must not exceed the number of pitch bins",
            ));
        }
        let ring = lag
            .checked_add(1)
            .filter(|r| r.checked_mul(2 * n_bins).is_some_and(|x| x <= 1 << 31))
            .ok_or_else(|| ConfigError::invalid("lag_hops", "too large for memory"))?;
        // Beta(2, b) prior with mean 2 / (2 + b).
        let a = 2.0f64;
        let b = a / cfg.prior_mean as f64 - a;
        let pdf: Vec<f64> = (1..=N_THRESHOLDS)
            .map(|i| {
                let s = i as f64 / N_THRESHOLDS as f64;
                s.powf(a - 1.0) * (1.0 - s).max(0.0).powf(b - 1.0)
            })
            .collect();
        let total: f64 = pdf.iter().sum();
        let mut prior_cum = vec![0.0f32; N_THRESHOLDS + 1];
        let mut acc = 0.0;
        for (i, p) in pdf.iter().enumerate() {
            acc += p / total;
            prior_cum[i + 1] = acc as f32;
        }
        let j = cfg.max_jump_bins;
        let norm = ((j + 1) * (j + 1)) as f32;
        let l_jump = (0..=j).map(|d| ((j + 1 - d) as f32 / norm).ln()).collect();
        let lag_range = core.tau_max - core.tau_min + 2;
        Ok(Tracker {
            lag,
            ring,
            n_bins,
            fmin: cfg.yin.fmin_hz,
            bins_per_octave: 12.0 * cfg.bins_per_semitone as f32,
            max_jump: j,
            trust: cfg.yin_trust,
            no_dip_weight: cfg.no_dip_weight,
            l_stay: (1.0 - cfg.switch_prob).ln(),
            l_switch: cfg.switch_prob.ln(),
            l_jump,
            prior_cum,
            frame_cands: Vec::with_capacity(lag_range),
            obs_voiced: vec![0.0; n_bins],
            delta: vec![0.0; 2 * n_bins],
            next: vec![0.0; 2 * n_bins],
            best_v: vec![0.0; n_bins],
            arg_v: vec![0; n_bins],
            best_u: vec![0.0; n_bins],
            arg_u: vec![0; n_bins],
            bp: vec![0; ring * 2 * n_bins],
            cands: vec![Candidate::default(); ring * CANDIDATES_PER_HOP],
            info: vec![HopInfo::default(); ring],
            path: vec![0; ring],
            hops_seen: 0,
            next_emit: 0,
            core,
        })
    }

    fn reset(&mut self) {
        self.hops_seen = 0;
        self.next_emit = 0;
    }

    /// Prior mass of the thresholds `s` with `lo < s ≤ hi`.
    fn prior_between(&self, lo: f32, hi: f32) -> f32 {
        let idx = |x: f32| {
            ((x * N_THRESHOLDS as f32)
                .floor()
                .clamp(0.0, N_THRESHOLDS as f32)) as usize
        };
        let (i_lo, i_hi) = (idx(lo), idx(hi));
        if i_hi > i_lo {
            self.prior_cum[i_hi] - self.prior_cum[i_lo]
        } else {
            0.0
        }
    }

    fn bin_of(&self, f0: f32) -> u32 {
        let b = (self.bins_per_octave * (f0 / self.fmin).log2()).round();
        b.clamp(0.0, (self.n_bins - 1) as f32) as u32
    }

    fn bin_hz(&self, bin: usize) -> f32 {
        self.fmin * (bin as f32 / self.bins_per_octave).exp2()
    }

    /// Candidates of the current CMND into `frame_cands`; returns the minimum CMND.
    fn extract_candidates(&mut self) -> f32 {
        self.frame_cands.clear();
        let (tau_min, tau_max) = (self.core.tau_min, self.core.tau_max);
        let mut run_min = f32::INFINITY;
        let mut last_m = tau_min;
        let mut last_pushed = None;
        let mut t = tau_min;
        while t <= tau_max {
            let c = &self.core.cmnd;
            if c[t] < run_min {
                let mut m = t;
                while m < tau_max && c[m + 1] < c[m] {
                    m += 1;
                }
                let cm = c[m];
                let mass = self.prior_between(cm, run_min);
                if mass > 0.0 && self.push_candidate(m, mass) {
                    last_pushed = Some(m);
                }
                run_min = cm;
                last_m = m;
                t = m + 1;
            } else {
                t += 1;
            }
        }
        let extra = self.no_dip_weight * self.prior_between(f32::NEG_INFINITY, run_min);
        if extra > 0.0 {
            match self.frame_cands.last_mut() {
                Some(c) if last_pushed == Some(last_m) => c.mass += extra,
                _ => {
                    self.push_candidate(last_m, extra);
                }
            }
        }
        run_min
    }

    /// Adds a candidate at integer `lag`; returns whether it was added.
    fn push_candidate(&mut self, lag: usize, mass: f32) -> bool {
        let f0 = self.core.sample_rate / self.core.refine_lag(lag);
        if !(f0.is_finite() && f0 > 0.0) {
            return false;
        }
        let cand = Candidate {
            f0,
            cmnd: self.core.cmnd[lag].clamp(0.0, 1.0),
            mass,
            bin: self.bin_of(f0),
        };
        // Capacity is the lag range; there is at most one candidate per lag.
        if self.frame_cands.len() < self.frame_cands.capacity() {
            self.frame_cands.push(cand);
            return true;
        }
        false
    }

    /// Analyses one frame as hop `t = hops_seen`, advances Viterbi, emits decided hops.
    fn on_frame(&mut self, frame: &[f32], emit: &mut dyn FnMut(usize, PitchEstimate)) {
        let t = self.hops_seen;
        let slot = t % self.ring;
        let m = self.n_bins;
        let silent = !self.core.analyse(frame);
        let min_cmnd = if silent {
            1.0
        } else {
            self.extract_candidates().clamp(0.0, 1.0)
        };
        if silent {
            self.frame_cands.clear();
        }
        // Observation model.
        self.obs_voiced.fill(0.0);
        let mut total = 0.0f32;
        for c in &self.frame_cands {
            self.obs_voiced[c.bin as usize] += c.mass;
            total += c.mass;
        }
        let total = total.min(1.0);
        let l_unvoiced = ((1.0 - self.trust * total) / m as f32).max(OBS_FLOOR).ln();
        for o in self.obs_voiced.iter_mut() {
            *o = (*o * self.trust).max(OBS_FLOOR).ln();
        }
        // Keep the most probable candidates for the f0 refinement.
        if self.frame_cands.len() > CANDIDATES_PER_HOP {
            self.frame_cands
                .sort_unstable_by(|a, b| b.mass.total_cmp(&a.mass));
        }
        let n_keep = self.frame_cands.len().min(CANDIDATES_PER_HOP);
        self.cands[slot * CANDIDATES_PER_HOP..slot * CANDIDATES_PER_HOP + n_keep]
            .copy_from_slice(&self.frame_cands[..n_keep]);
        self.info[slot] = HopInfo {
            silent,
            total_mass: total,
            min_cmnd,
            n_cands: n_keep,
        };
        // Viterbi step.
        if t == 0 {
            for k in 0..m {
                self.delta[k] = self.obs_voiced[k];
                self.delta[m + k] = l_unvoiced;
            }
        } else {
            crate::simd::viterbi_step(self, slot, l_unvoiced);
        }
        self.hops_seen = t + 1;
        if t >= self.lag {
            let mut s = self.best_state();
            for h in (t - self.lag + 1..=t).rev() {
                s = self.bp[(h % self.ring) * 2 * m + s] as usize;
            }
            let h = t - self.lag;
            emit(h, self.output(h, s));
            self.next_emit = h + 1;
        }
    }

    /// One Viterbi step from `delta` (hop t − 1) to `next`, then swapped into `delta`;
    /// backpointers of hop t go to ring slot `slot`. `obs_voiced` holds hop t's voiced
    /// log-observations, `l_unvoiced` its unvoiced one.
    #[inline(always)] // compiled inside `simd::viterbi_step`'s AVX2 frame
    fn viterbi_step(&mut self, slot: usize, l_unvoiced: f32) {
        let m = self.n_bins;
        let bp = &mut self.bp[slot * 2 * m..(slot + 1) * 2 * m];
        let (dv, du) = self.delta.split_at(m);
        let j = self.max_jump;
        // Best predecessor within the triangular window, for the voiced and the unvoiced
        // layer separately. Offset-major order (offset −j … +j, i.e. ascending source
        // bin for every target) with a strict `>` keeps the first maximum, exactly as a
        // source-ascending scan per target would, and lets the compiler vectorize the
        // inner loops (compare + select, no branches).
        let (bv, av, bu, au) = (
            &mut self.best_v,
            &mut self.arg_v,
            &mut self.best_u,
            &mut self.arg_u,
        );
        bv.fill(f32::NEG_INFINITY);
        bu.fill(f32::NEG_INFINITY);
        // Offset index `j` (offset 0) is "stay in the same bin".
        av.fill(j as u32);
        au.fill(j as u32);
        for oi in 0..=2 * j {
            let w = self.l_jump[oi.abs_diff(j)];
            // Targets k whose source k + oi − j lies in 0..m.
            let (k0, k1) = if oi < j {
                (j - oi, m)
            } else {
                (0, m - (oi - j))
            };
            if k0 >= k1 {
                continue;
            }
            let (s0, s1) = (k0 + oi - j, k1 + oi - j);
            crate::simd::relax(&mut bv[k0..k1], &mut av[k0..k1], &dv[s0..s1], w, oi as u32);
            crate::simd::relax(&mut bu[k0..k1], &mut au[k0..k1], &du[s0..s1], w, oi as u32);
        }
        let mut best = f32::NEG_INFINITY;
        for k in 0..m {
            let (bv, bu) = (bv[k], bu[k]);
            let (av, au) = ((k + av[k] as usize) - j, (k + au[k] as usize) - j);
            // Into voiced bin k.
            let (stay, switch) = (bv + self.l_stay, bu + self.l_switch);
            let (sv, pv) = if stay >= switch {
                (stay, av)
            } else {
                (switch, m + au)
            };
            // Into unvoiced bin k.
            let (stay, switch) = (bu + self.l_stay, bv + self.l_switch);
            let (su, pu) = if stay >= switch {
                (stay, m + au)
            } else {
                (switch, av)
            };
            self.next[k] = sv + self.obs_voiced[k];
            self.next[m + k] = su + l_unvoiced;
            bp[k] = pv as u16;
            bp[m + k] = pu as u16;
            best = best.max(self.next[k]).max(self.next[m + k]);
        }
        // Renormalize so the log scores stay bounded over long streams.
        if best.is_finite() {
            for v in self.next.iter_mut() {
                *v -= best;
            }
        }
        std::mem::swap(&mut self.delta, &mut self.next);
    }

    fn best_state(&self) -> usize {
        crate::viterbi::best_state(&self.delta)
    }

    /// Emits every hop not yet decided, backtracking from the best final state.
    fn flush(&mut self, emit: &mut dyn FnMut(usize, PitchEstimate)) {
        let end = self.hops_seen;
        let start = self.next_emit;
        if end <= start {
            return;
        }
        let last = self.best_state();
        let states = 2 * self.n_bins;
        crate::viterbi::backtrack(
            &mut self.path,
            &self.bp,
            self.ring,
            states,
            (start, end),
            last,
        );
        for h in start..end {
            emit(h, self.output(h, self.path[h - start] as usize));
        }
        self.next_emit = end;
    }

    fn output(&self, hop: usize, state: usize) -> PitchEstimate {
        let slot = hop % self.ring;
        let info = self.info[slot];
        let unvoiced = PitchEstimate {
            f0_hz: 0.0,
            aperiodicity: info.min_cmnd,
            voiced_prob: info.total_mass,
        };
        if info.silent || state >= self.n_bins {
            return unvoiced;
        }
        let cands =
            &self.cands[slot * CANDIDATES_PER_HOP..slot * CANDIDATES_PER_HOP + info.n_cands];
        let mut pick: Option<&Candidate> = None;
        for c in cands {
            let d = (c.bin as usize).abs_diff(state);
            if d > 1 {
                continue;
            }
            pick = match pick {
                Some(p) => {
                    let dp = (p.bin as usize).abs_diff(state);
                    if d < dp || (d == dp && c.mass > p.mass) {
                        Some(c)
                    } else {
                        Some(p)
                    }
                }
                None => Some(c),
            };
        }
        match pick {
            Some(c) => PitchEstimate {
                f0_hz: c.f0,
                aperiodicity: c.cmnd,
                voiced_prob: info.total_mass,
            },
            None => PitchEstimate {
                f0_hz: self.bin_hz(state),
                aperiodicity: info.min_cmnd,
                voiced_prob: info.total_mass,
            },
        }
    }
}

/// Streaming pYIN with fixed-lag Viterbi. See the module docs.
#[derive(Debug)]
pub struct Pyin {
    cfg: PyinConfig,
    framer: Framer,
    tracker: Tracker,
}

impl Pyin {
    /// Validates `cfg` and allocates every buffer the stage will ever need
    /// (about `(lag_hops + 1) × (4 × bins + 200)` bytes besides the YIN buffers).
    pub fn new(cfg: PyinConfig) -> Result<Pyin, ConfigError> {
        let tracker = Tracker::new(&cfg, cfg.lag_hops)?;
        let framer = Framer::new(cfg.yin.frame, cfg.yin.hop)?;
        Ok(Pyin {
            cfg,
            framer,
            tracker,
        })
    }

    /// The configuration in use.
    pub fn config(&self) -> &PyinConfig {
        &self.cfg
    }

    /// Number of pitch bins M (the HMM has 2M states).
    pub fn n_bins(&self) -> usize {
        self.tracker.n_bins
    }
}

impl HopStage for Pyin {
    type Out = PitchEstimate;

    fn process(&mut self, input: &[f32], emit: &mut dyn FnMut(usize, PitchEstimate)) {
        let tracker = &mut self.tracker;
        self.framer.push(input, |_, fr| tracker.on_frame(fr, emit));
    }

    fn finish(&mut self, emit: &mut dyn FnMut(usize, PitchEstimate)) {
        let tracker = &mut self.tracker;
        self.framer.finish(|_, fr| tracker.on_frame(fr, emit));
        self.tracker.flush(emit);
    }

    fn reset(&mut self) {
        self.framer.reset();
        self.tracker.reset();
    }

    fn latency_samples(&self) -> usize {
        self.framer.latency_samples() + self.cfg.lag_hops * self.cfg.yin.hop
    }

    fn hop(&self) -> usize {
        self.cfg.yin.hop
    }
}

/// Offline pYIN: Viterbi over the whole track (`cfg.lag_hops` is ignored). Returns one
/// estimate per hop, `samples.len().div_ceil(hop)` in all. Allocates O(hops × bins).
pub fn pyin_offline(samples: &[f32], cfg: &PyinConfig) -> Result<Vec<PitchEstimate>, ConfigError> {
    let hops = samples.len().div_ceil(cfg.yin.hop.max(1));
    let mut full = cfg.clone();
    full.lag_hops = hops.max(1);
    let mut p = Pyin::new(full)?;
    let mut out = Vec::with_capacity(hops);
    p.process(samples, &mut |_, e| out.push(e));
    p.finish(&mut |_, e| out.push(e));
    Ok(out)
}

impl crate::simd::ViterbiStep for Tracker {
    #[inline(always)]
    fn step(&mut self, slot: usize, l_unvoiced: f32) {
        self.viterbi_step(slot, l_unvoiced);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The obvious Viterbi step: for each target bin, scan the window's sources in
    /// ascending order (first maximum wins), as the first implementation did.
    fn naive_step(t: &Tracker, l_unvoiced: f32) -> (Vec<f32>, Vec<u16>) {
        let m = t.n_bins;
        let j = t.max_jump;
        let (dv, du) = t.delta.split_at(m);
        let mut next = vec![0.0f32; 2 * m];
        let mut bp = vec![0u16; 2 * m];
        let mut best = f32::NEG_INFINITY;
        for k in 0..m {
            let (lo, hi) = (k.saturating_sub(j), (k + j).min(m - 1));
            let (mut bv, mut av, mut bu, mut au) = (f32::NEG_INFINITY, k, f32::NEG_INFINITY, k);
            for src in lo..=hi {
                let w = t.l_jump[src.abs_diff(k)];
                if dv[src] + w > bv {
                    (bv, av) = (dv[src] + w, src);
                }
                if du[src] + w > bu {
                    (bu, au) = (du[src] + w, src);
                }
            }
            let (sv, pv) = if bv + t.l_stay >= bu + t.l_switch {
                (bv + t.l_stay, av)
            } else {
                (bu + t.l_switch, m + au)
            };
            let (su, pu) = if bu + t.l_stay >= bv + t.l_switch {
                (bu + t.l_stay, m + au)
            } else {
                (bv + t.l_switch, av)
            };
            next[k] = sv + t.obs_voiced[k];
            next[m + k] = su + l_unvoiced;
            bp[k] = pv as u16;
            bp[m + k] = pu as u16;
            best = best.max(next[k]).max(next[m + k]);
        }
        for v in &mut next {
            *v -= best;
        }
        (next, bp)
    }

    #[test]
    fn vectorized_viterbi_step_equals_the_naive_scan() {
        // Small integer-valued scores make exact ties common, so the tie rule is exercised.
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        for (fmin, fmax, jump) in [(35.0, 400.0, 25), (70.0, 90.0, 3), (50.0, 60.0, 4)] {
            let mut cfg = PyinConfig::new(16_000, fmin, fmax);
            cfg.max_jump_bins = jump;
            let Ok(mut t) = Tracker::new(&cfg, 4) else {
                panic!("config {fmin}–{fmax} Hz");
            };
            let m = t.n_bins;
            for round in 0..200 {
                for v in t.delta.iter_mut() {
                    *v = -((rnd() % 6) as f32);
                }
                for v in t.obs_voiced.iter_mut() {
                    *v = -((rnd() % 4) as f32) * 0.5;
                }
                let l_unvoiced = -((rnd() % 3) as f32);
                let (want_next, want_bp) = naive_step(&t, l_unvoiced);
                let slot = round % t.ring;
                // Odd rounds: the step as the tracker runs it, inside `simd::viterbi_step`'s AVX2
                // frame; even rounds: as compiled for the baseline CPU.
                if round % 2 == 1 {
                    crate::simd::viterbi_step(&mut t, slot, l_unvoiced);
                } else {
                    t.viterbi_step(slot, l_unvoiced);
                }
                assert_eq!(
                    t.delta, want_next,
                    "scores, {fmin}–{fmax} Hz, round {round}"
                );
                assert_eq!(
                    &t.bp[slot * 2 * m..(slot + 1) * 2 * m],
                    &want_bp[..],
                    "backpointers, {fmin}–{fmax} Hz, round {round}"
                );
            }
        }
    }
}
