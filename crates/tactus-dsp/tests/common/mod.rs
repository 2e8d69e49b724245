//! Checks shared by the pitch trackers' tests (`shs.rs`, `bassnet.rs`).
#![allow(dead_code)]

use tactus_dsp::shs::Shs;
use tactus_dsp::HopStage;

/// Feeds `x` one sample at a time: hops come out in order, and after sample `k` exactly as
/// many as the stated latency allows (`(k + 1 − latency) / hop + 1`, at most one per hop of
/// the input).
pub fn assert_emission_follows_latency(s: &mut Shs, x: &[f32]) {
    let (hop, lat) = (s.hop(), s.latency_samples());
    let mut emitted = 0usize;
    for (k, &v) in x.iter().enumerate() {
        s.process(&[v], &mut |i, _| {
            assert_eq!(i, emitted);
            emitted += 1;
        });
        let expect = if k + 1 >= lat {
            (k + 1 - lat) / hop + 1
        } else {
            0
        };
        assert_eq!(emitted, expect.min(x.len().div_ceil(hop)), "sample {k}");
    }
}

/// Feeds `y` one sample at a time; the first voiced hop and how many samples had been fed
/// when it came out.
pub fn first_voiced(s: &mut Shs, y: &[f32]) -> Option<(usize, usize)> {
    let mut first: Option<(usize, usize)> = None;
    for (k, &v) in y.iter().enumerate() {
        s.process(&[v], &mut |i, e| {
            if first.is_none() && e.f0_hz > 0.0 {
                first = Some((i, k + 1));
            }
        });
    }
    first
}
