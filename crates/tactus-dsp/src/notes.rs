//! Note onsets from a pitch track: a new note starts where voicing begins or where the
//! pitch moves to a new stable note.
//!
//! Spectral flux sees attacks; a sung or legato note changes pitch without one
//! (`docs/decisions/0004-note-onsets-from-the-pitch-track.md`). This stage reads the tracked f0
//! per hop (Hz, 0 = unvoiced, after gate and fences) and marks hop `j` as a **note onset** when
//! the `stable` hops `j ..= j + stable − 1` are all voiced and lie within ± `tolerance_st`
//! semitones of their median (a stable note), and either no note is current (voicing began, or
//! resumed after more than `gap_hops` unvoiced hops) or hop `j`'s pitch is at least `jump_st`
//! semitones from the current note's. The new note's pitch is the window's median; while the
//! note lasts, each later stable window pulls it 3 % of the way towards its own median, so it
//! settles on the note's centre. Vibrato (±35 cents) and scoops (−40 cents) stay inside one
//! note; a bend or glide only starts a note once it settles.
//!
//! **The stem's level** (the `attack` rule, [`NoteOnsets::push_level`];
//! `docs/decisions/0017-note-onsets-from-the-attack.md`): the pitch cannot see a note repeated
//! at the same pitch (a pop bass line on its root, a sung syllable on the previous note's
//! pitch), and it hears a new note only once its pitch has settled, after the previous note's
//! release or reverb (50–90 ms on the corpus's soundfont leads). So the detector also reads the
//! stem's RMS per hop `L` (dB, the pitch track's own 40 ms frames). With `step(h) = L[h] −
//! L[h−1]` and `rise(h) = max L[h ..= h+2] − min L[h−3 ..= h−1]`, a hop is an **attack** when
//! its step is positive and the steepest of hops `h−1 ..= h+2`:
//! 1. **Re-attack**: inside a held note (hop `j`'s pitch within `jump_st` of the current
//!    note's), an attack with `rise ≥ reattack_db` starts a new note of the same pitch, when
//!    at least `reattack_min_hops` have passed since the previous onset (0 by default; the
//!    engine's clean lead, 25: a patch whose level swings inside a note).
//! 2. **Onset at the attack**: a pitch onset at `j` moves back to the steepest attack with
//!    `rise ≥ attack_db` among hops `j − attack_back_hops .. j`, or is dropped when a note
//!    already started there (a re-attack caught it first).
//! 3. **Minimum interval**: no onset within `min_ioi_hops` of the previous one.
//! 4. **Dropouts**: a note that resumes within `resume_hops` unvoiced hops at the pitch it had
//!    before is the same note unless rule 2 finds an attack (the gate or a chord tone broke
//!    the track, the player did not).
//! 5. **Attacked changes** (`pitch_needs_attack`, off by default; the engine turns it on for
//!    the bass of a mixture): a change of note counts only where rule 2 finds an attack.
//! 6. **Guided onsets** (`guide_back_hops`, off by default and in the engine: tried, not
//!    adopted): a pitch onset that rule 2 did not move goes back to where a *guide* pitch fed
//!    beside the decoded one ([`NoteOnsets::push_guided`]: the harmonic-sum tracker's
//!    attack-aligned pitch) already holds the new note, within the attack search's window: a
//!    choir's slow attack cross-fades with the old note's release without raising the level,
//!    but the new note's own salience grows from its start.
//!
//! Without a level (NaN) rules 1, 2 and 4 find no attack, so the rule never adds an onset the
//! pitch rule lacks. The kick leaking into a separated bass stem also raises its level, but on
//! the corpus's mixes the false onsets were no more often near a kick than chance (8 % vs 8 %,
//! 15 % vs 12 %): they come from the pitch track's own errors, so the level is plain RMS, not a
//! harmonic-weighted flux.
//!
//! Note segmentation on a pitch track is in the spirit of Mauch et al., "Computer-aided
//! melody note transcription using the Tony software: accuracy and efficiency" (2015),
//! reduced to a causal rule with a fixed look-ahead; the attack as the steepest rise of the
//! level envelope is the classic energy onset detector (Bello et al., "A tutorial on onset
//! detection in music signals", 2005).
//!
//! **Defaults** ([`NoteConfig::default`], the `attack` rule): stable 4 hops (40 ms at 10 ms
//! hops), tolerance 0.5 semitone, jump 0.7 semitone, gap 2 hops (tuned on 4 chorales);
//! re-attack 6 dB, attack search 8 hops with 3 dB, minimum interval 10 hops (100 ms), dropouts
//! up to 10 hops (tuned on the tuning halves of the sung, drum and chorale corpora,
//! `benches/bass_eval.py`). [`NoteConfig::pitch_only`] is the
//! first implementation (the pitch alone).
//!
//! **Latency** ([`NoteOnsets::latency_hops`]): the decision's look-ahead, `stable − 1` hops
//! (at least 2 with re-attacks, for the rise), plus `attack_back_hops` (an onset may still
//! move back that far): 3 hops for the pitch rule, 3 + 8 = 11 hops (110 ms) for the default.
//! Allocation-free; O(stable + attack_back_hops) per hop.

use crate::{hz_to_semitones, ConfigError};

/// How fast the current note's pitch follows later stable windows (per hop).
const FOLLOW: f32 = 0.03;

/// Longest stability window accepted.
pub const MAX_STABLE_HOPS: usize = 32;

/// Longest attack search before a pitch onset ([`NoteConfig::attack_back_hops`]).
pub const MAX_BACK_HOPS: usize = 16;

/// Hops before a hop over which the level's rise is measured (its minimum is the base).
pub const RISE_BEHIND_HOPS: usize = 3;

/// Hops after a hop over which the level's rise is measured (its maximum is the top).
pub const RISE_AHEAD_HOPS: usize = 2;

/// History kept: look-ahead, look-back and the rise's windows fit.
const HIST: usize = 64;

/// Parameters of [`NoteOnsets`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoteConfig {
    /// Hops a new note must hold still (1..=[`MAX_STABLE_HOPS`]).
    pub stable_hops: usize,
    /// Largest distance from the window's median, semitones, for "still".
    pub tolerance_st: f32,
    /// Smallest pitch change that starts a new note, semitones.
    pub jump_st: f32,
    /// Unvoiced hops a note survives (a longer gap ends it; the next voiced note is new).
    pub gap_hops: usize,
    /// Re-attacks: a rise of the stem's level by at least this many dB (from the minimum of
    /// the [`RISE_BEHIND_HOPS`] hops before to the maximum of the hop and the
    /// [`RISE_AHEAD_HOPS`] after) inside a held note starts a new note of the same pitch.
    /// 0 = off (pitch only, the first implementation).
    pub reattack_db: f32,
    /// A pitch onset moves back to the steepest level rise of at least `attack_db` within
    /// this many hops before it (the attack, heard before the pitch settles), or is dropped
    /// when a re-attack already started a note there. 0 = off.
    pub attack_back_hops: usize,
    /// Smallest level rise, dB, that counts as an attack for `attack_back_hops`.
    pub attack_db: f32,
    /// Fewest hops between two onsets (a closer one is dropped; the note still changes).
    /// 0 = no limit.
    pub min_ioi_hops: usize,
    /// A note that resumes at the pitch it had before a gap of at most this many unvoiced
    /// hops is the same note (a dropout of the track) unless the level rises there by
    /// `attack_db` (searched like `attack_back_hops`, which must be > 0). 0 = off.
    pub resume_hops: usize,
    /// A change of note (not voicing after a rest) counts only where the attack search
    /// finds an attack (`attack_back_hops` must be > 0): for a plucked bass in a mixture,
    /// where a pitch change without an attack is mostly a chord tone the tracker took.
    pub pitch_needs_attack: bool,
    /// An onset placed at an attack (rules 1 and 2) moves back to the foot of its rise: the
    /// hop before the run of rising level steps that ends at the attack, at most this many
    /// hops back, never before the attack window's start (`j − attack_back_hops` for the hop
    /// `j` being decided) nor within `min_ioi_hops` of the previous onset. 0 = off.
    pub backtrack_hops: usize,
    /// A pitch onset that no attack moved (rule 2 found none) is placed this many hops
    /// before the hop where the pitch settled, never before `j − attack_back_hops` nor within
    /// `min_ioi_hops` of the previous onset (a release or reverb holds the old pitch). 0 = off.
    pub pitch_back_hops: usize,
    /// Fewest hops between the previous onset and a re-attack (rule 1): a soundfont lead's
    /// level swings inside a held note several times a second, a played repeat of one pitch
    /// rarely does. Below `min_ioi_hops` it changes nothing. 0 = off.
    pub reattack_min_hops: usize,
    /// Rule 6, **guided onsets**: a pitch onset that no attack moved (rule 2 found none)
    /// goes back to the first hop of the run, ending at the decided hop, over which the
    /// *guide* pitch ([`NoteOnsets::push_guided`]) already holds the new note (within
    /// `tolerance_st` of the stable window's median), at most this many hops back (and at
    /// most `attack_back_hops`), not within `min_ioi_hops` of the previous onset;
    /// `pitch_back_hops` applies where the guide has no such run. For a tracker that
    /// reports an attack-aligned pitch beside the decoded one: a choir's slow attack
    /// cross-fades without a level rise, but the aligned pitch changes where the new note
    /// starts to sound. 0 = off; without a guide it changes nothing.
    pub guide_back_hops: usize,
    /// How far a pitch onset may move back to its attack, hops (`None`: `attack_back_hops`).
    /// With `Some(m)` the attack search still reads `attack_back_hops` past hops to keep or
    /// drop an onset (rules 2, 3 and 5), but the onset moves back at most `m` hops, so the
    /// detector's latency holds `m` hops, not `attack_back_hops` (the live profile); no other
    /// rule moves an onset (`backtrack_hops`, `pitch_back_hops` and `guide_back_hops` are
    /// ignored).
    pub attack_move_hops: Option<usize>,
}

impl NoteConfig {
    /// Pitch only: the first implementation (no re-attacks, no attack search, no minimum
    /// interval). Reads no level.
    pub fn pitch_only() -> Self {
        NoteConfig {
            stable_hops: 4,
            tolerance_st: 0.5,
            jump_st: 0.7,
            gap_hops: 2,
            reattack_db: 0.0,
            attack_back_hops: 0,
            attack_db: 0.0,
            min_ioi_hops: 0,
            resume_hops: 0,
            pitch_needs_attack: false,
            backtrack_hops: 0,
            pitch_back_hops: 0,
            reattack_min_hops: 0,
            guide_back_hops: 0,
            attack_move_hops: None,
        }
    }

    /// Whether the detector reads the level ([`NoteOnsets::push_level`]).
    pub fn uses_level(&self) -> bool {
        self.reattack_db > 0.0 || self.attack_back_hops > 0
    }
}

impl Default for NoteConfig {
    fn default() -> Self {
        NoteConfig {
            reattack_db: 6.0,
            attack_back_hops: 8,
            attack_db: 3.0,
            min_ioi_hops: 10,
            resume_hops: 10,
            ..NoteConfig::pitch_only()
        }
    }
}

/// Streaming note-onset detector on a pitch track (and, optionally, the stem's level).
/// See the module docs.
#[derive(Debug, Clone)]
pub struct NoteOnsets {
    cfg: NoteConfig,
    /// Pitch in semitones (NaN = unvoiced) of hop `k` at `k % HIST`.
    st: [f32; HIST],
    /// Level in dB (NaN = unknown) of hop `k` at `k % HIST`.
    db: [f32; HIST],
    /// Guide pitch in semitones (NaN = unvoiced or none) of hop `k` at `k % HIST`.
    guide: [f32; HIST],
    /// Onset flag of decided, not yet emitted hop `k` at `k % HIST`.
    flag: [bool; HIST],
    /// Hops pushed.
    n_in: usize,
    /// Next hop to decide.
    decided: usize,
    /// Next hop to emit.
    emitted: usize,
    current: Option<f32>,
    unvoiced: usize,
    /// The note that the last gap ended.
    ended: Option<f32>,
    /// Last onset hop (decided), if any.
    last_onset: Option<usize>,
}

impl NoteOnsets {
    /// Validates `cfg`.
    pub fn new(cfg: NoteConfig) -> Result<Self, ConfigError> {
        if !(1..=MAX_STABLE_HOPS).contains(&cfg.stable_hops) {
            return Err(ConfigError::invalid(
                "stable_hops",
                format!("must be in 1..={MAX_STABLE_HOPS}"),
            ));
        }
        if !(cfg.tolerance_st.is_finite() && cfg.tolerance_st >= 0.0) {
            return Err(ConfigError::invalid(
                "tolerance_st",
                "must be finite and ≥ 0",
            ));
        }
        if !(cfg.jump_st.is_finite() && cfg.jump_st > 0.0) {
            return Err(ConfigError::invalid("jump_st", "must be finite and > 0"));
        }
        if !(cfg.reattack_db.is_finite() && cfg.reattack_db >= 0.0) {
            return Err(ConfigError::invalid(
                "reattack_db",
                "must be finite and ≥ 0",
            ));
        }
        if !(cfg.attack_db.is_finite() && cfg.attack_db >= 0.0) {
            return Err(ConfigError::invalid("attack_db", "must be finite and ≥ 0"));
        }
        if cfg.attack_back_hops > MAX_BACK_HOPS {
            return Err(ConfigError::invalid(
                "attack_back_hops",
                format!("must be ≤ {MAX_BACK_HOPS}"),
            ));
        }
        if cfg.pitch_back_hops > MAX_BACK_HOPS {
            return Err(ConfigError::invalid(
                "pitch_back_hops",
                format!("must be ≤ {MAX_BACK_HOPS}"),
            ));
        }
        if cfg.backtrack_hops > MAX_BACK_HOPS {
            return Err(ConfigError::invalid(
                "backtrack_hops",
                format!("must be ≤ {MAX_BACK_HOPS}"),
            ));
        }
        Ok(NoteOnsets {
            cfg,
            st: [f32::NAN; HIST],
            db: [f32::NAN; HIST],
            guide: [f32::NAN; HIST],
            flag: [false; HIST],
            n_in: 0,
            decided: 0,
            emitted: 0,
            current: None,
            unvoiced: usize::MAX / 2,
            ended: None,
            last_onset: None,
        })
    }

    /// Hops of look-ahead of a decision (the stability window's, and the level rise's when
    /// the level is read).
    fn ahead(&self) -> usize {
        let a = self.cfg.stable_hops - 1;
        if self.cfg.reattack_db > 0.0 {
            a.max(RISE_AHEAD_HOPS)
        } else {
            a
        }
    }

    /// Hops of look-ahead: hop `j` is emitted when hop `j + latency_hops()` arrives (the
    /// decision's look-ahead plus the attack search, which may still move an onset back).
    pub fn latency_hops(&self) -> usize {
        self.ahead() + self.move_back_hops()
    }

    /// Hops an onset may still move back after its hop is decided.
    fn move_back_hops(&self) -> usize {
        let back = self.cfg.attack_back_hops;
        self.cfg.attack_move_hops.map_or(back, |m| m.min(back))
    }

    /// Feeds hop `i`'s f0 (hops in order, from 0) without a level; calls `emit(j, onset)`
    /// for hop `j = i − latency_hops()` once it is decided.
    pub fn push(&mut self, f0_hz: f32, emit: &mut dyn FnMut(usize, bool)) {
        self.push_level(f0_hz, f32::NAN, emit);
    }

    /// Feeds hop `i`'s f0 and the stem's level at that hop (dB; NaN = unknown, which never
    /// rises); calls `emit(j, onset)` for hop `j = i − latency_hops()` once it is decided.
    pub fn push_level(&mut self, f0_hz: f32, level_db: f32, emit: &mut dyn FnMut(usize, bool)) {
        self.push_guided(f0_hz, level_db, f32::NAN, emit);
    }

    /// Feeds hop `i`'s f0, level and guide pitch (Hz, 0 or NaN = none; read only by rule 6,
    /// [`NoteConfig::guide_back_hops`]); calls `emit(j, onset)` for hop `j = i − latency_hops()`
    /// once it is decided.
    pub fn push_guided(
        &mut self,
        f0_hz: f32,
        level_db: f32,
        guide_hz: f32,
        emit: &mut dyn FnMut(usize, bool),
    ) {
        let semis = |f: f32| {
            if f.is_finite() && f > 0.0 {
                hz_to_semitones(f)
            } else {
                f32::NAN
            }
        };
        let k = self.n_in % HIST;
        self.st[k] = semis(f0_hz);
        self.guide[k] = semis(guide_hz);
        self.db[k] = if level_db.is_finite() {
            level_db
        } else {
            f32::NAN
        };
        self.n_in += 1;
        let ahead = self.ahead();
        while self.decided + ahead < self.n_in {
            self.decide();
        }
        self.drain(emit, false);
    }

    /// Ends the stream: decides and emits the remaining hops (their windows run past the
    /// end, so they cannot start a note by pitch).
    pub fn finish(&mut self, emit: &mut dyn FnMut(usize, bool)) {
        while self.decided < self.n_in {
            self.decide();
        }
        self.drain(emit, true);
    }

    fn drain(&mut self, emit: &mut dyn FnMut(usize, bool), all: bool) {
        let back = self.move_back_hops();
        while self.emitted < self.decided && (all || self.emitted + back < self.decided) {
            let k = self.emitted % HIST;
            emit(self.emitted, self.flag[k]);
            self.flag[k] = false;
            self.emitted += 1;
        }
    }

    fn level(&self, h: usize) -> f32 {
        if h < self.n_in && h + HIST > self.n_in {
            self.db[h % HIST]
        } else {
            f32::NAN
        }
    }

    /// Level step into hop `h` (NaN when unknown).
    fn step(&self, h: usize) -> f32 {
        if h == 0 {
            return f32::NAN;
        }
        self.level(h) - self.level(h - 1)
    }

    /// Rise of the level at hop `h`: the maximum of hops `h ..= h + RISE_AHEAD_HOPS` minus
    /// the minimum of the `RISE_BEHIND_HOPS` hops before (NaN when any is unknown).
    fn rise(&self, h: usize) -> f32 {
        if h < RISE_BEHIND_HOPS {
            return f32::NAN;
        }
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for x in h - RISE_BEHIND_HOPS..=h + RISE_AHEAD_HOPS {
            let v = self.level(x);
            if v.is_nan() {
                return f32::NAN;
            }
            if x < h {
                lo = lo.min(v);
            } else {
                hi = hi.max(v);
            }
        }
        hi - lo
    }

    /// Whether hop `h`'s level step is the steepest of hops `h − 1 ..= h + RISE_AHEAD_HOPS`
    /// (ties go to the earliest).
    fn steepest(&self, h: usize) -> bool {
        let s = self.step(h);
        if s.is_nan() || s <= 0.0 {
            return false;
        }
        let before = self.step(h - 1);
        if !before.is_nan() && s <= before {
            return false;
        }
        (h + 1..=h + RISE_AHEAD_HOPS).all(|a| {
            let t = self.step(a);
            t.is_nan() || s >= t
        })
    }

    fn spaced(&self, h: usize) -> bool {
        match self.last_onset {
            Some(l) => h >= l + self.cfg.min_ioi_hops.max(1),
            None => true,
        }
    }

    /// Decides hop `decided` from the hops that have arrived (at the end of the stream a
    /// window may run past the last hop: it is not stable, and a rise needs every hop it
    /// reads).
    fn decide(&mut self) {
        let j = self.decided;
        self.decided += 1;
        let n = self.cfg.stable_hops;
        let first = self.st[j % HIST];
        if first.is_nan() {
            self.unvoiced = self.unvoiced.saturating_add(1);
            if self.unvoiced > self.cfg.gap_hops {
                if let Some(c) = self.current.take() {
                    self.ended = Some(c);
                }
            }
            return;
        }
        let gap = self.unvoiced;
        self.unvoiced = 0;
        let len = (self.n_in - j).min(n);
        let mut w = [0f32; MAX_STABLE_HOPS];
        for (k, v) in w[..len].iter_mut().enumerate() {
            *v = self.st[(j + k) % HIST];
        }
        let w = &w[..len];
        let stable = len == n && w.iter().all(|v| !v.is_nan()) && {
            let med = median(w);
            w.iter().all(|v| (v - med).abs() <= self.cfg.tolerance_st)
        };
        let med = if stable { median(w) } else { f32::NAN };
        let pitch_onset = match self.current {
            _ if !stable => false,
            None => true,
            Some(c) => (first - c).abs() >= self.cfg.jump_st,
        };
        if pitch_onset {
            // Voicing resumed on the note a short gap ended: a dropout unless it is attacked.
            let resumed = self.current.is_none()
                && self.cfg.resume_hops > 0
                && self.cfg.attack_back_hops > 0
                && gap <= self.cfg.resume_hops
                && self
                    .ended
                    .is_some_and(|p| (med - p).abs() < self.cfg.jump_st);
            // A change of note that must be attacked (a plucked bass on a mixture).
            let need = resumed
                || (self.cfg.pitch_needs_attack
                    && self.cfg.attack_back_hops > 0
                    && self.current.is_some());
            self.current = Some(med);
            self.pitch_onset_at(j, med, need);
            return;
        }
        if stable {
            if let Some(c) = self.current {
                // Follow the note's centre slowly (vibrato averages out, a drift is followed).
                self.current = Some(c + FOLLOW * (med - c));
            }
        }
        // A re-attack inside the held note.
        if self.cfg.reattack_db > 0.0 {
            if let Some(c) = self.current {
                let rmin = self.cfg.reattack_min_hops;
                if (first - c).abs() < self.cfg.jump_st
                    && self.spaced(j)
                    && self.last_onset.is_none_or(|l| j >= l + rmin)
                    && self.rise(j) >= self.cfg.reattack_db
                    && self.steepest(j)
                {
                    let h = self.foot(j, j);
                    self.mark(h);
                }
            }
        }
    }

    /// A pitch onset decided at hop `j`: moved back to the attack before it, dropped when a
    /// note already started there, or kept at `j`.
    fn pitch_onset_at(&mut self, j: usize, med: f32, need_attack: bool) {
        let back = self.cfg.attack_back_hops;
        let limited = self.cfg.attack_move_hops.is_some();
        if back > 0 {
            // A limited move still searches hops already emitted (their levels are kept).
            let from = if limited {
                j.saturating_sub(back)
            } else {
                j.saturating_sub(back).max(self.emitted)
            };
            if self.last_onset.is_some_and(|l| l >= from) {
                return; // a re-attack in the window already started this note
            }
            let mut best: Option<(usize, f32)> = None;
            for h in from..j {
                if !limited && !self.spaced(h) {
                    continue;
                }
                let r = self.rise(h);
                if r >= self.cfg.attack_db && self.steepest(h) {
                    let s = self.step(h);
                    if best.is_none_or(|(_, b)| s > b) {
                        best = Some((h, s));
                    }
                }
            }
            if let Some((h, _)) = best {
                if limited {
                    let h = h
                        .max(j.saturating_sub(self.move_back_hops()))
                        .max(self.emitted);
                    if self.spaced(h) {
                        self.mark(h);
                    } else if self.spaced(j) {
                        self.mark(j);
                    }
                } else {
                    let h = self.foot(h, j);
                    self.mark(h);
                }
                return;
            }
            if need_attack {
                return;
            }
        }
        if self.spaced(j) {
            if limited {
                self.mark(j);
                return;
            }
            if let Some(h) = self.guided_start(j, med) {
                self.mark(h);
                return;
            }
            let mut h = j.saturating_sub(self.cfg.pitch_back_hops);
            if self.cfg.pitch_back_hops > 0 {
                h = h.max(j.saturating_sub(back));
                if let Some(l) = self.last_onset {
                    h = h.max(l + self.cfg.min_ioi_hops.max(1));
                }
            }
            self.mark(h);
        }
    }

    /// Rule 6 ([`NoteConfig::guide_back_hops`]): the first hop of the run of hops before `j`
    /// whose guide pitch holds the note `med` (within `tolerance_st`), reaching back at most
    /// `guide_back_hops` and `attack_back_hops`, never to an emitted hop nor within the
    /// minimum interval of the last onset; `None` when the run is empty or the rule is off.
    fn guided_start(&self, j: usize, med: f32) -> Option<usize> {
        if self.cfg.guide_back_hops == 0 {
            return None;
        }
        let mut lo = j
            .saturating_sub(self.cfg.attack_back_hops)
            .max(self.emitted);
        if let Some(l) = self.last_onset {
            lo = lo.max(l + self.cfg.min_ioi_hops.max(1));
        }
        let lo = lo.max(j.saturating_sub(self.cfg.guide_back_hops));
        let mut h = j;
        while h > lo {
            let g = self.guide[(h - 1) % HIST];
            if g.is_nan() || (g - med).abs() > self.cfg.tolerance_st {
                break;
            }
            h -= 1;
        }
        (h < j).then_some(h)
    }

    /// The foot of the rise that attacks at hop `h` (decided at hop `j`): walks back over
    /// rising steps, at most `backtrack_hops`, not before `j − attack_back_hops` nor within
    /// the minimum interval of the last onset.
    fn foot(&self, h: usize, j: usize) -> usize {
        let t = self.cfg.backtrack_hops;
        // A limited move ([`NoteConfig::attack_move_hops`]) never goes to the foot.
        if t == 0 || self.cfg.attack_move_hops.is_some() {
            return h;
        }
        let mut lo = j
            .saturating_sub(self.cfg.attack_back_hops)
            .max(h.saturating_sub(t));
        if let Some(l) = self.last_onset {
            lo = lo.max(l + self.cfg.min_ioi_hops.max(1));
        }
        let mut x = h;
        // Hop x − 1 is the foot while the step into it is not a rise.
        while x > lo && x >= 2 && self.step(x - 1) > 0.0 {
            x -= 1;
        }
        if x > lo {
            x - 1
        } else {
            x
        }
    }

    fn mark(&mut self, h: usize) {
        self.flag[h % HIST] = true;
        self.last_onset = Some(h);
    }

    /// Back to the initial state.
    pub fn reset(&mut self) {
        self.st = [f32::NAN; HIST];
        self.db = [f32::NAN; HIST];
        self.guide = [f32::NAN; HIST];
        self.flag = [false; HIST];
        self.n_in = 0;
        self.decided = 0;
        self.emitted = 0;
        self.current = None;
        self.unvoiced = usize::MAX / 2;
        self.ended = None;
        self.last_onset = None;
    }
}

/// Lower median of a short non-NaN slice (copied and sorted on the stack).
fn median(w: &[f32]) -> f32 {
    let mut s = [0f32; MAX_STABLE_HOPS];
    let s = &mut s[..w.len()];
    s.copy_from_slice(w);
    s.sort_unstable_by(f32::total_cmp);
    s[(s.len() - 1) / 2]
}

/// Note onsets of a whole pitch track (Hz per hop): one flag per hop. Allocates the result.
pub fn note_onsets_offline(f0_hz: &[f32], cfg: NoteConfig) -> Result<Vec<bool>, ConfigError> {
    note_onsets_offline_level(f0_hz, &[], cfg)
}

/// Note onsets of a whole pitch track (Hz per hop) and the stem's level per hop (dB; a
/// missing value counts as unknown): one flag per hop. Allocates the result.
pub fn note_onsets_offline_level(
    f0_hz: &[f32],
    level_db: &[f32],
    cfg: NoteConfig,
) -> Result<Vec<bool>, ConfigError> {
    note_onsets_offline_guided(f0_hz, level_db, &[], cfg)
}

/// Note onsets of a whole pitch track (Hz per hop), the stem's level per hop (dB) and a
/// guide pitch per hop (Hz; [`NoteConfig::guide_back_hops`]; a missing value counts as none): one
/// flag per hop. Allocates the result.
pub fn note_onsets_offline_guided(
    f0_hz: &[f32],
    level_db: &[f32],
    guide_hz: &[f32],
    cfg: NoteConfig,
) -> Result<Vec<bool>, ConfigError> {
    let mut d = NoteOnsets::new(cfg)?;
    let mut out = vec![false; f0_hz.len()];
    let mut put = |j: usize, o: bool| {
        if let Some(x) = out.get_mut(j) {
            *x = o;
        }
    };
    for (i, &f) in f0_hz.iter().enumerate() {
        let l = level_db.get(i).copied().unwrap_or(f32::NAN);
        let g = guide_hz.get(i).copied().unwrap_or(f32::NAN);
        d.push_guided(f, l, g, &mut put);
    }
    d.finish(&mut put);
    Ok(out)
}
