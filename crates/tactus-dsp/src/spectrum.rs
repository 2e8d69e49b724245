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
    // The peak in eight lanes, folded at the end: a maximum does not depend on the order
    // its values come in (`f32::max` skips NaN, and every lane starts at 0), so this is the
    // one-by-one fold's value, and the loop runs in vector registers instead of as one chain.
    let mut lanes = [0.0f32; 8];
    let split = n / 8 * 8;
    for ((bc, xc), wc) in buf[..split]
        .chunks_exact_mut(8)
        .zip(frame[..split].chunks_exact(8))
        .zip(window[..split].chunks_exact(8))
    {
        for k in 0..8 {
            let v = (f64::from(xc[k]) - mean) as f32;
            lanes[k] = lanes[k].max(v.abs());
            bc[k] = v * wc[k];
        }
    }
    for ((b, &x), &wv) in buf[split..n]
        .iter_mut()
        .zip(&frame[split..n])
        .zip(&window[split..n])
    {
        let v = (f64::from(x) - mean) as f32;
        lanes[0] = lanes[0].max(v.abs());
        *b = v * wv;
    }
    let peak = lanes.iter().fold(0.0f32, |a, &b| a.max(b));
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

#[cfg(test)]
mod tests {
    use super::{hann, prepare_frame};

    /// Step 1 before the FFT, written the obvious way: one value at a time.
    fn prepare_one_by_one(frame: &[f32], window: &[f32], buf: &mut [f32]) -> Option<f32> {
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

    #[test]
    fn prepared_frame_equals_the_one_by_one_loop_bit_for_bit() {
        let mut seed = 0x2545_f491u32;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            (seed as f32 / u32::MAX as f32) * 2.0 - 1.0
        };
        // Lengths that are and are not multiples of eight, frames shorter than the window,
        // the peak in the tail, a NaN, silence and a DC offset.
        for (len, win, n_fft) in [
            (1024usize, 1024usize, 2048usize),
            (1029, 1029, 2048),
            (7, 8, 16),
            (13, 16, 32),
            (64, 64, 64),
        ] {
            let window = hann(win);
            for case in 0..6 {
                let mut frame: Vec<f32> = (0..len)
                    .map(|i| rnd() * 10f32.powi(i as i32 % 5 - 3))
                    .collect();
                match case {
                    1 => frame[len - 1] = 40.0,
                    2 => frame[len / 2] = f32::NAN,
                    3 => frame.fill(0.0),
                    4 => frame.fill(0.25),
                    5 => frame.truncate(len - len / 3),
                    _ => {}
                }
                let (mut got, mut want) = (vec![f32::NAN; n_fft], vec![f32::NAN; n_fft]);
                let (g, w) = (
                    prepare_frame(&frame, &window, &mut got),
                    prepare_one_by_one(&frame, &window, &mut want),
                );
                assert_eq!(
                    g.map(f32::to_bits),
                    w.map(f32::to_bits),
                    "len {len} case {case}"
                );
                for (i, (a, b)) in got.iter().zip(&want).enumerate() {
                    assert_eq!(a.to_bits(), b.to_bits(), "len {len} case {case} value {i}");
                }
            }
        }
    }
}
