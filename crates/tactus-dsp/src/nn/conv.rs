//! The convolutional layers of a version-4 drum model file: a convolution over
//! (time × band) maps with ReLU and max-pooling, and the standardisation in front of them.

/// One convolution over (time × band) maps, "valid" in time and "same" (zero-padded by
/// `kb / 2` on each side) in band, then ReLU, then a max-pool of `pool_t × pool_b`
/// (incomplete windows at the end dropped).
#[derive(Clone, Debug, PartialEq)]
pub struct Conv {
    /// Output channels.
    pub c_out: usize,
    /// Input channels.
    pub c_in: usize,
    /// Kernel length in time (frames).
    pub kt: usize,
    /// Kernel width in band (odd).
    pub kb: usize,
    /// Pooling in time.
    pub pool_t: usize,
    /// Pooling in band.
    pub pool_b: usize,
    /// Weights `[c_out][c_in][kt][kb]`.
    pub w: Vec<f32>,
    /// Biases, `c_out`.
    pub b: Vec<f32>,
}

impl Conv {
    /// Output shape `(channels, frames, bands)` after pooling, for an input of
    /// `t × bands` per channel; `None` when the input is too short for the kernel or pool.
    pub fn out_shape(&self, t: usize, bands: usize) -> Option<(usize, usize, usize)> {
        let tc = t.checked_sub(self.kt - 1)?;
        let (to, bo) = (tc / self.pool_t, bands / self.pool_b);
        (to > 0 && bo > 0).then_some((self.c_out, to, bo))
    }

    /// Runs the layer on `x` (`c_in × t × bands`), using `tmp` (at least
    /// `c_out · (t - kt + 1) · bands`) for the maps before pooling; writes the pooled maps to
    /// `out`.
    pub fn run(&self, x: &[f32], t: usize, bands: usize, tmp: &mut [f32], out: &mut [f32]) {
        let tc = t + 1 - self.kt;
        let pad = self.kb / 2;
        let maps = &mut tmp[..self.c_out * tc * bands];
        for (o, map) in maps.chunks_exact_mut(tc * bands).enumerate() {
            map.fill(self.b[o]);
            for i in 0..self.c_in {
                let xi = &x[i * t * bands..(i + 1) * t * bands];
                for dt in 0..self.kt {
                    for db in 0..self.kb {
                        let w = self.w[((o * self.c_in + i) * self.kt + dt) * self.kb + db];
                        // Output band j reads input band j + db - pad, when inside.
                        let j0 = pad.saturating_sub(db);
                        let j1 = (bands + pad).saturating_sub(db).min(bands);
                        for tt in 0..tc {
                            let row = &mut map[tt * bands + j0..tt * bands + j1];
                            let src0 = (tt + dt) * bands + j0 + db - pad;
                            let src = &xi[src0..src0 + (j1 - j0)];
                            for (r, &v) in row.iter_mut().zip(src) {
                                *r += w * v;
                            }
                        }
                    }
                }
            }
        }
        let (_, to, bo) = self.out_shape(t, bands).expect("shape checked at load");
        for o in 0..self.c_out {
            let map = &maps[o * tc * bands..(o + 1) * tc * bands];
            for a in 0..to {
                for c in 0..bo {
                    let mut m = 0f32; // ReLU, then max: the max of 0 and the window
                    for pt in 0..self.pool_t {
                        let r = &map[(a * self.pool_t + pt) * bands + c * self.pool_b..];
                        for &v in &r[..self.pool_b] {
                            m = m.max(v);
                        }
                    }
                    out[(o * to + a) * bo + c] = m;
                }
            }
        }
    }
}

/// The convolutional part of a version-4 model: the input standardisation (not foldable
/// into weights shared across positions) and the layers.
#[derive(Clone, Debug, PartialEq)]
pub struct ConvNet {
    /// Training mean per input value (`window_len`).
    pub mean: Vec<f32>,
    /// Training standard deviation per input value.
    pub std: Vec<f32>,
    /// Layers, in order.
    pub layers: Vec<Conv>,
}
