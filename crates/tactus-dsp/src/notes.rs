//! Note onsets from a pitch track: a new note starts where voicing begins or where the
//! pitch moves to a new stable note.
//!
//! Spectral flux sees attacks; a sung or legato note changes pitch without one (issue 16,
//! item 4). This stage reads the tracked f0 per hop (Hz, 0 = unvoiced, after gate and fences)
//! and marks hop `j` as a **note onset** when the `stable` hops `j ..= j + stable − 1` are all
//! voiced and lie within ± `tolerance_st` semitones of their median (a stable note), and
//! either no note is current (voicing began, or resumed after more than `gap_hops` unvoiced
//! hops) or hop `j`'s pitch is at least `jump_st` semitones from the current note's. The new
//! note's pitch is the window's median; while the note lasts, each later stable window pulls
//! it 3 % of the way towards its own median, so it settles on the note's centre. Vibrato (±35 cents) and scoops (−40 cents) stay inside one
//! note; a bend or glide only starts a note once it settles.
//!
//! In the spirit of note segmentation on pYIN's track (Mauch et al., "Computer-aided melody
//! note transcription using the Tony software: accuracy and efficiency", 2015), reduced to a
//! causal rule with a fixed look-ahead.
//!
//! **Defaults** ([`NoteConfig::default`]): stable 4 hops (40 ms at 10 ms hops), tolerance
//! 0.5 semitone, jump 0.7 semitone, gap 2 hops. Tuned on 4 chorales of the corpus
//! (`benches/bass_eval.py`).
//!
//! **Latency**: `stable − 1` hops (hop `j` is decided when hop `j + stable − 1` arrives).
//! Allocation-free; O(stable) per hop.

use crate::{hz_to_semitones, ConfigError};

/// How fast the current note's pitch follows later stable windows (per hop).
const FOLLOW: f32 = 0.03;

/// Longest stability window accepted.
pub const MAX_STABLE_HOPS: usize = 32;

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
}

impl Default for NoteConfig {
    fn default() -> Self {
        NoteConfig {
            stable_hops: 4,
            tolerance_st: 0.5,
            jump_st: 0.7,
            gap_hops: 2,
        }
    }
}

/// Streaming note-onset detector on a pitch track. See the module docs.
#[derive(Debug, Clone)]
pub struct NoteOnsets {
    cfg: NoteConfig,
    /// The last `stable_hops` values in semitones (NaN = unvoiced), in arrival order.
    ring: [f32; MAX_STABLE_HOPS],
    len: usize,
    head: usize,
    current: Option<f32>,
    unvoiced: usize,
    next_out: usize,
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
        Ok(NoteOnsets {
            cfg,
            ring: [f32::NAN; MAX_STABLE_HOPS],
            len: 0,
            head: 0,
            current: None,
            unvoiced: usize::MAX / 2,
            next_out: 0,
        })
    }

    /// Hops of look-ahead.
    pub fn latency_hops(&self) -> usize {
        self.cfg.stable_hops - 1
    }

    /// Feeds hop `i`'s f0 (hops in order, from 0); calls `emit(j, onset)` for hop
    /// `j = i − latency_hops()` once it is decided.
    pub fn push(&mut self, f0_hz: f32, emit: &mut dyn FnMut(usize, bool)) {
        let st = if f0_hz.is_finite() && f0_hz > 0.0 {
            hz_to_semitones(f0_hz)
        } else {
            f32::NAN
        };
        let n = self.cfg.stable_hops;
        if self.len < n {
            self.ring[(self.head + self.len) % n] = st;
            self.len += 1;
        } else {
            self.ring[self.head] = st;
            self.head = (self.head + 1) % n;
        }
        if self.len == n {
            let onset = self.decide();
            emit(self.next_out, onset);
            self.next_out += 1;
        }
    }

    /// Ends the stream: decides the remaining hops (their windows run past the end, so they
    /// cannot start a note).
    pub fn finish(&mut self, emit: &mut dyn FnMut(usize, bool)) {
        let n = self.cfg.stable_hops;
        if self.len == n {
            // A full window's oldest hop was decided when the window filled.
            self.head = (self.head + 1) % n;
            self.len -= 1;
        }
        while self.len > 0 {
            // The window shrinks: the oldest hop is decided, then dropped.
            let onset = self.decide_partial();
            emit(self.next_out, onset);
            self.next_out += 1;
            self.head = (self.head + 1) % n;
            self.len -= 1;
        }
    }

    /// Decides the oldest hop of a full window.
    fn decide(&mut self) -> bool {
        let n = self.cfg.stable_hops;
        let mut w = [0f32; MAX_STABLE_HOPS];
        for (k, v) in w[..n].iter_mut().enumerate() {
            *v = self.ring[(self.head + k) % n];
        }
        self.decide_window(&w[..n], true)
    }

    /// Decides the oldest hop of a window cut short by the end of the stream.
    fn decide_partial(&mut self) -> bool {
        let n = self.cfg.stable_hops;
        let mut w = [0f32; MAX_STABLE_HOPS];
        for (k, v) in w[..self.len].iter_mut().enumerate() {
            *v = self.ring[(self.head + k) % n];
        }
        let full = self.len == n;
        let len = self.len;
        self.decide_window(&w[..len], full)
    }

    fn decide_window(&mut self, w: &[f32], full: bool) -> bool {
        let first = w[0];
        if first.is_nan() {
            self.unvoiced = self.unvoiced.saturating_add(1);
            if self.unvoiced > self.cfg.gap_hops {
                self.current = None;
            }
            return false;
        }
        self.unvoiced = 0;
        let stable = full && w.iter().all(|v| !v.is_nan()) && {
            let med = median(w);
            w.iter().all(|v| (v - med).abs() <= self.cfg.tolerance_st)
        };
        if !stable {
            return false;
        }
        let med = median(w);
        match self.current {
            None => {
                self.current = Some(med);
                true
            }
            Some(c) if (first - c).abs() >= self.cfg.jump_st => {
                self.current = Some(med);
                true
            }
            Some(c) => {
                // Follow the note's centre slowly (vibrato averages out, a drift is followed).
                self.current = Some(c + FOLLOW * (med - c));
                false
            }
        }
    }

    /// Back to the initial state.
    pub fn reset(&mut self) {
        self.len = 0;
        self.head = 0;
        self.current = None;
        self.unvoiced = usize::MAX / 2;
        self.next_out = 0;
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
    let mut d = NoteOnsets::new(cfg)?;
    let mut out = vec![false; f0_hz.len()];
    let mut put = |j: usize, o: bool| {
        if let Some(x) = out.get_mut(j) {
            *x = o;
        }
    };
    for &f in f0_hz {
        d.push(f, &mut put);
    }
    d.finish(&mut put);
    Ok(out)
}
