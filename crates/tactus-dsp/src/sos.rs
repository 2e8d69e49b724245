//! Butterworth low-pass, high-pass and band-pass filters as cascaded second-order sections.
//!
//! ## Algorithm
//! The design follows the textbook route (e.g. Oppenheim & Schafer, *Discrete-Time Signal
//! Processing*, §7.1; the same route as scipy's `butter(..., output='sos')`), but it never forms
//! the high-order `b/a` polynomials, which lose all precision for low cutoffs at high rates:
//!
//! 1. **Analog prototype.** The `N` poles of the order-`N` Butterworth low-pass with cutoff
//!    1 rad/s sit on the left half of the unit circle, `p_k = exp(jπ(2k + N + 1) / 2N)`.
//! 2. **Prewarping.** Every edge `f` becomes `Ω = tan(π f / fs)`, so that the bilinear
//!    transform below puts the −3 dB points exactly on the requested frequencies.
//! 3. **Frequency transform** (in the prewarped analog domain):
//!    low-pass `s → s / Ω_c`; high-pass `s → Ω_c / s`; band-pass
//!    `s → (s² + Ω_0²) / (s B)` with `Ω_0² = Ω_lo Ω_hi` and `B = Ω_hi − Ω_lo`.
//! 4. **Bilinear transform** `s = (1 − z⁻¹) / (1 + z⁻¹)`, pole by pole: `z = (1 + s) / (1 − s)`.
//!    Poles are grouped in conjugate pairs, one pair per section, with closed-form section
//!    denominators `a1 = −2 (1 − |s|²) / |1 − s|²`, `a2 = |1 + s|² / |1 − s|²` (exact in f64 even
//!    when `s` is tiny, i.e. for 30 Hz at 192 kHz).
//! 5. **Zeros**: low-pass puts all zeros at `z = −1`, high-pass at `z = +1`, band-pass one at each
//!    per section. Each section is scaled to unit gain at its reference frequency (DC for
//!    low-pass, Nyquist for high-pass, the band centre `2 atan(Ω_0)` for band-pass), which makes
//!    the cascade's pass-band gain 1 and keeps every section's level near the signal's.
//!
//! **Order convention.** For low-pass and high-pass, `order` is the number of poles
//! (`order.div_ceil(2)` sections; an odd order ends with a first-order section stored with
//! `b[2] = a[2] = 0`). For band-pass, `order` is the order of the low-pass *prototype*, as in
//! scipy's `butter(N, [lo, hi], 'bandpass')`: the filter has `2 N` poles and `N` sections, and
//! each skirt falls like an order-`N` low/high-pass (`6 N` dB per octave far from the band).
//!
//! **Processing.** Transposed direct form II per section, with `f64` coefficients and `f64`
//! state; `f32` in and out. Non-finite input samples are replaced by 0 and counted
//! ([`SosFilter::non_finite_count`]); inputs below [`FLUSH_BELOW`] are treated as 0 (see
//! [`crate::sanitize`]). A section whose two state values are both below `1e-60` in
//! magnitude is reset to 0, so a decaying tail never reaches f64 denormals (they would first affect the output around 1e-58,
//! far below what an `f32` output can carry past the output flush at [`FLUSH_BELOW`]).
//!
//! ## The paper's drum bands, and clamping
//! [`SosFilter::band`] builds the paper's kick 30–150, snare 150–800, toms 800–5000 and cymbals
//! 5000–12000 Hz bands as order-4 band-passes (8 poles each; docs/design.md). An edge is *usable*
//! when it is below [`MAX_EDGE_FRACTION`] × Nyquist (0.9 × Nyquist). The rule:
//!
//! * both edges usable → band-pass `[lo, hi]`;
//! * only the lower edge usable → order-4 high-pass at `lo` (the upper edge is dropped: a
//!   Butterworth edge squeezed against Nyquist removes almost no band, its sections' zeros and
//!   poles crowd at `z = −1`, and the bilinear warping compresses its skirt into a few hundred
//!   Hz; a high-pass at `lo` keeps the same lower skirt and passes what little lies above);
//! * lower edge unusable → the band is unavailable: [`band_edges`] returns `None` and
//!   [`SosFilter::band`] returns a [`ConfigError`]; the engine skips that band.
//!
//! So at 44.1 kHz and above every band is a true band-pass (12 kHz < 0.9 × 22.05 kHz = 19.8
//! kHz). At 22.05 and 24 kHz the cymbals band becomes a 5 kHz high-pass; at 16 kHz cymbals are
//! a 5 kHz high-pass and toms stay a band-pass (5 kHz < 7.2 kHz); at 8 kHz toms become an 800 Hz
//! high-pass and cymbals are unavailable.
//!
//! ## Defaults and latency
//! Drum bands: order 4. Denoising high-pass ([`SosFilter::highpass`]): order 4, 30 Hz for bass
//! and drums, 60 Hz for vocals and other (docs/design.md). [`SampleStage::latency_samples`] is 0 by
//! convention for IIR filters (their group delay depends on frequency).

use realfft::num_complex::Complex64;

use crate::sanitize::{sanitize_sample, FLUSH_BELOW};
use crate::{Band, ConfigError, SampleStage};

/// Band edges at or above this fraction of Nyquist are not used (see the module docs).
pub const MAX_EDGE_FRACTION: f64 = 0.9;

/// Drum band filter order (prototype order; 8 poles for a band-pass). docs/design.md.
pub const BAND_ORDER: usize = 4;

/// Denoising high-pass order. docs/design.md.
pub const DENOISE_ORDER: usize = 4;

/// Highest order accepted by [`butterworth`]; far beyond any use, it bounds the work done
/// on user input.
pub const MAX_ORDER: usize = 64;

/// State magnitudes below this are flushed to 0 (keeps f64 state out of denormals).
const STATE_FLUSH: f64 = 1e-60;

/// One second-order section `H(z) = (b0 + b1 z⁻¹ + b2 z⁻²) / (1 + a1 z⁻¹ + a2 z⁻²)`.
/// `a[0]` is always 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sos {
    /// Numerator coefficients `b0, b1, b2`.
    pub b: [f64; 3],
    /// Denominator coefficients `1, a1, a2`.
    pub a: [f64; 3],
}

impl Sos {
    /// This section's complex response at `z = e^{jω}`, `ω` in radians per sample.
    ///
    /// Both polynomials are expanded around the nearer of `z⁻¹ = ±1`, with `z⁻¹ ∓ 1`
    /// computed from `sin(ω/2)` or `cos(ω/2)`: the Butterworth zeros sit exactly at `z = ±1`,
    /// and the naive evaluation would lose all precision in the stop band next to them.
    pub fn response(&self, omega: f64) -> Complex64 {
        let half = Complex64::from_polar(1.0, -omega / 2.0);
        let eval = |c: &[f64; 3]| {
            if omega.cos() >= 0.0 {
                // z⁻¹ = 1 + e, e = e^{-jω} − 1 = −2j sin(ω/2) e^{-jω/2}.
                let e = half * Complex64::new(0.0, -2.0 * (omega / 2.0).sin());
                (c[0] + c[1] + c[2]) + e * (c[1] + 2.0 * c[2]) + e * e * c[2]
            } else {
                // z⁻¹ = −1 + e, e = e^{-jω} + 1 = 2 cos(ω/2) e^{-jω/2}.
                let e = half * (2.0 * (omega / 2.0).cos());
                (c[0] - c[1] + c[2]) + e * (c[1] - 2.0 * c[2]) + e * e * c[2]
            }
        };
        eval(&self.b) / eval(&self.a)
    }

    /// The section's poles (roots of `z² + a1 z + a2`); for a first-order section the second
    /// pole is 0.
    pub fn poles(&self) -> [Complex64; 2] {
        let (a1, a2) = (self.a[1], self.a[2]);
        let disc = Complex64::new(a1 * a1 - 4.0 * a2, 0.0).sqrt();
        [(-a1 + disc) / 2.0, (-a1 - disc) / 2.0]
    }
}

/// What a Butterworth design passes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Response {
    /// Passes below `cutoff_hz` (−3 dB there).
    LowPass {
        /// −3 dB frequency in Hz.
        cutoff_hz: f64,
    },
    /// Passes above `cutoff_hz` (−3 dB there).
    HighPass {
        /// −3 dB frequency in Hz.
        cutoff_hz: f64,
    },
    /// Passes between the two edges (−3 dB at both).
    BandPass {
        /// Lower −3 dB frequency in Hz.
        low_hz: f64,
        /// Upper −3 dB frequency in Hz.
        high_hz: f64,
    },
}

fn check_edge(name: &'static str, f: f64, nyquist: f64) -> Result<f64, ConfigError> {
    if !(f.is_finite() && f > 0.0 && f < nyquist) {
        return Err(ConfigError::invalid(
            name,
            format!("{f} Hz is not inside (0, {nyquist}) Hz, the open range up to Nyquist"),
        ));
    }
    Ok(f)
}

/// Designs an order-`order` Butterworth filter as second-order sections.
///
/// See the module docs for the order convention (band-pass: `2 * order` poles, `order`
/// sections). Errors when `order` is 0 or above [`MAX_ORDER`], `sample_rate` is 0, an edge
/// is not strictly between 0 and Nyquist, or `low_hz >= high_hz`.
pub fn butterworth(
    order: usize,
    response: Response,
    sample_rate: u32,
) -> Result<Vec<Sos>, ConfigError> {
    if order == 0 || order > MAX_ORDER {
        return Err(ConfigError::invalid(
            "order",
            format!("{order} is not in 1..={MAX_ORDER}"),
        ));
    }
    if sample_rate == 0 {
        return Err(ConfigError::invalid("sample_rate", "must be positive"));
    }
    let fs = f64::from(sample_rate);
    let nyquist = fs / 2.0;
    let warp = |f: f64| (std::f64::consts::PI * f / fs).tan();
    // Analog prototype poles in the upper half plane (and the real pole for odd orders).
    // Pole k of N: angle π(2k + N + 1) / 2N; k < N/2 gives Im > 0.
    let proto_upper = |n: usize| {
        (0..n / 2).map(move |k| {
            let theta = std::f64::consts::PI * (2 * k + n + 1) as f64 / (2 * n) as f64;
            Complex64::from_polar(1.0, theta)
        })
    };
    let odd = order % 2 == 1;
    let mut sections = Vec::with_capacity(order);
    match response {
        Response::LowPass { cutoff_hz } | Response::HighPass { cutoff_hz } => {
            let wc = warp(check_edge("cutoff_hz", cutoff_hz, nyquist)?);
            let low = matches!(response, Response::LowPass { .. });
            // Low-pass: s = wc p. High-pass: s = wc / p = wc conj(p) (|p| = 1).
            let map = |p: Complex64| if low { p * wc } else { p.conj() * wc };
            let (zero, reference) = if low {
                (-1.0, 0.0)
            } else {
                (1.0, std::f64::consts::PI)
            };
            for p in proto_upper(order) {
                sections.push(pair_section(map(p), [zero, zero], reference));
            }
            if odd {
                sections.push(real_section(
                    map(Complex64::new(-1.0, 0.0)).re,
                    zero,
                    reference,
                ));
            }
        }
        Response::BandPass { low_hz, high_hz } => {
            let lo = check_edge("low_hz", low_hz, nyquist)?;
            let hi = check_edge("high_hz", high_hz, nyquist)?;
            if lo >= hi {
                return Err(ConfigError::invalid(
                    "low_hz",
                    format!("lower edge {lo} Hz must be below the upper edge {hi} Hz"),
                ));
            }
            let (wlo, whi) = (warp(lo), warp(hi));
            let w0sq = wlo * whi;
            let bw = whi - wlo;
            let centre = 2.0 * w0sq.sqrt().atan();
            // Each prototype pole p gives the roots of s² − p B s + Ω0² = 0.
            let split = |p: Complex64| {
                let half = p * bw / 2.0;
                let d = (half * half - w0sq).sqrt();
                (half + d, half - d)
            };
            for p in proto_upper(order) {
                let (s1, s2) = split(p);
                sections.push(pair_section(s1, [1.0, -1.0], centre));
                sections.push(pair_section(s2, [1.0, -1.0], centre));
            }
            if odd {
                // The real prototype pole: s² + B s + Ω0² = 0, two real or one conjugate pair.
                let (s1, s2) = split(Complex64::new(-1.0, 0.0));
                let (z1, z2) = (bilinear(s1), bilinear(s2));
                let a = if s1.im.abs() > 0.0 {
                    pair_denominator(s1)
                } else {
                    [1.0, -(z1.re + z2.re), z1.re * z2.re]
                };
                sections.push(scaled(a, [1.0, 0.0, -1.0], centre));
            }
        }
    }
    // Sections in order of increasing pole radius (least resonant first, as scipy's zpk2sos
    // orders them): the sharpest resonance comes last, where its peak meets a signal that the
    // earlier sections have already band-limited.
    sections.sort_by(|x, y| {
        let r = |s: &Sos| s.a[2].abs();
        r(x).total_cmp(&r(y))
    });
    Ok(sections)
}

/// z = (1 + s) / (1 − s).
fn bilinear(s: Complex64) -> Complex64 {
    (1.0 + s) / (1.0 - s)
}

/// Denominator `[1, a1, a2]` of the digital pole pair from analog pole `s` and its conjugate,
/// in the closed form that stays exact for tiny `s`.
fn pair_denominator(s: Complex64) -> [f64; 3] {
    let m = (1.0 - s).norm_sqr();
    [
        1.0,
        -2.0 * (1.0 - s.norm_sqr()) / m,
        (1.0 + s).norm_sqr() / m,
    ]
}

/// A section with the pole pair from `s` and zeros at `z = zeros[0], zeros[1]` (real),
/// scaled to unit magnitude at `omega_ref`.
fn pair_section(s: Complex64, zeros: [f64; 2], omega_ref: f64) -> Sos {
    let b = [1.0, -(zeros[0] + zeros[1]), zeros[0] * zeros[1]];
    scaled(pair_denominator(s), b, omega_ref)
}

/// A first-order section with the real analog pole `s` and one zero at `z = zero`.
fn real_section(s: f64, zero: f64, omega_ref: f64) -> Sos {
    let a = [1.0, -(1.0 + s) / (1.0 - s), 0.0];
    scaled(a, [1.0, -zero, 0.0], omega_ref)
}

fn scaled(a: [f64; 3], b: [f64; 3], omega_ref: f64) -> Sos {
    let unit = Sos { b, a };
    let g = 1.0 / unit.response(omega_ref).norm();
    Sos {
        b: [b[0] * g, b[1] * g, b[2] * g],
        a,
    }
}

/// The drum band's clamped edges at `sample_rate` (see the module docs).
///
/// `Some((lo, hi))` with `hi < 0.9 × Nyquist`: a band-pass. `Some((lo, nyquist))` with
/// `hi == sample_rate / 2`: the upper edge was dropped and the band is a high-pass at `lo`.
/// `None`: the lower edge is at or above 0.9 × Nyquist (or `sample_rate` is 0); the band is
/// unavailable at this rate.
pub fn band_edges(band: Band, sample_rate: u32) -> Option<(f64, f64)> {
    let nyquist = f64::from(sample_rate) / 2.0;
    let limit = MAX_EDGE_FRACTION * nyquist;
    let (lo, hi) = band.edges_hz();
    if lo >= limit {
        None
    } else if hi < limit {
        Some((lo, hi))
    } else {
        Some((lo, nyquist))
    }
}

/// The [`Response`] that [`SosFilter::band`] designs for `band` at `sample_rate`, or `None`
/// when the band is unavailable (see [`band_edges`]).
pub fn band_response(band: Band, sample_rate: u32) -> Option<Response> {
    let (lo, hi) = band_edges(band, sample_rate)?;
    if hi >= f64::from(sample_rate) / 2.0 {
        Some(Response::HighPass { cutoff_hz: lo })
    } else {
        Some(Response::BandPass {
            low_hz: lo,
            high_hz: hi,
        })
    }
}

/// A cascade of second-order sections, transposed direct form II, f64 state.
#[derive(Clone, Debug)]
pub struct SosFilter {
    sections: Vec<Sos>,
    /// Per section `[s1, s2]`.
    state: Vec<[f64; 2]>,
    non_finite: u64,
}

impl SosFilter {
    /// A filter running `sections` in order. An empty list is the identity (apart from the
    /// input sanitizing).
    pub fn new(sections: Vec<Sos>) -> Self {
        let state = vec![[0.0; 2]; sections.len()];
        SosFilter {
            sections,
            state,
            non_finite: 0,
        }
    }

    /// Designs a Butterworth filter (see [`butterworth`]).
    pub fn butterworth(
        order: usize,
        response: Response,
        sample_rate: u32,
    ) -> Result<Self, ConfigError> {
        butterworth(order, response, sample_rate).map(Self::new)
    }

    /// The sections, in processing order.
    pub fn sections(&self) -> &[Sos] {
        &self.sections
    }

    /// The f64 state, `[s1, s2]` per section (for inspection and tests).
    pub fn state(&self) -> &[[f64; 2]] {
        &self.state
    }

    /// Input samples that were NaN or infinite (processed as 0) since construction or reset.
    pub fn non_finite_count(&self) -> u64 {
        self.non_finite
    }

    /// The paper's drum `band` filter: an order-4 Butterworth band-pass (8 poles), or an
    /// order-4 high-pass at the lower edge when the upper edge is too close to Nyquist.
    /// Errors when the band is unavailable at `sample_rate` (its lower edge is at or above
    /// 0.9 × Nyquist); see the module docs and [`band_edges`].
    pub fn band(band: Band, sample_rate: u32) -> Result<Self, ConfigError> {
        let response = band_response(band, sample_rate).ok_or_else(|| {
            ConfigError::invalid(
                "band",
                format!(
                    "the {} band ({:?} Hz) lies above {MAX_EDGE_FRACTION} x Nyquist at {sample_rate} Hz",
                    band.name(),
                    band.edges_hz()
                ),
            )
        })?;
        Self::butterworth(BAND_ORDER, response, sample_rate)
    }

    /// Denoising high-pass: Butterworth, `order` poles, −3 dB at `cutoff_hz`.
    /// docs/design.md defaults: order 4, 30 Hz for bass and drums, 60 Hz for vocals and other.
    pub fn highpass(cutoff_hz: f64, order: usize, sample_rate: u32) -> Result<Self, ConfigError> {
        Self::butterworth(order, Response::HighPass { cutoff_hz }, sample_rate)
    }

    /// The analytic complex response at `freq_hz`: `(magnitude, phase in radians)`.
    pub fn response_at(&self, freq_hz: f64, sample_rate: u32) -> (f64, f64) {
        let omega = 2.0 * std::f64::consts::PI * freq_hz / f64::from(sample_rate);
        let h = self
            .sections
            .iter()
            .fold(Complex64::new(1.0, 0.0), |acc, s| acc * s.response(omega));
        (h.norm(), h.arg())
    }

    /// Filters `block` in place. Dispatches on the section count so that, for the usual
    /// 1–6 sections, coefficients and state live in registers for the whole block; every
    /// path performs the same arithmetic in the same order, so results are bit-identical.
    fn filter_block(&mut self, block: &mut [f32]) {
        match self.sections.len() {
            1 => self.filter_fixed::<1>(block),
            2 => self.filter_fixed::<2>(block),
            3 => self.filter_fixed::<3>(block),
            4 => self.filter_fixed::<4>(block),
            5 => self.filter_fixed::<5>(block),
            6 => self.filter_fixed::<6>(block),
            _ => {
                let mut bad = 0;
                for x in block.iter_mut() {
                    let mut v = input_sample(*x, &mut bad);
                    for (s, st) in self.sections.iter().zip(self.state.iter_mut()) {
                        v = step(s, st, v);
                    }
                    *x = output_sample(v);
                }
                self.non_finite += bad;
            }
        }
    }

    fn filter_fixed<const N: usize>(&mut self, block: &mut [f32]) {
        let mut secs = [Sos {
            b: [0.0; 3],
            a: [1.0, 0.0, 0.0],
        }; N];
        secs.copy_from_slice(&self.sections);
        let mut state = [[0.0; 2]; N];
        state.copy_from_slice(&self.state);
        let mut bad = 0;
        for x in block.iter_mut() {
            let mut v = input_sample(*x, &mut bad);
            for (s, st) in secs.iter().zip(state.iter_mut()) {
                v = step(s, st, v);
            }
            *x = output_sample(v);
        }
        self.state.copy_from_slice(&state);
        self.non_finite += bad;
    }
}

/// Sanitized input sample as f64; counts non-finite samples in `bad`.
#[inline(always)]
fn input_sample(x: f32, bad: &mut u64) -> f64 {
    let (x, was_bad) = sanitize_sample(x);
    *bad += u64::from(was_bad);
    f64::from(x)
}

/// f64 result to f32 output, flushing what is below [`FLUSH_BELOW`].
#[inline(always)]
fn output_sample(v: f64) -> f32 {
    let y = v as f32;
    if y.abs() < FLUSH_BELOW {
        0.0
    } else {
        y
    }
}

/// One transposed-direct-form-II step of section `s` with state `st`.
#[inline(always)]
fn step(s: &Sos, st: &mut [f64; 2], v: f64) -> f64 {
    let y = s.b[0] * v + st[0];
    let mut s1 = s.b[1] * v - s.a[1] * y + st[1];
    let mut s2 = s.b[2] * v - s.a[2] * y;
    // Flush the section's state only as a whole: zeroing one component alone would inject a
    // perturbation that the nearly-parallel modes of a low-frequency section amplify into a
    // limit cycle just above the threshold.
    if s1.abs().max(s2.abs()) < STATE_FLUSH {
        s1 = 0.0;
        s2 = 0.0;
    }
    *st = [s1, s2];
    y
}

impl SampleStage for SosFilter {
    fn process_inplace(&mut self, block: &mut [f32]) {
        self.filter_block(block);
    }

    fn reset(&mut self) {
        self.state.fill([0.0; 2]);
        self.non_finite = 0;
    }

    fn latency_samples(&self) -> usize {
        0
    }
}
