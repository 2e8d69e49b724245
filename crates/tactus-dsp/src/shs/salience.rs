//! Steps 1 to 3 of the module docs: the harmonic-sum salience of every candidate in one
//! frame, the frame's voicing evidence, and its band level (for the attack alignment).

use super::config::ShsConfig;
use super::SILENT_DB;
use crate::spectrum::FrameFft;

/// Salience of one analysed frame, and the frame's voicing evidence.
pub(super) struct Salience {
    pub(super) fft: FrameFft,
    mag: Vec<f32>,
    /// `(k_lo, k_hi)` per (candidate, harmonic), `k_hi < k_lo` when above Nyquist.
    ranges: Vec<(u32, u32)>,
    /// `tilt(f_c) · w^{h−1}` per (candidate, harmonic).
    weights: Vec<f32>,
    /// FFT bins of the searched band, for the noise floor.
    band: (usize, usize),
    weight_sum: f32,
    harmonics: usize,
    pub(super) sharp: f32,
    ln_r0: f32,
    compress: f32,
    fund_ratio: f32,
    /// Peak of the last frame before normalisation (its level).
    pub(super) last_peak: f32,
    /// Mean power over the searched band of the last frame (normalised frame).
    last_band_power: f32,
}

impl std::fmt::Debug for Salience {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Salience")
            .field("n_fft", &self.fft.n_fft())
            .field("harmonics", &self.harmonics)
            .finish_non_exhaustive()
    }
}

impl Salience {
    pub(super) fn new(cfg: &ShsConfig, m: usize) -> Self {
        let df = cfg.sample_rate as f64 / cfg.n_fft as f64;
        let nyq = cfg.n_fft / 2;
        let half = 2f64.powf(cfg.harmonic_width_st as f64 / 12.0);
        let h_n = cfg.harmonics;
        let mut ranges = Vec::with_capacity(m * h_n);
        let mut weights = Vec::with_capacity(m * h_n);
        for c in 0..m {
            let f = cfg.bin_hz(c) as f64;
            let tilt = (f / cfg.fmin_hz as f64).powf(-(cfg.low_tilt as f64));
            for h in 1..=h_n {
                let x = f * h as f64;
                let lo = (x / half / df).round().max(1.0) as usize;
                let hi = ((x * half / df).round() as usize).min(nyq);
                ranges.push((lo as u32, hi as u32));
                let w = if lo <= hi && x <= cfg.max_harmonic_hz as f64 {
                    tilt * (cfg.harmonic_decay as f64).powi(h as i32 - 1)
                } else {
                    0.0
                };
                weights.push(w as f32);
            }
        }
        let band_lo = ((cfg.fmin_hz as f64 / df).floor() as usize).max(1);
        let band_hi = ((cfg.fmax_hz as f64 * h_n as f64 / df).ceil() as usize)
            .min(nyq)
            .max(band_lo);
        let weight_sum = (0..h_n).map(|h| cfg.harmonic_decay.powi(h as i32)).sum();
        Salience {
            fft: FrameFft::new(cfg.frame, cfg.n_fft),
            mag: vec![0.0; nyq + 1],
            ranges,
            weights,
            band: (band_lo, band_hi),
            weight_sum,
            harmonics: h_n,
            sharp: cfg.sharpness,
            ln_r0: cfg.voicing_ratio.ln(),
            compress: cfg.compress,
            fund_ratio: cfg.fundamental_ratio,
            last_peak: 0.0,
            last_band_power: 0.0,
        }
    }

    /// Magnitude spectrum of `frame` into `mag`; false when the frame is silent.
    pub(super) fn spectrum(&mut self, frame: &[f32]) -> bool {
        let Some(peak) = self.fft.analyse(frame) else {
            return false;
        };
        self.last_peak = peak;
        let e = 0.5 * self.compress;
        for (m, c) in self.mag.iter_mut().zip(&self.fft.spec) {
            let p = c.re * c.re + c.im * c.im;
            *m = if e == 0.5 { p.sqrt() } else { p.powf(e) };
        }
        let (b0, b1) = self.band;
        self.last_band_power =
            self.mag[b0..=b1].iter().map(|&a| a * a).sum::<f32>() / (b1 + 1 - b0) as f32;
        true
    }

    /// Band level of the last frame in dB, in the input's units (step 9): the mean power
    /// over the searched band (of `|X_k|^compress`). Power rather than magnitude: a frame
    /// that holds the end of one note and the start of the next has more spectral peaks but
    /// not more energy, so a change at a constant level is no rise.
    pub(super) fn band_level_db(&self) -> f32 {
        let a = self.last_band_power * self.last_peak * self.last_peak;
        if a > 1e-24 {
            10.0 * a.log10()
        } else {
            SILENT_DB
        }
    }

    /// Salience per candidate into `out`; returns the voicing evidence V.
    pub(super) fn salience(&self, out: &mut [f32]) -> f32 {
        let h_n = self.harmonics;
        let mut best = 0.0f32;
        for (c, s) in out.iter_mut().enumerate() {
            let mut acc = 0.0f32;
            let mut first = 0.0f32;
            let mut strongest = 0.0f32;
            for h in 0..h_n {
                let (lo, hi) = self.ranges[c * h_n + h];
                let w = self.weights[c * h_n + h];
                if lo > hi || w == 0.0 {
                    continue;
                }
                // Magnitudes are never −0 and the maximum starts at 0: `f32::max`'s value.
                let mut mx = 0.0f32;
                for &a in &self.mag[lo as usize..=hi as usize] {
                    mx = crate::max_skip_nan(mx, a);
                }
                acc += w * mx;
                if h == 0 {
                    first = mx;
                }
                strongest = strongest.max(mx);
            }
            if self.fund_ratio > 0.0 && strongest > 0.0 {
                let r = first / (strongest * self.fund_ratio);
                acc *= r.min(1.0);
            }
            *s = acc;
            best = best.max(acc);
        }
        let (b0, b1) = self.band;
        let floor = self.mag[b0..=b1].iter().sum::<f32>() / (b1 + 1 - b0) as f32 * self.weight_sum;
        if !(floor > 0.0 && best > 0.0) {
            return 0.02;
        }
        let z = ((best / floor).ln() - self.ln_r0) / 0.5;
        (1.0 / (1.0 + (-z).exp())).clamp(0.02, 0.98)
    }
}
