//! The spectrum of one analysis frame as the pitch trackers over mixtures see it (step 1 of
//! the [`crate::shs`] module docs): the frame minus its mean, scaled to unit peak, times a
//! Hann window, zero-padded, real FFT. Shared by the harmonic sum ([`crate::shs`]) and the
//! learned salience's front end ([`crate::bassnet::BassFront`]), so both read the same
//! values.

use std::sync::Arc;

use realfft::num_complex::Complex;
use realfft::{RealFftPlanner, RealToComplex};

/// The Hann window of step 1, `n` samples, sampled at the centres `(i + 0.5) / n`.
pub(crate) fn hann(n: usize) -> Vec<f32> {
    (0..n)
        .map(|i| {
            let x = std::f64::consts::PI * 2.0 * (i as f64 + 0.5) / n as f64;
            (0.5 - 0.5 * x.cos()) as f32
        })
        .collect()
}

/// Step 1 before the FFT: `frame` (at most `window.len()` samples) minus its mean, scaled to
/// unit peak, times `window`, into `buf`, zero-padded; the peak before scaling, or `None`
/// (and `buf` unscaled) when the frame is silent or not finite.
pub(crate) fn prepare_frame(frame: &[f32], window: &[f32], buf: &mut [f32]) -> Option<f32> {
    let n = frame.len().min(window.len());
    let mean = frame[..n].iter().map(|&x| f64::from(x)).sum::<f64>() / n.max(1) as f64;
    let mut peak = 0.0f32;
    for (i, (b, &x)) in buf.iter_mut().zip(&frame[..n]).enumerate() {
        let v = (f64::from(x) - mean) as f32;
        peak = peak.max(v.abs());
        *b = v * window[i];
    }
    buf[n..].fill(0.0);
    if peak.is_nan() || peak <= 1e-9 {
        return None;
    }
    for b in &mut buf[..n] {
        *b /= peak;
    }
    Some(peak)
}

/// Step 1, planned once: a frame through [`prepare_frame`] (Hann window of `frame` samples,
/// zero-padded to `n_fft`) and a real FFT.
pub(crate) struct FrameFft {
    fwd: Arc<dyn RealToComplex<f32>>,
    window: Vec<f32>,
    buf: Vec<f32>,
    scratch: Vec<Complex<f32>>,
    /// The last analysed frame's spectrum (`n_fft / 2 + 1` bins).
    pub(crate) spec: Vec<Complex<f32>>,
}

impl FrameFft {
    pub(crate) fn new(frame: usize, n_fft: usize) -> Self {
        let fwd = RealFftPlanner::<f32>::new().plan_fft_forward(n_fft);
        FrameFft {
            spec: fwd.make_output_vec(),
            scratch: fwd.make_scratch_vec(),
            window: hann(frame),
            buf: vec![0.0; n_fft],
            fwd,
        }
    }

    /// FFT length.
    pub(crate) fn n_fft(&self) -> usize {
        self.buf.len()
    }

    /// The spectrum of `frame` into [`FrameFft::spec`]; the frame's peak before scaling, or
    /// `None` when it is silent or not finite (the spectrum is then stale).
    pub(crate) fn analyse(&mut self, frame: &[f32]) -> Option<f32> {
        let peak = prepare_frame(frame, &self.window, &mut self.buf)?;
        self.fwd
            .process_with_scratch(&mut self.buf, &mut self.spec, &mut self.scratch)
            .ok()?;
        Some(peak)
    }
}
