//! The one inner loop the embedded networks share ([`crate::drums`], [`crate::bassnet`]).

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

/// The first `n` bytes of `bytes`, which move past them; an error naming `what` when the
/// file ends first.
pub(crate) fn take<'a>(
    bytes: &mut &'a [u8],
    n: usize,
    what: &'static str,
) -> Result<&'a [u8], crate::ConfigError> {
    if bytes.len() < n {
        return Err(crate::ConfigError::invalid(what, "file is truncated"));
    }
    let (a, b) = bytes.split_at(n);
    *bytes = b;
    Ok(a)
}

/// A little-endian u32 (see [`take`]).
pub(crate) fn read_u32(bytes: &mut &[u8], what: &'static str) -> Result<u32, crate::ConfigError> {
    let a = take(bytes, 4, what)?;
    Ok(u32::from_le_bytes([a[0], a[1], a[2], a[3]]))
}

/// `n` little-endian f32, every one finite (see [`take`]).
pub(crate) fn read_f32s(
    bytes: &mut &[u8],
    n: usize,
    what: &'static str,
) -> Result<Vec<f32>, crate::ConfigError> {
    let len = n
        .checked_mul(4)
        .ok_or_else(|| crate::ConfigError::invalid(what, "layer too large"))?;
    let v: Vec<f32> = take(bytes, len, what)?
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    if v.iter().any(|x| !x.is_finite()) {
        return Err(crate::ConfigError::invalid(what, "non-finite value"));
    }
    Ok(v)
}

/// `n_layers` dense layers, each u32 `n_in, n_out`, f32 `w[n_out·n_in], b[n_out]`, the first
/// taking `n_in0` inputs and each the previous one's outputs (see [`take`]).
pub(crate) fn read_layers(
    bytes: &mut &[u8],
    n_layers: usize,
    n_in0: usize,
    what: &'static str,
) -> Result<Vec<crate::drums::Layer>, crate::ConfigError> {
    let mut layers = Vec::with_capacity(n_layers);
    let mut expect = n_in0;
    for _ in 0..n_layers {
        let n_in = read_u32(bytes, what)? as usize;
        let n_out = read_u32(bytes, what)? as usize;
        if n_in != expect || n_out == 0 || n_out > 4096 {
            return Err(crate::ConfigError::invalid(
                what,
                "layer shapes do not chain",
            ));
        }
        let w = read_f32s(bytes, n_in * n_out, what)?;
        let b = read_f32s(bytes, n_out, what)?;
        layers.push(crate::drums::Layer { n_in, n_out, w, b });
        expect = n_out;
    }
    Ok(layers)
}

/// Runs `layers` (ReLU between them, none after the last) on `input`, with `a` and `b` as
/// scratch at least as long as the widest layer; returns the last layer's outputs.
pub(crate) fn run_layers<'a>(
    layers: &[crate::drums::Layer],
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
    layers: &[crate::drums::Layer],
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
        if !crate::simd::dense(l, src, count, dst, relu) {
            dense_portable(l, src, count, dst, relu);
        }
        std::mem::swap(&mut src, &mut dst);
    }
    let n = layers[last].n_out;
    &src[..count * n]
}

/// Layer `l` over `count` inputs as the portable build runs it (no AVX2): row by row, hop by
/// hop, each output one [`dot8`]; `dst[h·n_out + r]`, then `max(0)` when `relu`.
pub(crate) fn dense_portable(
    l: &crate::drums::Layer,
    src: &[f32],
    count: usize,
    dst: &mut [f32],
    relu: bool,
) {
    let (n_in, n_out) = (l.n_in, l.n_out);
    for (r, (row, &bias)) in l.w.chunks_exact(n_in).zip(&l.b).enumerate() {
        for h in 0..count {
            let s = dot8(row, &src[h * n_in..(h + 1) * n_in], bias);
            dst[h * n_out + r] = if relu { s.max(0.0) } else { s };
        }
    }
}
