//! Two-frame YIN for the live profile (`docs/decisions/0013-two-frame-yin-for-live-pitch.md`):
//! a short frame answers first, a long frame answers for the lowest octave.
//!
//! YIN needs two periods of the lowest note in its frame, so a bass frame from 41 Hz (E1) is
//! 48.8 ms long, and a new note shows once most of that frame holds it: on the live bench a
//! 98 Hz tone reached the thumb's pitch cell 66 ms (median) after it began, although it sits
//! an octave and more above the frame's lowest note. [`TwoFrameYin`] runs two YIN stages on
//! the same stream, split at a frequency `split` above `fmin`:
//!
//! * **short**: `[split, fmax]`, a frame of two periods of `split` (`split = 2·fmin`: half
//!   as long);
//! * **long**: `[fmin, fmax]`, the frame the range needs.
//!
//! Hop `i` is emitted as soon as the short stage has it; the long stage's newest estimate
//! then is hop `i − lag`, with `lag = ⌈(latency_long − latency_short) / hop⌉`. Per hop:
//!
//! * the long frame's estimate, when it is a note below the split (below
//!   `split · 2^(1/12)`): the short frame cannot see such a note, and what it reports then
//!   is a harmonic or an answer at the edge of its range. Over a voiced short frame, the
//!   long frame must have held that note (within a semitone) for two hops: a single low hop
//!   at the start of a higher note is the long frame's own octave error;
//! * otherwise the short frame's estimate, voiced or not: it is the fresher of the two; but
//!   an estimate below `split` (a dip at the very end of its lag range, moved below it by
//!   the interpolation) is the edge of a lower note, and counts as unvoiced.
//!
//! So notes from `split` up are shown with the short frame's latency, and notes below it
//! `lag` hops later, which is at most one hop after the long frame alone would have shown
//! them. In the hop-aligned output (a rendered features file) those low notes therefore sit
//! `lag` hops late. The cost: the first hops of a low note whose fundamental is weak may show
//! its octave (the short frame's answer) before the long frame takes over.
//!
//! ## Latency
//! The short stage's: `frame_short − frame_short / 2` samples.
//!
//! The block is fed to both stages one hop at a time (long first), so that the long
//! estimates waiting for their short partner never exceed `lag + 2`: a fixed ring, no
//! allocation after [`TwoFrameYin::new`]. The output is the same for any chunking of the input.

use crate::yin::{PitchEstimate, Yin, YinConfig};
use crate::{ConfigError, HopStage};

/// Ring of long-frame estimates (and of the short hops one call collects): [`TwoFrameYin::new`]
/// accepts only configurations whose waiting estimates fit.
const RING: usize = 32;
/// One semitone: the short frame defers to a long-frame note below `split · SEMITONE`.
const SEMITONE: f32 = 1.059_463_1;

/// See the module docs.
#[derive(Debug)]
pub struct TwoFrameYin {
    short: Yin,
    long: Yin,
    lag: usize,
    hop: usize,
    /// The short frame's lowest note, Hz.
    split_hz: f32,
    ring: [PitchEstimate; RING],
    /// Long estimates received (the next one is hop `long_seen`).
    long_seen: usize,
}

impl TwoFrameYin {
    /// The long frame's configuration `long` (range `[fmin, fmax]`, its frame and hop); the
    /// short frame gets `[split_hz, fmax]` with the frame `short_frame` (two periods of
    /// `split_hz` or more). Errors when either is invalid, when the short frame is not
    /// shorter, or when `split_hz` is not inside `(fmin, fmax)`.
    pub fn new(long: YinConfig, split_hz: f32, short_frame: usize) -> Result<Self, ConfigError> {
        let inside = |lo: f32, x: f32, hi: f32| {
            lo.partial_cmp(&x) == Some(std::cmp::Ordering::Less)
                && x.partial_cmp(&hi) == Some(std::cmp::Ordering::Less)
        };
        if !inside(long.fmin_hz, split_hz, long.fmax_hz) {
            return Err(ConfigError::invalid(
                "split_hz",
                "the short frame's lowest note must lie between fmin and fmax",
            ));
        }
        if short_frame >= long.frame {
            return Err(ConfigError::invalid(
                "frame",
                "the short frame must be shorter than the long one",
            ));
        }
        let mut sc = long.clone();
        sc.fmin_hz = split_hz;
        sc.frame = short_frame;
        let short = Yin::new(sc)?;
        let long = Yin::new(long)?;
        let hop = long.hop();
        let lag = (long.latency_samples() - short.latency_samples()).div_ceil(hop);
        // Waiting long estimates: at most `lag` plus the short hops still due at the end.
        let due = short.latency_samples().div_ceil(hop) + 2;
        if lag + due > RING {
            return Err(ConfigError::invalid(
                "frame",
                format!(
                    "the frames are too long for the hop: {} hops of look-ahead (at most {RING})",
                    lag + due
                ),
            ));
        }
        Ok(TwoFrameYin {
            short,
            long,
            lag,
            hop,
            split_hz,
            ring: [PitchEstimate::SILENT; RING],
            long_seen: 0,
        })
    }

    /// Hops by which the long frame's estimate trails the emitted hop.
    pub fn lag_hops(&self) -> usize {
        self.lag
    }

    /// The per-hop rule of the module docs: `short` for hop `i`, `long` for hop `i − lag`
    /// and `long_before` for the hop before that.
    pub fn pick(
        &self,
        short: PitchEstimate,
        long: Option<PitchEstimate>,
        long_before: Option<PitchEstimate>,
    ) -> PitchEstimate {
        let lowest = |e: &PitchEstimate| e.is_voiced() && e.f0_hz < self.split_hz * SEMITONE;
        // A short-frame answer below its range is the edge of a lower note: unvoiced.
        let short = if short.is_voiced() && short.f0_hz < self.split_hz {
            PitchEstimate {
                f0_hz: 0.0,
                voiced_prob: 0.0,
                ..short
            }
        } else {
            short
        };
        match long {
            // Over a voiced short frame only when the long frame held the note for two hops:
            // a single low hop at a note's start is the long frame's own octave error.
            Some(l)
                if lowest(&l)
                    && (!short.is_voiced()
                        || long_before.is_some_and(|b| {
                            lowest(&b) && (b.f0_hz / l.f0_hz - 1.0).abs() < SEMITONE - 1.0
                        })) =>
            {
                l
            }
            _ => short,
        }
    }

    fn emit_short(
        &mut self,
        i: usize,
        s: PitchEstimate,
        emit: &mut dyn FnMut(usize, PitchEstimate),
    ) {
        let long_at = |back: usize| {
            (i >= self.lag + back && i - self.lag - back < self.long_seen)
                .then(|| self.ring[(i - self.lag - back) % RING])
        };
        emit(i, self.pick(s, long_at(0), long_at(1)));
    }

    /// Feeds both stages up to one hop, long first; `finish` closes both instead.
    fn step(&mut self, chunk: &[f32], finish: bool, emit: &mut dyn FnMut(usize, PitchEstimate)) {
        let (ring, seen) = (&mut self.ring, &mut self.long_seen);
        let mut keep = |j: usize, e: PitchEstimate| {
            debug_assert_eq!(j, *seen);
            ring[j % RING] = e;
            *seen = j + 1;
        };
        if finish {
            self.long.finish(&mut keep);
        } else {
            self.long.process(chunk, &mut keep);
        }
        // The short stage's hops, collected first (at most a few per call) so that `self`
        // is free for the rule.
        let mut got = [(0usize, PitchEstimate::SILENT); RING];
        let mut n = 0;
        let mut put = |i: usize, e: PitchEstimate| {
            got[n] = (i, e);
            n += 1;
        };
        if finish {
            self.short.finish(&mut put);
        } else {
            self.short.process(chunk, &mut put);
        }
        for &(i, e) in &got[..n] {
            self.emit_short(i, e, emit);
        }
    }
}

impl HopStage for TwoFrameYin {
    type Out = PitchEstimate;

    fn process(&mut self, input: &[f32], emit: &mut dyn FnMut(usize, PitchEstimate)) {
        for chunk in input.chunks(self.hop) {
            self.step(chunk, false, emit);
        }
    }

    fn finish(&mut self, emit: &mut dyn FnMut(usize, PitchEstimate)) {
        self.step(&[], true, emit);
    }

    fn reset(&mut self) {
        self.short.reset();
        self.long.reset();
        self.ring = [PitchEstimate::SILENT; RING];
        self.long_seen = 0;
    }

    fn latency_samples(&self) -> usize {
        self.short.latency_samples()
    }

    fn hop(&self) -> usize {
        self.hop
    }
}
