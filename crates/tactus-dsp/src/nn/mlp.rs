//! The forward pass the embedded networks share ([`crate::drums`], [`crate::bassnet`]): the
//! inner dot product and a chain of dense layers, one input or a batch at a time.

use super::layer::Layer;

/// `bias + Σ row[i]·x[i]` over `row.len()` values, summed in eight lanes over the first
/// `8·⌊n/8⌋` values, the lanes added in order, then the bias, then the rest one by one: a
/// fixed order, so every network's output is the same on every run and for any batching.
pub(crate) fn dot8(row: &[f32], x: &[f32], bias: f32) -> f32 {
    let n = row.len();
    let split = n / 8 * 8;
    let (rc, rr) = row.split_at(split);
    let (xc, xr) = x[..n].split_at(split);
    let mut acc = [0f32; 8];
    for (wc, xc) in rc.chunks_exact(8).zip(xc.chunks_exact(8)) {
        for k in 0..8 {
            acc[k] += wc[k] * xc[k];
        }
    }
    let mut s: f32 = acc.iter().sum::<f32>() + bias;
    for (w, v) in rr.iter().zip(xr) {
        s += w * v;
    }
    s
}

/// Runs `layers` (ReLU between them, none after the last) on `input`, with `a` and `b` as
/// scratch at least as long as the widest layer; returns the last layer's outputs.
pub(crate) fn run_layers<'a>(
    layers: &[Layer],
    input: &[f32],
    a: &'a mut [f32],
    b: &'a mut [f32],
) -> &'a [f32] {
    run_layers_batch(layers, input, 1, a, b)
}

/// [`run_layers`] on `count` inputs at once (`inputs`: `count` rows of the first layer's
/// `n_in` values), with `a` and `b` as scratch of at least `count ×` the widest layer;
/// returns `count` rows of the last layer's outputs. Every output is [`dot8`] of its weight
/// row and its own input, so each row's values are those of [`run_layers`] on that input
/// alone, bit for bit. What batching buys: a weight row is read from memory once for all
/// `count` inputs and then stays in L1 (the lead ensemble's two models, 1.2 MB, do not fit
/// this machine's 1 MB L2 per core, so a hop at a time re-reads them from L3).
pub(crate) fn run_layers_batch<'a>(
    layers: &[Layer],
    inputs: &[f32],
    count: usize,
    a: &'a mut [f32],
    b: &'a mut [f32],
) -> &'a [f32] {
    let last = layers.len() - 1;
    let n0 = layers[0].n_in;
    a[..count * n0].copy_from_slice(&inputs[..count * n0]);
    let (mut src, mut dst) = (a, b);
    for (li, l) in layers.iter().enumerate() {
        let relu = li != last;
        if !super::simd::dense(l, src, count, dst, relu) {
            dense_portable(l, src, count, dst, relu);
        }
        std::mem::swap(&mut src, &mut dst);
    }
    let n = layers[last].n_out;
    &src[..count * n]
}

/// Layer `l` over `count` inputs as the portable build runs it (no AVX2): row by row, hop by
/// hop, each output one [`dot8`]; `dst[h·n_out + r]`, then `max(0)` when `relu`.
pub(crate) fn dense_portable(l: &Layer, src: &[f32], count: usize, dst: &mut [f32], relu: bool) {
    let (n_in, n_out) = (l.n_in, l.n_out);
    for (r, (row, &bias)) in l.w.chunks_exact(n_in).zip(&l.b).enumerate() {
        for h in 0..count {
            let s = dot8(row, &src[h * n_in..(h + 1) * n_in], bias);
            dst[h * n_out + r] = if relu { s.max(0.0) } else { s };
        }
    }
}
