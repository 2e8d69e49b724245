//! Input hygiene: non-finite samples become 0 and are counted; values in the subnormal
//! range and below (|x| < 1e-30, i.e. below -600 dBFS) are flushed to 0 so that no later
//! stage is slowed down by denormal arithmetic.

/// Below this magnitude a sample is flushed to zero. -600 dBFS: far under any gate.
pub const FLUSH_BELOW: f32 = 1e-30;

/// Returns a finite, non-denormal version of `x` and whether `x` was non-finite.
#[inline]
pub fn sanitize_sample(x: f32) -> (f32, bool) {
    if !x.is_finite() {
        (0.0, true)
    } else if x.abs() < FLUSH_BELOW {
        (0.0, false)
    } else {
        (x, false)
    }
}

/// Sanitizes a block in place and returns how many samples were NaN or infinite.
pub fn sanitize(block: &mut [f32]) -> usize {
    let mut bad = 0;
    for x in block.iter_mut() {
        let (y, was_bad) = sanitize_sample(*x);
        *x = y;
        bad += was_bad as usize;
    }
    bad
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replaces_and_counts_non_finite() {
        let mut v = [
            1.0,
            f32::NAN,
            -8.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            1e-38,
            0.5,
        ];
        assert_eq!(sanitize(&mut v), 3);
        assert_eq!(v, [1.0, 0.0, -8.0, 0.0, 0.0, 0.0, 0.5]);
    }
}
