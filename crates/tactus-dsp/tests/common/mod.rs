//! Checks shared by the pitch trackers' tests (`shs.rs`, `bassnet.rs`).
#![allow(dead_code)]

use tactus_dsp::shs::{Shs, ShsConfig};
use tactus_dsp::yin::PitchEstimate;
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

pub fn run(s: &mut Shs, x: &[f32], chunks: &[usize]) -> Vec<PitchEstimate> {
    let mut out = Vec::new();
    let mut i = 0;
    let mut k = 0;
    while i < x.len() {
        let n = chunks[k % chunks.len()].max(1).min(x.len() - i);
        s.process(&x[i..i + n], &mut |h, e| {
            assert_eq!(h, out.len());
            out.push(e)
        });
        i += n;
        k += 1;
    }
    s.finish(&mut |h, e| {
        assert_eq!(h, out.len());
        out.push(e)
    });
    out
}

/// Every chunking of `x` and a reset between runs give the same hops as one block, one per
/// hop of the input, for each configuration.
pub fn assert_chunking_and_reset_invariant(cfgs: &[ShsConfig], x: &[f32]) {
    for c in cfgs {
        let mut s = Shs::new(c.clone()).unwrap();
        let whole = run(&mut s, x, &[x.len()]);
        for chunks in [vec![1usize, 7, 300], vec![49], vec![4096, 13]] {
            s.reset();
            assert_eq!(run(&mut s, x, &chunks), whole, "chunks {chunks:?}");
        }
        assert_eq!(whole.len(), x.len().div_ceil(c.hop));
    }
}
