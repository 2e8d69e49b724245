//! Log mel-band power per hop, with a chosen look-ahead: the front end of the drum
//! transcriber ([`crate::drums`]).
//!
//! # Algorithm
//! 1. **Frames.** Frame `i` holds the `frame` samples ending `lookahead` samples after
//!    sample `i * hop`: it covers input samples `[i*hop + lookahead - frame, i*hop +
//!    lookahead)`, with zeros before the stream. (This is a [`Framer`] fed `frame/2 -
//!    lookahead` extra leading zeros.) So hop `i` sees exactly `lookahead` samples of the
//!    future, whatever the frame size.
//! 2. **Power spectrum.** Periodic Hann window scaled by `1/sqrt(Σ w²)`, real FFT,
//!    `P[k] = |X[k]|²` (white noise of variance σ² has `E P[k] = σ²`).
//! 3. **Mel bands.** `bands` triangular filters with centres equally spaced on the HTK mel
//!    scale `m(f) = 2595 log10(1 + f/700)` between `f_lo` and `f_hi`; each triangle spans
//!    the centres either side and is normalised to unit sum, so a band's value is the mean
//!    power of its bins (a white-noise level in every band). A triangle narrower than one
//!    FFT bin still gets the bin nearest to its centre.
//! 4. **Log.** `ln(E_b + 1e-20)`: -46 for digital silence (far below anything the
//!    transcriber's relative floor keeps, so a gain change of the input does not change
//!    what silence looks like); a full-scale sine lands near +5 in its band.
//!
//! # Defaults ([`MelConfig::drums`]) at 44.1 kHz
//! | parameter | value |
//! |---|---|
//! | `frame` | 2048 (46.4 ms) |
//! | `hop` | `sr / 100` = 441 (10 ms) |
//! | `lookahead` | `frame / 4` = 512 (11.6 ms) |
//! | `bands` | 48, 20 Hz – 16 kHz (capped at 0.45 sr) |
//!
//! # Latency
//! Hop `i` is emitted once sample `i*hop + lookahead - 1` has arrived:
//! `latency_samples() = lookahead`.
//!
//! # End of stream
//! [`HopStage::finish`] emits the remaining hops (`n.div_ceil(hop)` in all). A frame that
//! reaches past the end of the input would see the zero padding as a sudden drop (a DC
//! offset that lasts to the end would turn into a step): such frames repeat the last frame
//! that lay wholly inside the input instead (or silence, for a stream shorter than one
//! frame's look-ahead).
//!
//! # Cost
//! One real FFT of `frame` points and `frame/2 + 1` squared magnitudes per hop, plus about
//! `2 · frame/2` multiply-adds for the filters. No allocation after [`MelBank::new`].

use crate::framer::{Framer, WindowedFft};
use crate::{ConfigError, HopStage};

/// The floor inside the logarithm.
pub const LOG_FLOOR: f32 = 1e-20;

/// Parameters of [`MelBank`].
#[derive(Clone, Debug, PartialEq)]
pub struct MelConfig {
    /// Sample rate in Hz.
    pub sample_rate: u32,
    /// FFT frame in samples (a power of two is fastest).
    pub frame: usize,
    /// Samples between hops.
    pub hop: usize,
    /// Samples after `i * hop` that frame `i` reaches (`1..=frame / 2`).
    pub lookahead: usize,
    /// Number of mel bands.
    pub bands: usize,
    /// Lowest band edge in Hz.
    pub f_lo: f32,
    /// Highest band edge in Hz (capped at 0.45 × the sample rate).
    pub f_hi: f32,
}

impl MelConfig {
    /// The drum transcriber's front end (see the module docs).
    pub fn drums(sample_rate: u32) -> Self {
        let sr = sample_rate.max(1) as f64;
        // The power of two at or above 40 ms: 2048 at 44.1/48 kHz, 1024 at 22.05 kHz.
        let frame = ((sr * 0.04) as usize).max(16).next_power_of_two();
        MelConfig {
            sample_rate,
            frame,
            hop: ((sr / 100.0) as usize).max(1),
            lookahead: frame / 4,
            bands: 48,
            f_lo: 20.0,
            f_hi: 16_000.0,
        }
    }

    /// The drum front end's short view ([`crate::drums`], input feature set 3): the same
    /// hop, look-ahead, bands and range as [`MelConfig::drums`] on a frame half as long
    /// (1024 points, 23.2 ms at 44.1 kHz), so its frame `i` ends at the same sample and a
    /// hit is sharper in time. Adds no latency.
    pub fn drums_short(sample_rate: u32) -> Self {
        let long = Self::drums(sample_rate);
        MelConfig {
            frame: long.frame / 2,
            ..long
        }
    }

    fn validate(&self) -> Result<(), ConfigError> {
        if self.sample_rate == 0 {
            return Err(ConfigError::invalid("sample_rate", "must be positive"));
        }
        if self.frame < 16 {
            return Err(ConfigError::invalid("frame", "must be at least 16 samples"));
        }
        if self.hop == 0 {
            return Err(ConfigError::invalid("hop", "must be at least 1 sample"));
        }
        if self.lookahead == 0 || self.lookahead > self.frame / 2 {
            return Err(ConfigError::invalid("lookahead", "must be in 1..=frame/2"));
        }
        if self.bands == 0 || self.bands > self.frame / 2 {
            return Err(ConfigError::invalid("bands", "must be in 1..=frame/2"));
        }
        let hi = self.f_hi.min(0.45 * self.sample_rate as f32);
        if !(self.f_lo.is_finite() && self.f_lo >= 0.0 && hi.is_finite() && self.f_lo < hi) {
            return Err(ConfigError::invalid(
                "f_lo/f_hi",
                "need 0 <= f_lo < min(f_hi, 0.45 sr)",
            ));
        }
        Ok(())
    }
}

/// HTK mel scale.
pub(crate) fn hz_to_mel(f: f64) -> f64 {
    2595.0 * (1.0 + f / 700.0).log10()
}

pub(crate) fn mel_to_hz(m: f64) -> f64 {
    700.0 * (10f64.powf(m / 2595.0) - 1.0)
}

/// One triangular filter: weights for bins `start..start + w.len()`.
#[derive(Clone, Debug)]
struct Tri {
    start: usize,
    w: Vec<f32>,
}

/// The filter bank of `cfg` as (first bin, weights) per band; weights sum to 1.
/// Public for the tests' oracle and for the training script's documentation.
pub fn filters(cfg: &MelConfig) -> Vec<(usize, Vec<f32>)> {
    build_filters(cfg)
        .into_iter()
        .map(|t| (t.start, t.w))
        .collect()
}

fn build_filters(cfg: &MelConfig) -> Vec<Tri> {
    let sr = cfg.sample_rate as f64;
    let n = cfg.frame as f64;
    let bins = cfg.frame / 2 + 1;
    let hi = (cfg.f_hi as f64).min(0.45 * sr);
    let (m_lo, m_hi) = (hz_to_mel(cfg.f_lo as f64), hz_to_mel(hi));
    let step = (m_hi - m_lo) / (cfg.bands + 1) as f64;
    let edge = |j: usize| mel_to_hz(m_lo + step * j as f64) * n / sr; // in bins
    (0..cfg.bands)
        .map(|b| {
            let (l, c, r) = (edge(b), edge(b + 1), edge(b + 2));
            let first = (l.floor().max(0.0) as usize).min(bins - 1);
            let last = (r.ceil() as usize).min(bins - 1);
            let mut w: Vec<f64> = (first..=last)
                .map(|k| {
                    let k = k as f64;
                    if k <= l || k >= r {
                        0.0
                    } else if k <= c {
                        (k - l) / (c - l)
                    } else {
                        (r - k) / (r - c)
                    }
                })
                .collect();
            let s: f64 = w.iter().sum();
            if s <= 0.0 {
                // Narrower than a bin: the bin nearest the centre.
                let k = (c.round().max(0.0) as usize).min(bins - 1);
                return Tri {
                    start: k,
                    w: vec![1.0],
                };
            }
            // Trim zeros at both ends.
            let lead = w.iter().take_while(|&&x| x == 0.0).count();
            let trail = w.iter().rev().take_while(|&&x| x == 0.0).count();
            w.truncate(w.len() - trail);
            w.drain(..lead);
            Tri {
                start: first + lead,
                w: w.iter().map(|&x| (x / s) as f32).collect(),
            }
        })
        .collect()
}

/// Streaming log mel-band power. See the module docs.
pub struct MelBank {
    cfg: MelConfig,
    framer: Framer,
    core: Core,
}

struct Core {
    fft: WindowedFft,
    power: Vec<f32>,
    filters: Vec<Tri>,
    /// The last frame computed wholly from real input (held at the end of the stream).
    last_real: Vec<f32>,
    out: Vec<f32>,
}

impl Core {
    fn compute(&mut self, frame: &[f32]) {
        for (p, c) in self.power.iter_mut().zip(self.fft.transform(frame)) {
            *p = (c.re * c.re + c.im * c.im).min(1e30);
        }
        for (o, t) in self.out.iter_mut().zip(&self.filters) {
            let e: f32 =
                t.w.iter()
                    .zip(&self.power[t.start..t.start + t.w.len()])
                    .map(|(w, p)| w * p)
                    .sum();
            *o = (e + LOG_FLOOR).ln();
        }
    }
}

impl MelBank {
    /// Builds the bank; fails on impossible parameters.
    pub fn new(cfg: MelConfig) -> Result<Self, ConfigError> {
        cfg.validate()?;
        let n = cfg.frame;
        let core = Core {
            fft: WindowedFft::new(n),
            power: vec![0.0; n / 2 + 1],
            filters: build_filters(&cfg),
            last_real: vec![LOG_FLOOR.ln(); cfg.bands],
            out: vec![0.0; cfg.bands],
        };
        let framer = Framer::new(n, cfg.hop)?;
        let mut m = MelBank { cfg, framer, core };
        m.reset();
        Ok(m)
    }

    /// The configuration.
    pub fn config(&self) -> &MelConfig {
        &self.cfg
    }

    /// Number of bands (values per hop).
    pub fn bands(&self) -> usize {
        self.cfg.bands
    }

    /// Extra zeros fed before the stream so that the framer's centred frames end
    /// `lookahead` samples after each hop.
    fn pre_pad(&self) -> usize {
        self.cfg.frame / 2 - self.cfg.lookahead
    }

    /// Feeds a block; `emit(i, bands)` for every completed hop.
    pub fn process_bands(&mut self, input: &[f32], emit: &mut dyn FnMut(usize, &[f32])) {
        let core = &mut self.core;
        // Every frame completed while pushing lies wholly inside the input (it ends at
        // sample i*hop + lookahead, which has arrived).
        self.framer.push(input, |i, fr| {
            core.compute(fr);
            core.last_real.copy_from_slice(&core.out);
            emit(i, &core.out);
        });
    }

    /// Ends the stream: emits the remaining hops, holding the last real frame (see the
    /// module docs).
    pub fn finish_bands(&mut self, emit: &mut dyn FnMut(usize, &[f32])) {
        let n = self.framer.samples_seen().saturating_sub(self.pre_pad());
        let total = n.div_ceil(self.cfg.hop);
        let core = &mut self.core;
        let mut next = self.framer.frames_emitted();
        if next < total {
            self.framer.finish(|i, _| {
                if i < total {
                    emit(i, &core.last_real);
                    next = i + 1;
                }
            });
        }
        while next < total {
            emit(next, &core.last_real);
            next += 1;
        }
    }

    /// Hops emitted so far.
    pub fn hops_emitted(&self) -> usize {
        self.framer.frames_emitted()
    }
}

impl HopStage for MelBank {
    /// The first band's value; use [`MelBank::process_bands`] for all of them.
    type Out = f32;

    fn process(&mut self, input: &[f32], emit: &mut dyn FnMut(usize, f32)) {
        self.process_bands(input, &mut |i, b| emit(i, b[0]));
    }

    fn finish(&mut self, emit: &mut dyn FnMut(usize, f32)) {
        self.finish_bands(&mut |i, b| emit(i, b[0]));
    }

    fn reset(&mut self) {
        self.framer.reset();
        let pad = self.pre_pad();
        // The framer already holds frame/2 zeros; add the rest of the pre-padding (fewer
        // than `frame - frame/2` samples in all, so no frame completes here). The framer
        // counts them as input: `finish_bands` subtracts them again.
        let zeros = [0.0f32; 64];
        let mut left = pad;
        while left > 0 {
            let k = left.min(zeros.len());
            self.framer.push(&zeros[..k], |_, _| {});
            left -= k;
        }
        self.core.last_real.fill(LOG_FLOOR.ln());
    }

    fn latency_samples(&self) -> usize {
        self.cfg.lookahead
    }

    fn hop(&self) -> usize {
        self.cfg.hop
    }
}
