//! The `none` separator: no separation at all.
//!
//! The input is treated as a single stem: every requested stem receives the mono mix
//! `(L + R) / 2`, sample for sample (non-finite samples become 0, values below 1e-30 are
//! flushed to 0, as everywhere in Tactus). Useful when a track already is one instrument,
//! and as the trivial baseline the real backends must beat. Latency 0; nothing allocates
//! after construction.

use tactus_dsp::sanitize::sanitize_sample;

use crate::{SeparateError, Separator, Stem, StemOutput, StemSet};

/// Every requested stem is the mono mix. See the module docs.
#[derive(Clone, Debug)]
pub struct NoneSeparator {
    sample_rate: u32,
    stems: StemSet,
}

impl NoneSeparator {
    /// A pass-through separator for `stems` at `sample_rate` Hz.
    pub fn new(sample_rate: u32, stems: StemSet) -> Result<Self, SeparateError> {
        if sample_rate == 0 {
            return Err(SeparateError::SampleRate(sample_rate));
        }
        if stems.is_empty() {
            return Err(SeparateError::NoStems);
        }
        Ok(NoneSeparator { sample_rate, stems })
    }
}

impl Separator for NoneSeparator {
    fn name(&self) -> &'static str {
        "none"
    }

    fn sample_rate(&self) -> u32 {
        self.sample_rate
    }

    fn stems(&self) -> StemSet {
        self.stems
    }

    fn process(&mut self, left: &[f32], right: &[f32], out: &mut StemOutput) {
        out.declare(self.stems);
        for (&l, &r) in left.iter().zip(right) {
            let m = 0.5 * sanitize_sample(l).0 + 0.5 * sanitize_sample(r).0;
            for s in Stem::ALL {
                if self.stems.contains(s) {
                    out.push(s, m);
                }
            }
        }
    }

    fn finish(&mut self, out: &mut StemOutput) {
        out.declare(self.stems);
    }

    fn reset(&mut self) {}

    fn latency_samples(&self) -> usize {
        0
    }
}
