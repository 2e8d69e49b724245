//! The weight-file pieces shared by the drum and bass model files: bytes, little-endian
//! integers and floats, and a chain of dense layers, each read with an error that names the
//! file kind when it ends early or holds a non-finite value.

use super::layer::Layer;

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
) -> Result<Vec<Layer>, crate::ConfigError> {
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
        layers.push(Layer { n_in, n_out, w, b });
        expect = n_out;
    }
    Ok(layers)
}
