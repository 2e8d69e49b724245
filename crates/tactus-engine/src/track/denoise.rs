//! The front ends of a stem's tracks: the denoiser and the decimator.

use tactus_dsp::median::MedianFilter;
use tactus_dsp::sos::{Response, SosFilter};
use tactus_dsp::{ConfigError, SampleStage};

/// Denoising front end of a stem (docs/design.md: Butterworth high-pass order 4, then a
/// 3-sample median).
pub struct Denoise {
    hp: SosFilter,
    median: MedianFilter,
}

impl Denoise {
    /// A high-pass at `cutoff_hz` then a 3-sample median.
    pub fn new(cutoff_hz: f64, sample_rate: u32) -> Result<Self, ConfigError> {
        Ok(Denoise {
            hp: SosFilter::highpass(cutoff_hz, 4, sample_rate)?,
            median: MedianFilter::new(3)?,
        })
    }

    /// Denoises a block in place.
    pub fn process_inplace(&mut self, block: &mut [f32]) {
        self.hp.process_inplace(block);
        self.median.process_inplace(block);
    }

    /// Samples of delay the median adds.
    pub fn latency_samples(&self) -> usize {
        self.hp.latency_samples() + self.median.latency_samples()
    }

    /// Back to the initial state.
    pub fn reset(&mut self) {
        self.hp.reset();
        self.median.reset();
    }
}

/// Anti-aliased integer decimation in front of a pitch tracker: a stem whose highest
/// pitch is 400 Hz does not need 44.1 kHz. The rate after decimation keeps 10 ms hops
/// whole (`rate / factor` divisible by 100) and stays at least 7 × fmax, where YIN keeps
/// its ≤ 5 cent accuracy (tactus-dsp's pitch tests hold to sr/8 for sines).
/// An order-8 Butterworth low-pass at 0.4 × the new rate removes what would alias.
pub struct Decimator {
    lp: SosFilter,
    pub(super) factor: usize,
    /// Input samples to skip before the next kept one.
    skip: usize,
    scratch: Vec<f32>,
    out: Vec<f32>,
}

impl Decimator {
    /// The largest factor that keeps `rate / factor` ≥ 7·fmax with whole 10 ms hops.
    pub fn factor_for(rate: u32, fmax_hz: f32) -> usize {
        (1..=32usize)
            .rev()
            .find(|&f| {
                (rate as usize).is_multiple_of(f)
                    && (rate as usize / f).is_multiple_of(100)
                    && (rate as usize / f) as f32 >= 7.0 * fmax_hz
            })
            .unwrap_or(1)
    }

    /// A decimator by `factor` for input at `rate`.
    pub fn new(rate: u32, factor: usize) -> Result<Self, ConfigError> {
        let out_rate = rate as f64 / factor as f64;
        let lp = SosFilter::butterworth(
            8,
            Response::LowPass {
                cutoff_hz: 0.4 * out_rate,
            },
            rate,
        )?;
        Ok(Decimator {
            lp,
            factor,
            skip: 0,
            scratch: Vec::with_capacity(1 << 16),
            out: Vec::with_capacity(1 << 16),
        })
    }

    /// Filters and decimates `block`; the result is in [`Decimator::output`].
    pub fn process(&mut self, block: &[f32]) {
        self.out.clear();
        if self.factor == 1 {
            self.out.extend_from_slice(block);
            return;
        }
        self.scratch.clear();
        self.scratch.extend_from_slice(block);
        self.lp.process_inplace(&mut self.scratch);
        let mut i = self.skip;
        while i < self.scratch.len() {
            self.out.push(self.scratch[i]);
            i += self.factor;
        }
        self.skip = i - self.scratch.len();
    }

    /// The decimated samples of the last block.
    pub fn output(&self) -> &[f32] {
        &self.out
    }

    /// Back to the initial state.
    pub fn reset(&mut self) {
        self.lp.reset();
        self.skip = 0;
        self.out.clear();
    }
}
