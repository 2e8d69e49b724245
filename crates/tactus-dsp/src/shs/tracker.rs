//! The tracker: per hop, the salience (harmonic sum or learned) into observations, one
//! Viterbi step, and the hop `lag_hops` back decided, voiced or not, aligned and refined.

use super::attack::Attack;
use super::config::ShsConfig;
use super::contour::ContourGate;
use super::hmm::Hmm;
use super::hops::HopRing;
use super::net::{NetState, NET_BATCH};
use super::register::Register;
use super::salience::Salience;
use super::{P_FLOOR, SILENT_DB};
use crate::yin::PitchEstimate;
use crate::ConfigError;

/// The tracker's output per hop: (hop, reported estimate, decoded estimate).
type Emit<'a> = dyn FnMut(usize, PitchEstimate, PitchEstimate) + 'a;

/// Candidates on each side of the decided one whose probabilities a learned tracker's
/// confidence sums (module docs, "Learned salience").
pub const CONFIDENCE_BINS: usize = 2;

/// Everything but the framer, so the framer's callback can borrow it.
#[derive(Debug)]
pub(super) struct Tracker {
    pub(super) sal: Salience,
    /// Candidates.
    pub(super) m: usize,
    lag: usize,
    ring: usize,
    cfg_bin0: f32,
    bins_per_octave: f32,
    /// The current hop's salience per candidate.
    s: Vec<f32>,
    hmm: Hmm,
    hops: HopRing,
    path: Vec<u16>,
    hops_seen: usize,
    next_emit: usize,
    attack: Attack,
    contour: ContourGate,
    register: Register,
    /// The learned salience's state, when [`ShsConfig::learned`].
    pub(super) net: Option<Box<NetState>>,
    /// [`ShsConfig::learned`]: voiced estimates carry the network's confidence (module docs,
    /// "Learned salience"). (`net` is taken out while a batch runs, so it cannot say.)
    learned: bool,
}

impl Tracker {
    pub(super) fn new(cfg: &ShsConfig) -> Result<Self, ConfigError> {
        let m = cfg.n_bins()?;
        let ring = cfg.lag_hops + 1;
        Ok(Tracker {
            sal: Salience::new(cfg, m),
            m,
            lag: cfg.lag_hops,
            ring,
            cfg_bin0: cfg.fmin_hz,
            bins_per_octave: 12.0 * cfg.bins_per_semitone as f32,
            s: vec![0.0; m],
            hmm: Hmm::new(cfg, m, ring),
            hops: HopRing::new(m, ring),
            path: vec![0; ring],
            hops_seen: 0,
            next_emit: 0,
            attack: Attack::new(cfg),
            contour: ContourGate::new(cfg),
            register: Register::new(cfg),
            net: if cfg.learned {
                Some(Box::new(NetState::new(cfg, m)?))
            } else {
                None
            },
            learned: cfg.learned,
        })
    }

    pub(super) fn reset(&mut self) {
        self.hops_seen = 0;
        self.next_emit = 0;
        self.contour.reset();
        self.register.reset();
        if let Some(n) = &mut self.net {
            n.reset();
        }
    }

    /// Observation log-probabilities of the current salience `s` with evidence `v` into `obs`;
    /// returns the unvoiced one.
    fn observe(&mut self, v: f32) -> f32 {
        let peak = self.s.iter().fold(0.0f32, |a, &b| a.max(b));
        if peak > 0.0 {
            for (o, &s) in self.hmm.obs.iter_mut().zip(&self.s) {
                *o = (v * (s.max(0.0) / peak).powf(self.sal.sharp))
                    .max(P_FLOOR)
                    .ln();
            }
        } else {
            self.hmm.obs.fill(P_FLOOR.ln());
        }
        self.register.apply(&mut self.hmm.obs);
        (1.0 - v).max(P_FLOOR).ln()
    }

    /// The learned salience: frame `frames` arrives; the hop `future` frames before it
    /// goes to the Viterbi.
    fn on_net_frame(&mut self, frame: &[f32], view: Option<&[f32]>, emit: &mut Emit) {
        let Some(mut n) = self.net.take() else {
            return;
        };
        n.take_frame(&mut self.sal, self.m, frame, view);
        while n.queued + n.future < n.frames {
            n.queue();
            if n.pending() == NET_BATCH {
                self.run_batch(&mut n, emit);
            }
        }
        self.net = Some(n);
    }

    /// The hops still waiting for future frames (the stream has ended).
    pub(super) fn drain_net(&mut self, emit: &mut Emit) {
        let Some(mut n) = self.net.take() else {
            return;
        };
        while n.queued < n.frames {
            n.queue();
            if n.pending() == NET_BATCH {
                self.run_batch(&mut n, emit);
            }
        }
        self.run_batch(&mut n, emit);
        self.net = Some(n);
    }

    /// Runs the hops waiting in the batch, if any (the end of a block: whatever a block
    /// makes ready leaves with it, so batching adds no latency).
    pub(super) fn flush_batch(&mut self, emit: &mut Emit) {
        let Some(mut n) = self.net.take() else {
            return;
        };
        self.run_batch(&mut n, emit);
        self.net = Some(n);
    }

    /// The waiting hops through the network together, then each through the Viterbi in
    /// order.
    fn run_batch(&mut self, n: &mut NetState, emit: &mut Emit) {
        if n.pending() == 0 {
            return;
        }
        n.infer();
        for row in 0..n.pending() {
            self.net_hop(n, row, emit);
        }
    }

    /// Hop `n.hops`, whose log-probabilities are row `row` of `n.logp`, through the Viterbi.
    fn net_hop(&mut self, n: &mut NetState, row: usize, emit: &mut Emit) {
        let slot = n.hops % n.ring;
        let (silent, peak) = (n.silent[slot], n.peak[slot]);
        n.hops += 1;
        let (v, l_unvoiced) = if silent {
            self.s.fill(0.0);
            (0.02, self.observe(0.02))
        } else {
            let (v, lu) = n.observe(row, self.sal.sharp, &mut self.s, &mut self.hmm.obs);
            self.register.apply(&mut self.hmm.obs);
            (v, lu)
        };
        self.advance(silent, v, l_unvoiced, peak, SILENT_DB, emit);
    }

    /// [`Tracker::on_frame`] with the learned salience reading `view` (its frame of the
    /// same hop) when one is given.
    pub(super) fn on_frame_view(&mut self, frame: &[f32], view: Option<&[f32]>, emit: &mut Emit) {
        if self.net.is_some() {
            self.on_net_frame(frame, view, emit);
        } else {
            self.on_frame(frame, emit);
        }
    }

    pub(super) fn on_frame(&mut self, frame: &[f32], emit: &mut Emit) {
        if self.net.is_some() {
            self.on_net_frame(frame, None, emit);
            return;
        }
        let silent = !self.sal.spectrum(frame);
        let v = if silent {
            self.s.fill(0.0);
            0.02
        } else {
            let mut s = std::mem::take(&mut self.s);
            let v = self.sal.salience(&mut s);
            self.s = s;
            v
        };
        let l_unvoiced = self.observe(v);
        let peak = if silent { 0.0 } else { self.sal.last_peak };
        let level = if silent {
            SILENT_DB
        } else {
            self.sal.band_level_db()
        };
        self.advance(silent, v, l_unvoiced, peak, level, emit);
    }

    /// The current hop's salience `s` and observations `obs` (voicing evidence `v`,
    /// unvoiced log-probability `l_unvoiced`) into the rings and the Viterbi; emits the hop
    /// `lag_hops` back.
    #[allow(clippy::too_many_arguments)]
    fn advance(
        &mut self,
        silent: bool,
        v: f32,
        l_unvoiced: f32,
        peak: f32,
        level_db: f32,
        emit: &mut Emit,
    ) {
        let t = self.hops_seen;
        let slot = t % self.ring;
        let m = self.m;
        self.hops.sal[slot * m..(slot + 1) * m].copy_from_slice(&self.s);
        self.hops.peak[slot] = peak;
        self.hops.level[slot] = level_db;
        self.hops.silent[slot] = silent;
        self.hops.voicing[slot] = v;
        if t == 0 {
            self.hmm.start(l_unvoiced);
        } else {
            crate::simd::viterbi_step(&mut self.hmm, slot, l_unvoiced);
        }
        self.hops_seen = t + 1;
        if t >= self.lag {
            // The provisional path from the best current state back to the hop decided now:
            // `path[k]` is the state at hop `t − lag + k`.
            let h = t - self.lag;
            let mut s = self.hmm.best_state();
            for hh in (h + 1..=t).rev() {
                self.path[hh - h] = s as u16;
                s = self.hmm.bp[(hh % self.ring) * (m + 1) + s] as usize;
            }
            self.path[0] = s as u16;
            let path = std::mem::take(&mut self.path);
            self.decide(h, s, &path[1..], emit);
            self.path = path;
            self.next_emit = h + 1;
        }
    }

    /// Hop `h` is decided as state `s` with the provisional path `ahead` after it: the
    /// contour voicing (step 7), the register (step 8) and the attack alignment (step 9),
    /// then `emit(h, reported, decoded)`.
    fn decide(&mut self, h: usize, s: usize, ahead: &[u16], emit: &mut Emit) {
        let voiced = self.contour.voiced(&self.hops, h, s, ahead);
        let st = if voiced { s } else { self.m };
        let reported = self.attack.aligned_state(&self.hops, h, st, ahead);
        self.register.note(&self.hops, h, st);
        let decoded = self.output(h, st);
        let out = if reported == st {
            decoded
        } else {
            self.output(h, reported)
        };
        emit(h, out, decoded);
    }

    pub(super) fn flush(&mut self, emit: &mut Emit) {
        let (start, end) = (self.next_emit, self.hops_seen);
        if end <= start {
            return;
        }
        let last = self.hmm.best_state();
        let states = self.m + 1;
        crate::viterbi::backtrack(
            &mut self.path,
            &self.hmm.bp,
            self.ring,
            states,
            (start, end),
            last,
        );
        let path = std::mem::take(&mut self.path);
        for h in start..end {
            let s = path[h - start] as usize;
            self.decide(h, s, &path[h - start + 1..end - start], emit);
        }
        self.path = path;
        self.next_emit = end;
    }

    fn output(&self, hop: usize, state: usize) -> PitchEstimate {
        let slot = hop % self.ring;
        let v = self.hops.voicing[slot];
        if self.hops.silent[slot] || state >= self.m {
            return PitchEstimate {
                f0_hz: 0.0,
                aperiodicity: 1.0 - v,
                voiced_prob: v,
            };
        }
        let s = &self.hops.sal[slot * self.m..(slot + 1) * self.m];
        let mut off = 0.0f32;
        if state > 0 && state + 1 < self.m {
            let (a, b, c) = (s[state - 1], s[state], s[state + 1]);
            let den = a - 2.0 * b + c;
            if den < 0.0 {
                off = (0.5 * (a - c) / den).clamp(-0.5, 0.5);
            }
        }
        // The learned salience's confidence in this pitch (module docs, "Learned salience").
        let aperiodicity = if self.learned {
            let near =
                state.saturating_sub(CONFIDENCE_BINS)..(state + CONFIDENCE_BINS + 1).min(self.m);
            (1.0 - s[near].iter().sum::<f32>()).clamp(0.0, 1.0)
        } else {
            1.0 - v
        };
        PitchEstimate {
            f0_hz: self.cfg_bin0 * ((state as f32 + off) / self.bins_per_octave).exp2(),
            aperiodicity,
            voiced_prob: v,
        }
    }
}
