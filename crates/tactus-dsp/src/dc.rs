//! DC removal at the engine's input: a constant offset is not music.
//!
//! `y = x − m`, with the running mean `m ← m + a·(x − m)`, `a = 1 − exp(−1 / (τ·rate))`
//! and `τ` = [`TIME_CONSTANT_S`] (a first-order high-pass at `1 / (2π·τ)` ≈ 0.16 Hz: below
//! any note, −0.0002 dB at 41 Hz). The mean starts at the first sample, so a file that
//! begins at an offset does not begin with a step (which read as a drum hit and a burst of
//! pitch; docs/decisions/0053-dc-at-the-input.md). Causal, no latency, no allocation.

use crate::{ConfigError, SampleStage};

/// Time constant of the running mean, seconds.
pub const TIME_CONSTANT_S: f32 = 1.0;

/// See the module docs.
#[derive(Clone, Debug)]
pub struct DcBlock {
    a: f32,
    mean: f32,
    started: bool,
}

impl DcBlock {
    /// A DC remover for input at `sample_rate`.
    pub fn new(sample_rate: u32) -> Result<Self, ConfigError> {
        if sample_rate == 0 {
            return Err(ConfigError::invalid("sample_rate", "must be positive"));
        }
        Ok(DcBlock {
            a: 1.0 - (-1.0 / (TIME_CONSTANT_S * sample_rate as f32)).exp(),
            mean: 0.0,
            started: false,
        })
    }
}

impl SampleStage for DcBlock {
    fn process_inplace(&mut self, block: &mut [f32]) {
        let Some(&first) = block.first() else {
            return;
        };
        if !self.started {
            self.mean = if first.is_finite() { first } else { 0.0 };
            self.started = true;
        }
        let (a, mut m) = (self.a, self.mean);
        for x in block.iter_mut() {
            m += a * (*x - m);
            *x -= m;
        }
        // A non-finite sample must not poison the mean for the rest of the stream.
        self.mean = if m.is_finite() { m } else { 0.0 };
    }

    fn reset(&mut self) {
        self.mean = 0.0;
        self.started = false;
    }

    fn latency_samples(&self) -> usize {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_offset_from_the_first_sample_is_removed_at_once() {
        let mut d = DcBlock::new(8000).unwrap();
        let mut x = vec![0.3f32; 800];
        d.process_inplace(&mut x);
        assert!(x.iter().all(|v| v.abs() < 1e-6), "{:?}", &x[..4]);
    }

    #[test]
    fn a_tone_passes_and_a_late_offset_decays_with_the_time_constant() {
        let rate = 8000;
        let mut d = DcBlock::new(rate).unwrap();
        let n = rate as usize * 3;
        let tone = |j: usize| 0.5 * (std::f32::consts::TAU * 41.0 * j as f32 / rate as f32).sin();
        let mut x: Vec<f32> = (0..n)
            .map(|j| tone(j) + if j >= rate as usize { 0.2 } else { 0.0 })
            .collect();
        // Fed in odd blocks: the state carries over.
        for c in x.chunks_mut(313) {
            d.process_inplace(c);
        }
        // One time constant after the step, e^-1 of it is left; three after, 5 %.
        let at = |t: f32| {
            let j = (t * rate as f32) as usize;
            x[j] - tone(j)
        };
        assert!(
            (at(2.0) - 0.2 * (-1.0f32).exp()).abs() < 0.02,
            "{}",
            at(2.0)
        );
        // Before the step the tone passes within 0.1 %.
        let err = (rate as usize / 2..rate as usize)
            .map(|j| (x[j] - tone(j)).abs())
            .fold(0.0, f32::max);
        assert!(err < 0.5 * 0.02, "{err}");
    }

    #[test]
    fn non_finite_input_does_not_stick() {
        let mut d = DcBlock::new(8000).unwrap();
        let mut x = vec![f32::NAN; 4];
        d.process_inplace(&mut x);
        let mut y = vec![0.1f32; 8000];
        d.process_inplace(&mut y);
        assert!(y.iter().all(|v| v.is_finite()));
    }
}
