//! Step 9 of the module docs, the attack alignment: a decided note change moves back to the
//! hop where the new note's attack begins, read along the Viterbi's own lag.

use super::config::ShsConfig;
use super::hops::HopRing;

/// Hops the note a change jumps to must hold for the attack alignment (step 9).
pub const ATTACK_HOLD_HOPS: usize = 3;

/// The attack alignment's salience criterion (module docs, step 9): the new note's salience
/// may fall from one hop to the next towards the change to no less than this share.
pub const ATTACK_SALIENCE_TOL: f32 = 0.8;

/// The attack alignment's parameters.
#[derive(Debug)]
pub(super) struct Attack {
    /// [`ShsConfig::attack_rise_db`] (0, off, for a learned salience).
    attack_db: f32,
    /// [`ShsConfig::attack_salience_ratio`].
    attack_ratio: f32,
    /// A jump of at least this many bins is a change of note (a semitone).
    note_jump_bins: usize,
}

impl Attack {
    pub(super) fn new(cfg: &ShsConfig) -> Attack {
        Attack {
            attack_db: if cfg.learned { 0.0 } else { cfg.attack_rise_db },
            attack_ratio: cfg.attack_salience_ratio,
            note_jump_bins: cfg.bins_per_semitone as usize,
        }
    }

    /// Step 9, the attack alignment: the state `hop` reports, given its decided `state` and
    /// the provisional path after it (`ahead`, oldest first, at most the lag). `state`
    /// itself unless the path leaves it for another note `B` in one step of at least a
    /// semitone, every hop up to that jump voiced and sounding, `B` held for
    /// [`ATTACK_HOLD_HOPS`] hops (within a bin), and the band level rising from `hop` to
    /// the jump: no hop-to-hop fall beyond `attack_db`, at least `attack_db` in all. Then
    /// `B`.
    pub(super) fn aligned_state(
        &self,
        hops: &HopRing,
        hop: usize,
        state: usize,
        ahead: &[u16],
    ) -> usize {
        let m = hops.m;
        if self.attack_db <= 0.0 || state >= m || hops.silent[hop % hops.ring] {
            return state;
        }
        let level = |h: usize| hops.level[h % hops.ring];
        // The largest salience within a bin of candidate `c` at hop `h`.
        let sal = |h: usize, c: usize| {
            let row = &hops.sal[(h % hops.ring) * m..(h % hops.ring + 1) * m];
            row[c.saturating_sub(1)..(c + 2).min(m)]
                .iter()
                .fold(0.0f32, |a, &b| a.max(b))
        };
        let mut prev = state;
        // The band level has not fallen by more than `attack_db` in one hop so far.
        let mut level_ok = true;
        for (k, &s) in ahead.iter().enumerate() {
            let (s, h) = (s as usize, hop + 1 + k);
            if s >= m || hops.silent[h % hops.ring] {
                return state;
            }
            if level(h) < level(h - 1) - self.attack_db {
                if self.attack_ratio <= 0.0 {
                    return state;
                }
                level_ok = false;
            }
            if s.abs_diff(prev) >= self.note_jump_bins {
                let held = ahead.get(k..k + ATTACK_HOLD_HOPS).is_some_and(|run| {
                    run.iter()
                        .all(|&x| (x as usize) < m && (x as usize).abs_diff(s) <= 1)
                });
                if !held {
                    return state;
                }
                if level_ok && level(h) - level(hop) >= self.attack_db {
                    return s;
                }
                // The new note already sounds at `hop` and grows towards the jump.
                let (a, b) = (sal(hop, state), sal(hop, s));
                let grows = (hop..h).all(|x| sal(x + 1, s) >= ATTACK_SALIENCE_TOL * sal(x, s));
                return if self.attack_ratio > 0.0 && a > 0.0 && b >= self.attack_ratio * a && grows
                {
                    s
                } else {
                    state
                };
            }
            prev = s;
        }
        state
    }
}
