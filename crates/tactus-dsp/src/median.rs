//! Running median over an odd window of samples: the paper's denoising median filter.
//!
//! ## Algorithm
//! The streaming [`MedianFilter`] outputs, for input sample `i`, the median of the last `w`
//! inputs `x[i−w+1 ..= i]`, with zeros before the start of the stream. That is the centred
//! median (scipy's `medfilt`, zero padding) delayed by `(w − 1) / 2` samples, which is its
//! latency. It keeps the window twice: a ring in arrival order and a sorted copy. Each new
//! sample overwrites the oldest one in the sorted copy (found by binary search) and is moved
//! to its place by adjacent swaps: O(log w + distance moved) per sample, O(w) worst case, no
//! allocation after construction. Window 3 (the default, docs/design.md) takes a branch-only fast
//! path; window 1 is the identity.
//!
//! Samples are ordered with [`f32::total_cmp`], so the result equals sorting the window and
//! taking its middle element, bit for bit (−0.0 sorts below +0.0). Non-finite inputs are
//! replaced by 0 and counted, and inputs below [`crate::sanitize::FLUSH_BELOW`] become 0
//! (see [`crate::sanitize`]).
//!
//! [`median_centered`] is the offline, zero-latency form for whole signals.
//!
//! ## Defaults and latency
//! Window 3 samples (docs/design.md, after the denoising high-pass). Latency `(w − 1) / 2` samples.

use crate::sanitize::sanitize_sample;
use crate::{ConfigError, SampleStage};

/// The window docs/design.md uses after the denoising high-pass.
pub const DEFAULT_WINDOW: usize = 3;

/// Streaming median over the last `window` samples. See the module docs.
#[derive(Clone, Debug)]
pub struct MedianFilter {
    window: usize,
    /// The window in arrival order; `ring[head]` is the oldest sample. (Window 3 uses only
    /// `ring[0..2]`, the two previous samples.)
    ring: Vec<f32>,
    head: usize,
    /// The same samples, sorted by `total_cmp`.
    sorted: Vec<f32>,
    non_finite: u64,
}

impl MedianFilter {
    /// A median filter over `window` samples; `window` must be odd (so the median is one
    /// sample) and at least 1.
    pub fn new(window: usize) -> Result<Self, ConfigError> {
        if window & 1 == 0 {
            return Err(ConfigError::invalid(
                "window",
                format!("{window} must be odd and at least 1"),
            ));
        }
        Ok(MedianFilter {
            window,
            ring: vec![0.0; window],
            head: 0,
            sorted: vec![0.0; window],
            non_finite: 0,
        })
    }

    /// Samples in the window.
    pub fn window(&self) -> usize {
        self.window
    }

    /// Input samples that were NaN or infinite (processed as 0) since construction or reset.
    pub fn non_finite_count(&self) -> u64 {
        self.non_finite
    }

    /// Filters `block` in place, choosing the path once per block.
    fn filter_block(&mut self, block: &mut [f32]) {
        let mut bad = 0u64;
        let mut clean = |x: f32| {
            let (x, was_bad) = sanitize_sample(x);
            bad += u64::from(was_bad);
            x
        };
        match self.window {
            1 => block.iter_mut().for_each(|x| *x = clean(*x)),
            3 => {
                // `ring[0]` and `ring[1]` hold the two previous samples, oldest first.
                let (mut a, mut b) = (self.ring[0], self.ring[1]);
                for x in block.iter_mut() {
                    let c = clean(*x);
                    *x = median3(a, b, c);
                    (a, b) = (b, c);
                }
                (self.ring[0], self.ring[1]) = (a, b);
            }
            _ => {
                for x in block.iter_mut() {
                    *x = self.tick_sorted(clean(*x));
                }
            }
        }
        self.non_finite += bad;
    }

    fn tick_sorted(&mut self, x: f32) -> f32 {
        let old = std::mem::replace(&mut self.ring[self.head], x);
        self.head += 1;
        if self.head == self.window {
            self.head = 0;
        }
        let sorted = &mut self.sorted[..];
        // `old` is in `sorted`; any bitwise-equal copy will do.
        let mut pos = match sorted.binary_search_by(|v| v.total_cmp(&old)) {
            Ok(p) => p,
            // Cannot happen (every ring value is in `sorted`); the nearest slot avoids a panic.
            Err(p) => p.min(sorted.len() - 1),
        };
        sorted[pos] = x;
        while pos > 0 && sorted[pos - 1].total_cmp(&x).is_gt() {
            sorted.swap(pos - 1, pos);
            pos -= 1;
        }
        while pos + 1 < sorted.len() && sorted[pos + 1].total_cmp(&x).is_lt() {
            sorted.swap(pos + 1, pos);
            pos += 1;
        }
        sorted[self.window / 2]
    }
}

/// Median of three by `total_cmp`.
#[inline]
fn median3(a: f32, b: f32, c: f32) -> f32 {
    let (lo, hi) = if a.total_cmp(&b).is_le() {
        (a, b)
    } else {
        (b, a)
    };
    if c.total_cmp(&lo).is_le() {
        lo
    } else if c.total_cmp(&hi).is_ge() {
        hi
    } else {
        c
    }
}

impl SampleStage for MedianFilter {
    fn process_inplace(&mut self, block: &mut [f32]) {
        self.filter_block(block);
    }

    fn reset(&mut self) {
        self.ring.fill(0.0);
        self.sorted.fill(0.0);
        self.head = 0;
        self.non_finite = 0;
    }

    fn latency_samples(&self) -> usize {
        (self.window - 1) / 2
    }
}

/// Offline centred median with zero padding, as `scipy.signal.medfilt(x, window)`:
/// `out[i]` is the median of `x[i−h ..= i+h]`, `h = (window − 1) / 2`, with zeros outside `x`.
/// Same length as `x`. Non-finite samples count as 0 (scipy would propagate them
/// unpredictably). Errors when `window` is even or 0.
pub fn median_centered(x: &[f32], window: usize) -> Result<Vec<f32>, ConfigError> {
    let mut filter = MedianFilter::new(window)?;
    let h = filter.latency_samples();
    let mut out = vec![0.0; x.len() + h];
    filter.process(x, &mut out[..x.len()]);
    let zeros = [0.0f32; 64];
    let mut at = x.len();
    while at < out.len() {
        let n = (out.len() - at).min(zeros.len());
        filter.process(&zeros[..n], &mut out[at..at + n]);
        at += n;
    }
    out.drain(..h.min(out.len()));
    Ok(out)
}
