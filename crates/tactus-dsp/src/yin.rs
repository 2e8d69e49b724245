//! YIN fundamental-frequency estimation (de Cheveigné & Kawahara, "YIN, a fundamental
//! frequency estimator for speech and music", JASA 111(4), 2002), one estimate per hop.
//!
//! ## Algorithm (per frame of `N = frame` samples)
//! * Integration window `W = N / 2`, lags `τ ∈ [0, τmax + 1]`. The analysed region is
//!   `x = frame[a .. a + W + τmax + 1]`, with the offset `a` chosen so that the region is
//!   centred on the frame centre for the mid-range lag `(τmin + τmax)/2` (as far as it fits).
//!   YIN's window would otherwise sit in the first half of the frame, a quarter frame early
//!   (≈ 10 ms at 2048/44.1 kHz), which biases fast pitch changes. See [`Yin::analysis_window`].
//! * **Difference function** `d(τ) = Σ_{j<W} (x_j − x_{j+τ})²`, computed through the FFT as
//!   `d(τ) = E(0) + E(τ) − 2 r(τ)`, with `E(τ) = Σ_{j=τ}^{τ+W−1} x_j²` (prefix sums, f64) and
//!   the cross-correlation `r(τ) = Σ_{j<W} x_j x_{j+τ}` taken from one size-`N` real FFT of the
//!   frame, one of its first `W` samples (zero-padded) and one inverse FFT. No wrap-around:
//!   `j + τ ≤ N − 1`. Each frame costs O(N log N). Before the FFT the frame's mean is removed
//!   and it is scaled to unit peak: `d` is invariant to a constant offset and the CMND to scale,
//!   so this changes no result but keeps f32 arithmetic exact enough for DC-heavy or very
//!   quiet frames.
//! * **CMND** (cumulative mean normalized difference, step 3 of the paper):
//!   `d'(0) = 1`, `d'(τ) = d(τ) · τ / Σ_{j=1}^{τ} d(j)`.
//! * **Absolute threshold** (step 4): the first lag in `[τmin, τmax]` with `d' < threshold`,
//!   followed downhill to its local minimum; if none dips below, the global minimum of `d'` in
//!   the lag range. `τmin = ⌊sr / fmax⌋`, `τmax = ⌈sr / fmin⌉`.
//! * **Parabolic interpolation** (step 5) of `d` (not `d'`, as the paper advises) around the
//!   chosen lag (offset clamped to ±1 lag); `f0 = sr / τ̂`.
//!
//! ## Voicing (our choice)
//! A frame is **unvoiced** when
//! * it is silent: all zero, or nothing but DC (the mean-removed peak is below 10⁻⁵ of the raw
//!   peak, i.e. −100 dB) — then `aperiodicity = 1`;
//! * or the CMND at the chosen lag is above [`YinConfig::voicing_ceiling`] (default 0.5):
//!   there is no periodic dip at all. White noise has a CMND minimum around 0.8–0.9 over the
//!   lag range (relative spread of `d` is about `√(2/W)`), clean tones below 0.05, and noisy
//!   but clearly pitched tones (SNR ≥ 0 dB) below 0.5.
//!
//! ## Defaults
//! `threshold = 0.1` (docs/design.md), `voicing_ceiling = 0.5`, `hop = round(sr × 10 ms)` (the
//! features-file contract), `frame` = the smallest power of two ≥ `2 (τmax + 1)`: the window
//! `W = N/2` must hold at least one whole longest period (the paper's requirement
//! `W ≥ τmax`), and the lags up to `τmax + 1` (one past for interpolation) must fit in `N − W`.
//! 44.1 kHz, 35 Hz → 4096; 44.1 kHz, 50–70 Hz → 2048.
//!
//! ## Latency
//! That of [`Framer`]: `frame − frame / 2` samples (hop `i` is centred on sample `i·hop`).
//!
//! No allocation after [`Yin::new`]; FFT plans and scratch buffers are owned by the stage.

use std::sync::Arc;

use realfft::num_complex::Complex;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};

use crate::framer::Framer;
use crate::sanitize::sanitize_sample;
use crate::{ConfigError, HopStage};

/// One pitch estimate per hop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PitchEstimate {
    /// Fundamental frequency in Hz; 0 = unvoiced.
    pub f0_hz: f32,
    /// CMND at the chosen lag, clamped to [0, 1]; 1 when the frame is silent.
    pub aperiodicity: f32,
    /// YIN: `1 − aperiodicity` when voiced, else 0. pYIN: the frame's voicing probability.
    pub voiced_prob: f32,
}

impl PitchEstimate {
    /// The estimate for a silent frame.
    pub const SILENT: PitchEstimate = PitchEstimate {
        f0_hz: 0.0,
        aperiodicity: 1.0,
        voiced_prob: 0.0,
    };

    /// Whether a pitch was reported.
    pub fn is_voiced(&self) -> bool {
        self.f0_hz > 0.0
    }
}

/// YIN parameters. Build with [`YinConfig::new`] and adjust fields; [`Yin::new`] validates.
#[derive(Clone, Debug, PartialEq)]
pub struct YinConfig {
    /// Sample rate in Hz.
    pub sample_rate: u32,
    /// Samples per analysis frame `N` (integration window `N / 2`).
    pub frame: usize,
    /// Samples between frame centres.
    pub hop: usize,
    /// Lowest f0 searched, Hz.
    pub fmin_hz: f32,
    /// Highest f0 searched, Hz.
    pub fmax_hz: f32,
    /// CMND absolute threshold (paper step 4), default 0.1.
    pub threshold: f32,
    /// A frame whose CMND at the chosen lag exceeds this is unvoiced (default 0.5).
    pub voicing_ceiling: f32,
}

/// Relative floor under which the FFT difference function counts as exactly 0.
const D_FLOOR: f64 = 1e-6;

/// Largest frame accepted by [`Yin::new`] (2^20 samples), to bound memory.
pub const MAX_FRAME: usize = 1 << 20;

impl YinConfig {
    /// Sensible defaults for a search range: frame = smallest power of two ≥ 2 (⌈sr/fmin⌉ + 1)
    /// (see the module docs), hop = round(sr × 0.010), threshold 0.1, voicing ceiling 0.5.
    /// Never panics; invalid inputs are reported by [`Yin::new`].
    pub fn new(sample_rate: u32, fmin_hz: f32, fmax_hz: f32) -> Self {
        let lag = if fmin_hz.is_finite() && fmin_hz > 0.0 {
            (sample_rate as f64 / fmin_hz as f64)
                .ceil()
                .clamp(1.0, MAX_FRAME as f64) as usize
        } else {
            512
        };
        let frame = (2 * (lag + 1)).next_power_of_two().max(64);
        let hop = ((sample_rate as f64 * 0.010).round() as usize).max(1);
        YinConfig {
            sample_rate,
            frame,
            hop,
            fmin_hz,
            fmax_hz,
            threshold: 0.1,
            voicing_ceiling: 0.5,
        }
    }

    /// Lag range `(τmin, τmax)` in samples, or why the configuration is invalid.
    pub fn lag_range(&self) -> Result<(usize, usize), ConfigError> {
        if self.sample_rate == 0 {
            return Err(ConfigError::invalid("sample_rate", "must be positive"));
        }
        let sr = self.sample_rate as f64;
        if !(self.fmin_hz.is_finite() && self.fmin_hz > 0.0) {
            return Err(ConfigError::invalid("fmin_hz", "must be finite and > 0"));
        }
        if !(self.fmax_hz.is_finite() && self.fmax_hz > self.fmin_hz) {
            return Err(ConfigError::invalid(
                "fmax_hz",
                "must be finite and > fmin_hz",
            ));
        }
        let tau_min = (sr / self.fmax_hz as f64).floor();
        if tau_min < 2.0 {
            return Err(ConfigError::invalid(
                "fmax_hz",
                format!("must be ≤ sample_rate / 2 = {} Hz", sr / 2.0),
            ));
        }
        let tau_max = (sr / self.fmin_hz as f64).ceil();
        if self.frame < 8 || self.frame > MAX_FRAME {
            return Err(ConfigError::invalid(
                "frame",
                format!("must be in [8, {MAX_FRAME}] samples"),
            ));
        }
        let max_lag = self.frame - self.frame / 2;
        if tau_max + 1.0 > max_lag as f64 {
            return Err(ConfigError::invalid(
                "frame",
                format!(
                    "{} samples cannot hold lags up to sr/fmin + 1 = {}; need frame ≥ {}",
                    self.frame,
                    tau_max + 1.0,
                    2.0 * (tau_max + 1.0)
                ),
            ));
        }
        if self.hop == 0 {
            return Err(ConfigError::invalid("hop", "must be at least 1 sample"));
        }
        if !(self.threshold.is_finite() && self.threshold > 0.0 && self.threshold <= 1.0) {
            return Err(ConfigError::invalid("threshold", "must be in (0, 1]"));
        }
        if !(self.voicing_ceiling.is_finite() && self.voicing_ceiling > 0.0) {
            return Err(ConfigError::invalid(
                "voicing_ceiling",
                "must be finite and > 0",
            ));
        }
        Ok((tau_min as usize, tau_max as usize))
    }
}

/// The per-frame YIN machinery shared by [`Yin`] and [`crate::pyin::Pyin`]: CMND of a frame
/// through the FFT, threshold search and interpolation. Allocation-free after construction.
pub(crate) struct YinCore {
    pub(crate) sample_rate: f32,
    frame: usize,
    win: usize,
    pub(crate) tau_min: usize,
    pub(crate) tau_max: usize,
    threshold: f32,
    voicing_ceiling: f32,
    fwd: Arc<dyn RealToComplex<f32>>,
    inv: Arc<dyn ComplexToReal<f32>>,
    buf_a: Vec<f32>,
    buf_b: Vec<f32>,
    spec_a: Vec<Complex<f32>>,
    spec_b: Vec<Complex<f32>>,
    scratch: Vec<Complex<f32>>,
    corr: Vec<f32>,
    prefix: Vec<f64>,
    /// First frame sample of the analysed region.
    pub(crate) offset: usize,
    /// Length of the analysed region, `W + τmax + 1`.
    pub(crate) region: usize,
    /// `cmnd[τ]` for τ in `0..=tau_max + 1`.
    pub(crate) cmnd: Vec<f32>,
    /// The difference function `d(τ)` of the normalized region, same range.
    diff: Vec<f32>,
}

impl std::fmt::Debug for YinCore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("YinCore")
            .field("frame", &self.frame)
            .field("tau_min", &self.tau_min)
            .field("tau_max", &self.tau_max)
            .finish_non_exhaustive()
    }
}

impl YinCore {
    pub(crate) fn new(cfg: &YinConfig) -> Result<Self, ConfigError> {
        let (tau_min, tau_max) = cfg.lag_range()?;
        let n = cfg.frame;
        let mut planner = RealFftPlanner::<f32>::new();
        let fwd = planner.plan_fft_forward(n);
        let inv = planner.plan_fft_inverse(n);
        // Centre the analysed region on the frame centre for the mid-range lag, as far as
        // the region `[offset, offset + W + τmax + 1)` still fits in the frame.
        let max_offset = n - n / 2 - tau_max - 1;
        let offset = (n / 4)
            .saturating_sub((tau_min + tau_max) / 4)
            .min(max_offset);
        let scratch_len = fwd.get_scratch_len().max(inv.get_scratch_len());
        Ok(YinCore {
            sample_rate: cfg.sample_rate as f32,
            frame: n,
            win: n / 2,
            tau_min,
            tau_max,
            threshold: cfg.threshold,
            voicing_ceiling: cfg.voicing_ceiling,
            buf_a: fwd.make_input_vec(),
            buf_b: fwd.make_input_vec(),
            spec_a: fwd.make_output_vec(),
            spec_b: fwd.make_output_vec(),
            scratch: vec![Complex::new(0.0, 0.0); scratch_len],
            corr: inv.make_output_vec(),
            prefix: vec![0.0; n + 1],
            offset,
            region: n / 2 + tau_max + 1,
            cmnd: vec![1.0; tau_max + 2],
            diff: vec![0.0; tau_max + 2],
            fwd,
            inv,
        })
    }

    /// Fills `self.cmnd[..=tau_max + 1]` from the analysed region of `frame` (zero-padded if
    /// `frame` is short; non-finite samples count as 0). Returns `false` for a silent frame (all zero
    /// or pure DC), in which case `cmnd` is all 1.
    pub(crate) fn analyse(&mut self, frame: &[f32]) -> bool {
        let n = self.frame;
        let w = self.win;
        let start = self.offset.min(frame.len());
        let region = &frame[start..frame.len().min(self.offset + self.region)];
        let len = region.len();
        // Any constant may be removed (d is offset-invariant), so an f32 mean is enough.
        let mut sum = [0.0f32; 8];
        let mut peak = [0.0f32; 8];
        for (k, (dst, &x)) in self.buf_b[..len].iter_mut().zip(region).enumerate() {
            let y = sanitize_sample(x).0;
            *dst = y;
            sum[k % 8] += y;
            peak[k % 8] = peak[k % 8].max(y.abs());
        }
        let peak = peak.iter().fold(0.0f32, |a, &b| a.max(b));
        self.buf_b[len..].fill(0.0);
        let mean = sum.iter().sum::<f32>() / self.region as f32;
        let mut lanes = [0.0f32; 8];
        for (k, x) in self.buf_b[..self.region].iter_mut().enumerate() {
            *x -= mean;
            lanes[k % 8] = lanes[k % 8].max(x.abs());
        }
        let peak_res = lanes.iter().fold(0.0f32, |a, &b| a.max(b));
        if peak == 0.0 || peak_res <= 1e-5 * peak {
            self.cmnd.fill(1.0);
            self.diff.fill(0.0);
            return false;
        }
        let scale = 1.0 / peak_res;
        let mut acc = 0.0f64;
        self.prefix[0] = 0.0;
        for (j, x) in self.buf_b[..self.region].iter_mut().enumerate() {
            *x *= scale;
            acc += (*x as f64) * (*x as f64);
            self.prefix[j + 1] = acc;
        }
        self.buf_a[..w].copy_from_slice(&self.buf_b[..w]);
        self.buf_a[w..].fill(0.0);
        // Lengths are fixed at construction, so these transforms cannot fail.
        self.fwd
            .process_with_scratch(&mut self.buf_a, &mut self.spec_a, &mut self.scratch)
            .expect("YIN forward FFT: buffer lengths fixed at construction");
        self.fwd
            .process_with_scratch(&mut self.buf_b, &mut self.spec_b, &mut self.scratch)
            .expect("YIN forward FFT: buffer lengths fixed at construction");
        for (b, a) in self.spec_b.iter_mut().zip(&self.spec_a) {
            *b *= a.conj();
        }
        // DC and Nyquist bins of a product of real spectra are real; make it exact.
        self.spec_b[0].im = 0.0;
        if n.is_multiple_of(2) {
            if let Some(last) = self.spec_b.last_mut() {
                last.im = 0.0;
            }
        }
        self.inv
            .process_with_scratch(&mut self.spec_b, &mut self.corr, &mut self.scratch)
            .expect("YIN inverse FFT: buffer lengths fixed at construction");
        let norm = 1.0 / n as f64;
        let e0 = self.prefix[w];
        let hi = self.tau_max + 1;
        // Three passes so that only the running sum is serial: d (vectorizable), the
        // cumulative sum of d (serial, stored over `prefix`, no longer needed), then the CMND.
        self.diff[0] = 0.0;
        for tau in 1..=hi {
            let e_tau = self.prefix[tau + w] - self.prefix[tau];
            // Below 1e-6 of the energies, d is f32 FFT rounding noise (~1e-7 relative):
            // call it 0, so that numerically constant stretches do not fake a dip.
            let d = e0 + e_tau - 2.0 * self.corr[tau] as f64 * norm;
            self.diff[tau] = if d > D_FLOOR * (e0 + e_tau) {
                d as f32
            } else {
                0.0
            };
        }
        let mut cum = 0.0f64;
        for tau in 1..=hi {
            cum += self.diff[tau] as f64;
            self.prefix[tau] = cum;
        }
        self.cmnd[0] = 1.0;
        for tau in 1..=hi {
            let cum = self.prefix[tau];
            self.cmnd[tau] = if cum > 0.0 {
                (self.diff[tau] as f64 * tau as f64 / cum) as f32
            } else {
                1.0
            };
        }
        true
    }

    /// The lag chosen by the absolute-threshold rule (paper step 4) on the current CMND.
    pub(crate) fn pick_lag(&self, threshold: f32) -> usize {
        let c = &self.cmnd;
        let mut tau = self.tau_min;
        while tau <= self.tau_max {
            if c[tau] < threshold {
                while tau < self.tau_max && c[tau + 1] < c[tau] {
                    tau += 1;
                }
                return tau;
            }
            tau += 1;
        }
        self.global_min_lag()
    }

    /// [`YinCore::pick_lag`] judged on the interpolated CMND: the first local minimum below
    /// twice `threshold` whose vertex ([`YinCore::vertex_cmnd`]) is below `threshold`. A short period of a
    /// fractional number of samples whose integer lags miss the threshold is then not
    /// passed over for twice its length.
    pub(crate) fn pick_lag_vertex(&self, threshold: f32) -> usize {
        let c = &self.cmnd;
        for tau in self.tau_min..=self.tau_max {
            // The integer lag must be near the threshold already (within twice it): a jagged
            // CMND's parabola can dip far below its points.
            let local_min = c[tau] <= c[tau - 1] && c[tau] <= c[tau + 1];
            if local_min && c[tau] < 2.0 * threshold && self.vertex_cmnd(tau) < threshold {
                return tau;
            }
        }
        self.global_min_lag()
    }

    /// The lag of the smallest CMND in `[tau_min, tau_max]` (the first one on ties).
    pub(crate) fn global_min_lag(&self) -> usize {
        let mut best = self.tau_min;
        for tau in self.tau_min..=self.tau_max {
            if self.cmnd[tau] < self.cmnd[best] {
                best = tau;
            }
        }
        best
    }

    /// Parabolic interpolation around integer lag `tau` (paper step 5): the fractional lag of
    /// the vertex of the parabola through `d(τ−1), d(τ), d(τ+1)`, offset clamped to ±1. As the
    /// paper recommends, the raw difference function is used, not the CMND, whose `τ` factor
    /// biases the vertex (by ~7 cents for an 11-sample period).
    pub(crate) fn refine_lag(&self, tau: usize) -> f32 {
        let (a, b, c) = (self.diff[tau - 1], self.diff[tau], self.diff[tau + 1]);
        let den = a - 2.0 * b + c;
        let shift = if den > 0.0 {
            (0.5 * (a - c) / den).clamp(-1.0, 1.0)
        } else {
            0.0
        };
        tau as f32 + shift
    }

    /// Full YIN estimate of one frame.
    pub(crate) fn estimate(&mut self, frame: &[f32]) -> PitchEstimate {
        self.estimate_with(frame, false)
    }

    /// The CMND's minimum between lags by parabolic interpolation around `tau` (at least 0,
    /// at most `d'(τ)`).
    fn vertex_cmnd(&self, tau: usize) -> f32 {
        let (a, b, c) = (self.cmnd[tau - 1], self.cmnd[tau], self.cmnd[tau + 1]);
        let den = a - 2.0 * b + c;
        if den > 0.0 {
            (b - (a - c) * (a - c) / (8.0 * den)).clamp(0.0, b)
        } else {
            b
        }
    }

    /// [`YinCore::estimate`], with the aperiodicity at the interpolated lag if `vertex`.
    pub(crate) fn estimate_with(&mut self, frame: &[f32], vertex: bool) -> PitchEstimate {
        if !self.analyse(frame) {
            return PitchEstimate::SILENT;
        }
        let tau = if vertex {
            self.pick_lag_vertex(self.threshold)
        } else {
            self.pick_lag(self.threshold)
        };
        let ap = if vertex && self.cmnd[tau] < 2.0 * self.threshold {
            self.vertex_cmnd(tau)
        } else {
            self.cmnd[tau]
        }
        .clamp(0.0, 1.0);
        if ap > self.voicing_ceiling {
            return PitchEstimate {
                f0_hz: 0.0,
                aperiodicity: ap,
                voiced_prob: 0.0,
            };
        }
        let f0 = self.sample_rate / self.refine_lag(tau);
        if !(f0.is_finite() && f0 > 0.0) {
            return PitchEstimate {
                f0_hz: 0.0,
                aperiodicity: ap,
                voiced_prob: 0.0,
            };
        }
        PitchEstimate {
            f0_hz: f0,
            aperiodicity: ap,
            voiced_prob: 1.0 - ap,
        }
    }
}

/// Streaming YIN: one [`PitchEstimate`] per hop. See the module docs.
#[derive(Debug)]
pub struct Yin {
    cfg: YinConfig,
    framer: Framer,
    core: YinCore,
    /// Report the aperiodicity at the interpolated lag ([`Yin::with_vertex_aperiodicity`]).
    vertex: bool,
}

impl Yin {
    /// Validates `cfg` and allocates every buffer the stage will ever need.
    pub fn new(cfg: YinConfig) -> Result<Yin, ConfigError> {
        let core = YinCore::new(&cfg)?;
        let framer = Framer::new(cfg.frame, cfg.hop)?;
        Ok(Yin {
            cfg,
            framer,
            core,
            vertex: false,
        })
    }

    /// Judges the CMND at the interpolated lag (the vertex of the parabola through
    /// `d'(τ−1), d'(τ), d'(τ+1)`, at least 0) instead of at the integer lag, both for the
    /// absolute threshold (the first local minimum whose vertex is below it) and for the
    /// reported aperiodicity: a period of a fractional number of samples then reads closer
    /// to as periodic as it is (a 2 kHz saw at 14.7 kHz, 7.35 samples a period: 0.07 at
    /// lag 7, and judged at integer lags YIN took twice the period). The vertex is an
    /// estimate: where the minimum falls midway between two lags it stays above the true
    /// one (about 0.05 for the first two harmonics of a 1970 Hz saw at 14.7 kHz). For
    /// judging whether a signal is a plain tone ([`crate::plain`]).
    pub fn with_vertex_aperiodicity(mut self) -> Self {
        self.vertex = true;
        self
    }

    /// The configuration in use.
    pub fn config(&self) -> &YinConfig {
        &self.cfg
    }

    /// The analysed part of each frame: `(start, window)`. The difference function uses
    /// frame samples `[start, start + window + τmax + 1)` with integration window `window`
    /// (= frame / 2). `start` centres the region on the frame centre for the mid-range lag.
    pub fn analysis_window(&self) -> (usize, usize) {
        (self.core.offset, self.core.win)
    }

    /// Lag range `(τmin, τmax)` in samples.
    pub fn lag_range(&self) -> (usize, usize) {
        (self.core.tau_min, self.core.tau_max)
    }

    /// The CMND `d'(τ)` for `τ = 0 ..= τmax + 1` of the last frame analysed (all 1 if silent).
    pub fn cmnd(&self) -> &[f32] {
        &self.core.cmnd
    }

    /// YIN on one frame (its first `frame` samples, zero-padded if shorter; non-finite samples
    /// count as 0). Allocation-free; does not touch the streaming state.
    pub fn estimate_frame(&mut self, frame: &[f32]) -> PitchEstimate {
        self.core.estimate(frame)
    }
}

impl HopStage for Yin {
    type Out = PitchEstimate;

    fn process(&mut self, input: &[f32], emit: &mut dyn FnMut(usize, PitchEstimate)) {
        let (core, vertex) = (&mut self.core, self.vertex);
        self.framer
            .push(input, |i, fr| emit(i, core.estimate_with(fr, vertex)));
    }

    fn finish(&mut self, emit: &mut dyn FnMut(usize, PitchEstimate)) {
        let (core, vertex) = (&mut self.core, self.vertex);
        self.framer
            .finish(|i, fr| emit(i, core.estimate_with(fr, vertex)));
    }

    fn reset(&mut self) {
        self.framer.reset();
    }

    fn latency_samples(&self) -> usize {
        self.framer.latency_samples()
    }

    fn hop(&self) -> usize {
        self.cfg.hop
    }
}
