//! Overlapping analysis frames from a stream of any chunk size.
//!
//! Frame `i` covers padded samples `[i*hop, i*hop + frame)` of the stream that has
//! `frame / 2` zeros prepended, so it is centred on input sample `i * hop`. A stream of
//! `n` samples has `n.div_ceil(hop)` frames; [`Framer::finish`] emits the last ones with
//! zeros after the input. The framer owns one buffer of `2 * frame + hop` samples allocated
//! at construction and never allocates again.

use crate::sanitize::sanitize_sample;
use crate::ConfigError;

/// The periodic Hann window of `n` samples scaled by `1 / sqrt(Σ w²)` (computed in f64), so
/// that white noise of variance σ² has `E|X[k]|² = σ²` in every bin of its FFT: the window
/// of the spectral front ends ([`crate::flux`], [`crate::melbank`]).
pub fn hann_unit_power(n: usize) -> Vec<f32> {
    let hann: Vec<f64> = (0..n)
        .map(|i| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / n as f64).cos())
        .collect();
    let norm = 1.0 / hann.iter().map(|w| w * w).sum::<f64>().sqrt();
    hann.iter().map(|w| (w * norm) as f32).collect()
}

/// A real FFT of one frame weighted by [`hann_unit_power`], with its buffers allocated
/// once (the spectral front ends' shared first step: [`crate::flux`], [`crate::melbank`]).
pub struct WindowedFft {
    fft: std::sync::Arc<dyn realfft::RealToComplex<f32>>,
    window: Vec<f32>,
    input: Vec<f32>,
    spectrum: Vec<realfft::num_complex::Complex<f32>>,
    scratch: Vec<realfft::num_complex::Complex<f32>>,
}

impl WindowedFft {
    /// A transform of `n`-sample frames.
    pub fn new(n: usize) -> Self {
        let fft = realfft::RealFftPlanner::<f32>::new().plan_fft_forward(n);
        WindowedFft {
            window: hann_unit_power(n),
            input: fft.make_input_vec(),
            spectrum: fft.make_output_vec(),
            scratch: fft.make_scratch_vec(),
            fft,
        }
    }

    /// The spectrum (`n / 2 + 1` bins) of `frame` (`n` samples) times the window.
    pub fn transform(&mut self, frame: &[f32]) -> &[realfft::num_complex::Complex<f32>] {
        for ((d, &x), &w) in self.input.iter_mut().zip(frame).zip(&self.window) {
            *d = x * w;
        }
        // Cannot fail: every buffer came from the plan's own make_*_vec.
        let _ =
            self.fft
                .process_with_scratch(&mut self.input, &mut self.spectrum, &mut self.scratch);
        &self.spectrum
    }
}

/// Cuts a sample stream into centred, overlapping frames. See the module docs.
#[derive(Debug, Clone)]
pub struct Framer {
    frame: usize,
    hop: usize,
    buf: Vec<f32>,
    len: usize,
    /// Padded-stream index of `buf[0]`.
    buf_start: usize,
    next_hop: usize,
    real_seen: usize,
    /// Frames with index >= limit are not emitted (used while flushing).
    limit: usize,
}

const ZEROS: [f32; 256] = [0.0; 256];

impl Framer {
    /// A framer with `frame` samples per frame and `hop` samples between frame centres.
    pub fn new(frame: usize, hop: usize) -> Result<Self, ConfigError> {
        if frame == 0 {
            return Err(ConfigError::invalid("frame", "must be at least 1 sample"));
        }
        if hop == 0 {
            return Err(ConfigError::invalid("hop", "must be at least 1 sample"));
        }
        let mut f = Framer {
            frame,
            hop,
            buf: vec![0.0; 2 * frame + hop],
            len: 0,
            buf_start: 0,
            next_hop: 0,
            real_seen: 0,
            limit: usize::MAX,
        };
        f.reset();
        Ok(f)
    }

    /// Samples per frame.
    pub fn frame_len(&self) -> usize {
        self.frame
    }

    /// Samples between frame centres.
    pub fn hop(&self) -> usize {
        self.hop
    }

    /// Index of the next frame to be emitted (= frames emitted so far).
    pub fn frames_emitted(&self) -> usize {
        self.next_hop
    }

    /// Real (not padding) samples accepted so far.
    pub fn samples_seen(&self) -> usize {
        self.real_seen
    }

    /// Frame `i` is emitted once input sample `i*hop + latency_samples() - 1` has arrived.
    pub fn latency_samples(&self) -> usize {
        self.frame - self.frame / 2
    }

    /// Back to the just-constructed state: the `frame / 2` leading zeros are in place.
    pub fn reset(&mut self) {
        let pad = self.frame / 2;
        self.buf[..pad].fill(0.0);
        self.len = pad;
        self.buf_start = 0;
        self.next_hop = 0;
        self.real_seen = 0;
        self.limit = usize::MAX;
    }

    /// Feeds samples; calls `emit(i, frame)` for every frame completed by them, in order.
    /// Non-finite samples are replaced by 0; returns how many there were.
    pub fn push<F: FnMut(usize, &[f32])>(&mut self, input: &[f32], mut emit: F) -> usize {
        self.real_seen += input.len();
        self.push_padded(input, &mut emit)
    }

    /// Ends the stream: emits the remaining frames (`n.div_ceil(hop)` in all) as if zeros
    /// followed the input. Call [`Framer::reset`] before feeding a new stream.
    pub fn finish<F: FnMut(usize, &[f32])>(&mut self, mut emit: F) {
        let total = self.real_seen.div_ceil(self.hop);
        self.limit = total;
        while self.next_hop < total {
            self.push_padded(&ZEROS, &mut emit);
        }
    }

    fn push_padded<F: FnMut(usize, &[f32])>(&mut self, mut input: &[f32], emit: &mut F) -> usize {
        let mut bad = 0;
        let cap = self.buf.len();
        while !input.is_empty() && self.next_hop < self.limit {
            let next_start = self.next_hop * self.hop;
            let end = self.buf_start + self.len;
            if end < next_start {
                // hop > frame: samples between frames are never looked at.
                let skip = (next_start - end).min(input.len());
                for &x in &input[..skip] {
                    bad += !x.is_finite() as usize;
                }
                input = &input[skip..];
                self.buf_start = end + skip;
                self.len = 0;
                continue;
            }
            if self.len == cap {
                // The pending frame is incomplete, so next_start > buf_start + cap - frame:
                // dropping everything before it frees at least `hop` slots.
                let drop = next_start - self.buf_start;
                self.buf.copy_within(drop..self.len, 0);
                self.len -= drop;
                self.buf_start = next_start;
            }
            let take = (cap - self.len).min(input.len());
            for (dst, &x) in self.buf[self.len..self.len + take]
                .iter_mut()
                .zip(&input[..take])
            {
                let (y, was_bad) = sanitize_sample(x);
                *dst = y;
                bad += was_bad as usize;
            }
            self.len += take;
            input = &input[take..];
            loop {
                let start = self.next_hop * self.hop;
                if self.next_hop >= self.limit || start + self.frame > self.buf_start + self.len {
                    break;
                }
                let off = start - self.buf_start;
                emit(self.next_hop, &self.buf[off..off + self.frame]);
                self.next_hop += 1;
            }
        }
        for &x in input {
            bad += !x.is_finite() as usize;
        }
        bad
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The obvious oracle: pad, then slice.
    fn naive(x: &[f32], frame: usize, hop: usize) -> Vec<Vec<f32>> {
        let pad = frame / 2;
        let mut p = vec![0.0; pad];
        p.extend_from_slice(x);
        p.resize(pad + x.len() + frame + hop, 0.0);
        (0..x.len().div_ceil(hop))
            .map(|i| p[i * hop..i * hop + frame].to_vec())
            .collect()
    }

    fn chunked(x: &[f32], frame: usize, hop: usize, chunk: usize) -> Vec<Vec<f32>> {
        let mut f = Framer::new(frame, hop).unwrap();
        let mut out = Vec::new();
        for c in x.chunks(chunk.max(1)) {
            f.push(c, |i, fr| {
                assert_eq!(i, out.len());
                out.push(fr.to_vec())
            });
        }
        f.finish(|i, fr| {
            assert_eq!(i, out.len());
            out.push(fr.to_vec())
        });
        out
    }

    #[test]
    fn matches_naive_for_many_shapes() {
        let x: Vec<f32> = (0..1000).map(|i| i as f32 + 1.0).collect();
        for &(frame, hop) in &[(1, 1), (2, 1), (8, 3), (16, 16), (5, 9), (64, 10), (7, 2)] {
            for n in [0usize, 1, 2, 7, 63, 64, 65, 1000] {
                let want = naive(&x[..n], frame, hop);
                for chunk in [1usize, 2, 3, 17, 64, 1000] {
                    assert_eq!(
                        chunked(&x[..n], frame, hop, chunk),
                        want,
                        "f{frame} h{hop} n{n} c{chunk}"
                    );
                }
            }
        }
    }

    #[test]
    fn reset_reproduces() {
        let x: Vec<f32> = (0..300).map(|i| (i as f32 * 0.1).sin()).collect();
        let a = chunked(&x, 32, 8, 7);
        let mut f = Framer::new(32, 8).unwrap();
        f.push(&x[..100], |_, _| {});
        f.reset();
        let mut b = Vec::new();
        f.push(&x, |_, fr| b.push(fr.to_vec()));
        f.finish(|_, fr| b.push(fr.to_vec()));
        assert_eq!(a, b);
    }

    #[test]
    fn counts_non_finite() {
        let mut f = Framer::new(4, 2).unwrap();
        let n = f.push(&[1.0, f32::NAN, f32::INFINITY, 2.0], |_, fr| {
            assert!(fr.iter().all(|v| v.is_finite()))
        });
        assert_eq!(n, 2);
    }
}
