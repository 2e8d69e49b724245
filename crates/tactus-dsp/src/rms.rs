//! Frame RMS in dBFS and the 35 dB energy gate.
//!
//! **Algorithm.** For every hop the RMS of the frame centred on it (see [`crate::framer`]) is
//! `sqrt(mean(x²))`, accumulated in `f64`, and reported as `10·log10(mean(x²))` dBFS
//! (a full-scale square wave is 0 dBFS, a full-scale sine −3.01 dBFS). Digital silence has no
//! logarithm; it is reported as [`SILENCE_DB`] (−200 dB), never −∞ or NaN. Non-finite input
//! samples are replaced by 0 and counted ([`Rms::non_finite_samples`]).
//!
//! **Gate (the paper, §2: "a predefined threshold, which is 35 dB").** A hop is *open*
//! (voiced / may carry an onset) when its RMS is at most [`GATE_BELOW_DB`] below a reference:
//! * offline ([`gate_offline`], paper-faithful): the reference is the track's maximum RMS;
//! * streaming ([`StreamingGate`]): the reference is a running maximum that decays by
//!   [`DEFAULT_DECAY_DB_PER_S`] per second, and hops at or under an absolute floor
//!   ([`DEFAULT_FLOOR_DB`]) are never open, so near-silence after a long pause stays closed.
//!
//! **Defaults.** The engine uses the pitch tracker's frame and hop (e.g. 2048 / 441 samples
//! at 44.1 kHz) so that RMS hop `i` and pitch hop `i` describe the same instant.
//!
//! **Latency.** [`Rms`] emits hop `i` once sample `i·hop + frame − frame/2 − 1` has arrived
//! (the framer's latency). The gates add none: [`StreamingGate`] is causal and decides each hop
//! from that hop and the past; [`gate_offline`] needs the whole track.

use crate::framer::Framer;
use crate::{ConfigError, HopStage};

/// What [`Rms`] reports for a frame of digital silence (and the lower clamp of every value).
pub const SILENCE_DB: f32 = -200.0;

/// The paper's gate: hops more than this many dB below the reference are closed.
pub const GATE_BELOW_DB: f32 = 35.0;

/// Default decay of the streaming reference, in dB per second.
///
/// Our choice. A quiet passage `x` dB below the gate (i.e. `35 + x` dB under a loud one) re-opens
/// after `x / 3` seconds: a verse 10 dB "too quiet" after a loud chorus is gated for 3.3 s, about
/// one musical phrase, instead of forever (offline behaviour) or instantly (no reference at all).
/// Passages within 35 dB of the loud part stay open throughout, as offline.
pub const DEFAULT_DECAY_DB_PER_S: f32 = 3.0;

/// Default absolute floor of the streaming gate, in dBFS: hops at or below it are never open.
///
/// Our choice. After a long pause the decaying reference keeps falling, so without a floor any
/// residue (dither, separation leakage, a few LSBs of noise) would eventually count as signal.
/// −80 dBFS lies above 16-bit dither (≈ −101 dBFS) and typical separation leakage in silent
/// stretches, and far below any musically meaningful passage.
pub const DEFAULT_FLOOR_DB: f32 = -80.0;

/// RMS level of one frame in dBFS, floored at [`SILENCE_DB`]. Accumulates in `f64`.
///
/// Samples are used as given (the [`Rms`] stage sanitizes them first); an empty frame is silence.
#[inline]
pub fn frame_rms_db(frame: &[f32]) -> f32 {
    if frame.is_empty() {
        return SILENCE_DB;
    }
    // Four independent accumulators let the compiler pipeline the f64 multiply-adds.
    let mut acc = [0.0f64; 4];
    let mut chunks = frame.chunks_exact(4);
    for c in &mut chunks {
        for (a, &x) in acc.iter_mut().zip(c) {
            let x = f64::from(x);
            *a += x * x;
        }
    }
    let mut sum = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for &x in chunks.remainder() {
        let x = f64::from(x);
        sum += x * x;
    }
    let mean = sum / frame.len() as f64;
    if mean.is_finite() && mean > 0.0 {
        ((10.0 * mean.log10()) as f32).max(SILENCE_DB)
    } else {
        SILENCE_DB
    }
}

/// Frame RMS in dBFS, one value per hop. See the module docs.
#[derive(Debug, Clone)]
pub struct Rms {
    framer: Framer,
    non_finite: usize,
}

impl Rms {
    /// An RMS stage with `frame` samples per frame and `hop` samples between frame centres.
    /// Errors when either is 0. Allocates the framer's buffer (`2·frame + hop` samples) once.
    pub fn new(frame: usize, hop: usize) -> Result<Self, ConfigError> {
        Ok(Rms {
            framer: Framer::new(frame, hop)?,
            non_finite: 0,
        })
    }

    /// Samples per frame.
    pub fn frame_len(&self) -> usize {
        self.framer.frame_len()
    }

    /// NaN or infinite input samples seen since construction or the last reset (each was
    /// treated as 0).
    pub fn non_finite_samples(&self) -> usize {
        self.non_finite
    }
}

impl HopStage for Rms {
    type Out = f32;

    fn process(&mut self, input: &[f32], emit: &mut dyn FnMut(usize, f32)) {
        self.non_finite += self
            .framer
            .push(input, |i, frame| emit(i, frame_rms_db(frame)));
    }

    fn finish(&mut self, emit: &mut dyn FnMut(usize, f32)) {
        self.framer.finish(|i, frame| emit(i, frame_rms_db(frame)));
    }

    fn reset(&mut self) {
        self.framer.reset();
        self.non_finite = 0;
    }

    fn latency_samples(&self) -> usize {
        self.framer.latency_samples()
    }

    fn hop(&self) -> usize {
        self.framer.hop()
    }
}

/// Offline gate (paper-faithful): the reference is the track's maximum RMS.
///
/// Sets `open[i] = rms_db[i] >= reference - below_db` and returns the reference. Non-finite entries
/// (NaN, ±∞) are ignored when finding the maximum and are closed. When the track is digital silence
/// (reference ≤ [`SILENCE_DB`], or no finite value) every hop is closed, and so is every hop at
/// [`SILENCE_DB`]. Only `min(rms_db.len(), open.len())` entries are decided; any further entries
/// of `open` are set to `false`. Does not allocate. A non-finite or negative `below_db` is
/// treated as [`GATE_BELOW_DB`].
pub fn gate_offline(rms_db: &[f32], below_db: f32, open: &mut [bool]) -> f32 {
    let below = if below_db.is_finite() && below_db >= 0.0 {
        below_db
    } else {
        GATE_BELOW_DB
    };
    let reference = rms_db
        .iter()
        .copied()
        .filter(|x| x.is_finite())
        .fold(SILENCE_DB, f32::max)
        .max(SILENCE_DB);
    let threshold = reference - below;
    let n = rms_db.len().min(open.len());
    let silent_track = reference <= SILENCE_DB;
    for (o, &x) in open[..n].iter_mut().zip(rms_db) {
        *o = !silent_track && x.is_finite() && x > SILENCE_DB && x >= threshold;
    }
    open[n..].fill(false);
    reference
}

/// Streaming gate: the reference is a decaying running maximum. Causal, no allocation.
///
/// For each hop with level `x` (dBFS; NaN and ±∞ count as [`SILENCE_DB`]):
/// `reference = max(reference − decay·hop_s, x)` (never below [`SILENCE_DB`]), and the hop is
/// open when `x > floor` and `x >= reference − below_db`.
#[derive(Debug, Clone)]
pub struct StreamingGate {
    below_db: f32,
    decay_per_hop: f32,
    floor_db: f32,
    reference: f32,
}

impl StreamingGate {
    /// A gate `below_db` under a reference that decays `decay_db_per_s` per second, for hops of
    /// `hop_s` seconds, with the default absolute floor [`DEFAULT_FLOOR_DB`].
    ///
    /// Errors unless `below_db ≥ 0`, `decay_db_per_s ≥ 0` and `hop_s > 0`, all finite.
    /// The paper's values are `below_db = GATE_BELOW_DB`; see [`DEFAULT_DECAY_DB_PER_S`].
    pub fn new(below_db: f32, decay_db_per_s: f32, hop_s: f32) -> Result<Self, ConfigError> {
        if !(below_db.is_finite() && below_db >= 0.0) {
            return Err(ConfigError::invalid("below_db", "must be finite and >= 0"));
        }
        if !(decay_db_per_s.is_finite() && decay_db_per_s >= 0.0) {
            return Err(ConfigError::invalid(
                "decay_db_per_s",
                "must be finite and >= 0",
            ));
        }
        if !(hop_s.is_finite() && hop_s > 0.0) {
            return Err(ConfigError::invalid("hop_s", "must be finite and > 0"));
        }
        Ok(StreamingGate {
            below_db,
            decay_per_hop: decay_db_per_s * hop_s,
            floor_db: DEFAULT_FLOOR_DB,
            reference: SILENCE_DB,
        })
    }

    /// Replaces the absolute floor (dBFS). Errors when `floor_db` is not finite.
    pub fn with_floor_db(mut self, floor_db: f32) -> Result<Self, ConfigError> {
        if !floor_db.is_finite() {
            return Err(ConfigError::invalid("floor_db", "must be finite"));
        }
        self.floor_db = floor_db;
        Ok(self)
    }

    /// The current reference level in dBFS.
    pub fn reference_db(&self) -> f32 {
        self.reference
    }

    /// Feeds one hop's RMS level; returns whether the hop is open.
    #[inline]
    pub fn process(&mut self, rms_db: f32) -> bool {
        let x = if rms_db.is_finite() {
            rms_db.max(SILENCE_DB)
        } else {
            SILENCE_DB
        };
        self.reference = (self.reference - self.decay_per_hop).max(x).max(SILENCE_DB);
        x > self.floor_db && x >= self.reference - self.below_db
    }

    /// Back to the just-constructed state (reference at [`SILENCE_DB`]).
    pub fn reset(&mut self) {
        self.reference = SILENCE_DB;
    }
}
