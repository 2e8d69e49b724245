//! The embedded networks' dense layer compiled for AVX2, chosen at run time when the CPU has
//! it ([`crate::simd::avx2`]); with [`crate::simd`], the crate's only `unsafe` code.
//!
//! # Why
//! A dense layer is a dot product per weight row ([`super::mlp::dot8`]): eight lanes, each
//! one dependent chain of adds, so a row at a time is bound by the adder's latency, not its
//! throughput, and the portable build (x86-64's SSE2 baseline) holds the eight lanes in two
//! registers. Here a tile of two rows meets four inputs at once
//! ([`super::mlp::run_layers_batch`]'s hops): eight independent chains, one 256-bit register
//! each; one load of a weight vector serves four inputs and one load of an input two rows.
//!
//! # Exactness
//! Lane `k` of an accumulator is `Σ_c w[8c + k] · x[8c + k]` in ascending `c`, each product
//! rounded and then added (`vmulps`, then `vaddps`: no fused multiply-add, which would round
//! once and change the bits). The lanes, the bias and the tail are then summed by the very
//! code of [`super::mlp::dot8`]. So every output equals the portable path's bit for bit,
//! which `tests::avx2_dense_equals_dot8_bit_for_bit` checks on awkward shapes, and the
//! pinned render outputs check end to end.
//!
//! # Safety
//! The `unsafe` is (1) calling a `#[target_feature(enable = "avx2")]` function, done only
//! after `is_x86_feature_detected!("avx2")` said yes (which also checks that the OS saves the
//! 256-bit registers), and (2) unaligned loads and stores through pointers derived from
//! slices whose lengths are checked by `assert!`s at the top of the kernel.

#![allow(unsafe_code)]

use super::layer::Layer;

/// Layer `l` over `count` inputs: `dst[h·n_out + r] = dot8(w[r], src[h], b[r])`, then
/// `max(0)` when `relu`, for `h < count`, `r < n_out`. Returns false (and does nothing)
/// when the CPU lacks AVX2; the caller then runs the portable loop.
pub(crate) fn dense(l: &Layer, src: &[f32], count: usize, dst: &mut [f32], relu: bool) -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        if crate::simd::avx512() {
            // SAFETY: the CPU has AVX-512F (checked on the line above).
            unsafe { x86_512::dense_avx512(l, src, count, dst, relu) };
            return true;
        }
        if crate::simd::avx2() {
            // SAFETY: the CPU has AVX2 (checked on the line above).
            unsafe { x86::dense_avx2(l, src, count, dst, relu) };
            return true;
        }
    }
    let _ = (l, src, count, dst, relu);
    false
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::{
        __m256, _mm256_add_ps, _mm256_loadu_ps, _mm256_mul_ps, _mm256_setzero_ps, _mm256_storeu_ps,
    };

    /// Inputs met by the weight rows of a tile.
    const HOPS: usize = 4;
    /// Weight rows of a tile: with [`HOPS`] inputs, eight accumulators, two weight registers
    /// and four input registers, fourteen of the sixteen `ymm` registers. Each weight load
    /// serves four inputs and each input load two rows, so the loop is bound by the
    /// multiplier and adder ports, not by loads or by one chain's latency.
    const ROWS: usize = 2;

    /// See [`super::dense`].
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn dense_avx2(
        l: &super::Layer,
        src: &[f32],
        count: usize,
        dst: &mut [f32],
        relu: bool,
    ) {
        let (w, b, n_in, n_out) = (&l.w[..], &l.b[..], l.n_in, l.n_out);
        // Every pointer below stays inside these lengths.
        assert!(w.len() >= n_out * n_in && b.len() >= n_out);
        assert!(src.len() >= count * n_in && dst.len() >= count * n_out);
        let chunks = n_in / 8;
        let split = chunks * 8;
        let mut r = 0;
        while r < n_out {
            let nr = (n_out - r).min(ROWS);
            let mut h = 0;
            while h < count {
                let k = (count - h).min(HOPS);
                let mut acc: [[__m256; HOPS]; ROWS] = [[_mm256_setzero_ps(); HOPS]; ROWS];
                if nr == ROWS && k == HOPS {
                    // A whole tile: fixed bounds, so the accumulators stay in registers.
                    // SAFETY: as in `tile`, with `nr = ROWS` rows and `k = HOPS` hops.
                    acc = unsafe { tile(w, src, n_in, r, h, chunks) };
                } else if nr == ROWS && k == 1 {
                    // One hop (a live block): two rows, two independent chains.
                    // SAFETY: as in `pair_one`, with `nr = ROWS` rows and one hop.
                    let [a0, a1] = unsafe { pair_one(w, src, n_in, r, h, chunks) };
                    acc[0][0] = a0;
                    acc[1][0] = a1;
                } else {
                    // The rest: a row at a time against up to four hops.
                    for (i, acc_row) in acc.iter_mut().enumerate().take(nr) {
                        let row = (r + i) * n_in;
                        for c in 0..chunks {
                            // SAFETY: `row + 8c + 8 ≤ row + split ≤ n_out·n_in ≤ w.len()`.
                            let wv = unsafe { _mm256_loadu_ps(w.as_ptr().add(row + 8 * c)) };
                            for (j, a) in acc_row.iter_mut().enumerate().take(k) {
                                // SAFETY: `(h + j)·n_in + 8c + 8 ≤ count·n_in ≤ src.len()`.
                                let xv = unsafe {
                                    _mm256_loadu_ps(src.as_ptr().add((h + j) * n_in + 8 * c))
                                };
                                *a = _mm256_add_ps(*a, _mm256_mul_ps(wv, xv));
                            }
                        }
                    }
                }
                for (i, acc_row) in acc.iter().enumerate().take(nr) {
                    let row = &w[(r + i) * n_in..(r + i + 1) * n_in];
                    let bias = b[r + i];
                    for (j, a) in acc_row.iter().enumerate().take(k) {
                        let mut lanes = [0f32; 8];
                        // SAFETY: `lanes` holds eight values.
                        unsafe { _mm256_storeu_ps(lanes.as_mut_ptr(), *a) };
                        let x = &src[(h + j) * n_in..(h + j + 1) * n_in];
                        // The same expression as `dot8`'s, so the same bits.
                        let mut s: f32 = lanes.iter().sum::<f32>() + bias;
                        for (wt, v) in row[split..].iter().zip(&x[split..]) {
                            s += wt * v;
                        }
                        dst[(h + j) * n_out + r + i] = if relu { s.max(0.0) } else { s };
                    }
                }
                h += k;
            }
            r += nr;
        }
    }

    /// The accumulators of rows `r`, `r + 1` of `w` against input `h` of `src` alone, summed
    /// as in [`tile`].
    ///
    /// # Safety
    /// As [`tile`], with `(h + 1)·n_in ≤ src.len()`.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn pair_one(
        w: &[f32],
        src: &[f32],
        n_in: usize,
        r: usize,
        h: usize,
        chunks: usize,
    ) -> [__m256; ROWS] {
        debug_assert!((r + ROWS) * n_in <= w.len() && (h + 1) * n_in <= src.len());
        let (w0, w1) = (w.as_ptr().add(r * n_in), w.as_ptr().add((r + 1) * n_in));
        let x0 = src.as_ptr().add(h * n_in);
        let (mut a0, mut a1) = (_mm256_setzero_ps(), _mm256_setzero_ps());
        for c in 0..chunks {
            let o = 8 * c;
            let v = _mm256_loadu_ps(x0.add(o));
            a0 = _mm256_add_ps(a0, _mm256_mul_ps(_mm256_loadu_ps(w0.add(o)), v));
            a1 = _mm256_add_ps(a1, _mm256_mul_ps(_mm256_loadu_ps(w1.add(o)), v));
        }
        [a0, a1]
    }

    /// The accumulators of a whole tile: rows `r`, `r + 1` of `w` against inputs `h..h + 4`
    /// of `src`, over the first `8·chunks` values, each lane summed in ascending chunk order
    /// (a product rounded, then added), exactly as the remainder loop in `dense_avx2` does.
    ///
    /// # Safety
    /// The CPU must have AVX2; `(r + 2)·n_in ≤ w.len()`, `(h + 4)·n_in ≤ src.len()` and
    /// `8·chunks ≤ n_in` (what `dense_avx2` asserts and iterates within).
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn tile(
        w: &[f32],
        src: &[f32],
        n_in: usize,
        r: usize,
        h: usize,
        chunks: usize,
    ) -> [[__m256; HOPS]; ROWS] {
        debug_assert!((r + ROWS) * n_in <= w.len() && (h + HOPS) * n_in <= src.len());
        let (w0, w1) = (w.as_ptr().add(r * n_in), w.as_ptr().add((r + 1) * n_in));
        let x0 = src.as_ptr().add(h * n_in);
        let (x1, x2, x3) = (x0.add(n_in), x0.add(2 * n_in), x0.add(3 * n_in));
        let z = _mm256_setzero_ps();
        let (mut a00, mut a01, mut a02, mut a03) = (z, z, z, z);
        let (mut a10, mut a11, mut a12, mut a13) = (z, z, z, z);
        for c in 0..chunks {
            let o = 8 * c;
            let (wa, wb) = (_mm256_loadu_ps(w0.add(o)), _mm256_loadu_ps(w1.add(o)));
            let v = _mm256_loadu_ps(x0.add(o));
            a00 = _mm256_add_ps(a00, _mm256_mul_ps(wa, v));
            a10 = _mm256_add_ps(a10, _mm256_mul_ps(wb, v));
            let v = _mm256_loadu_ps(x1.add(o));
            a01 = _mm256_add_ps(a01, _mm256_mul_ps(wa, v));
            a11 = _mm256_add_ps(a11, _mm256_mul_ps(wb, v));
            let v = _mm256_loadu_ps(x2.add(o));
            a02 = _mm256_add_ps(a02, _mm256_mul_ps(wa, v));
            a12 = _mm256_add_ps(a12, _mm256_mul_ps(wb, v));
            let v = _mm256_loadu_ps(x3.add(o));
            a03 = _mm256_add_ps(a03, _mm256_mul_ps(wa, v));
            a13 = _mm256_add_ps(a13, _mm256_mul_ps(wb, v));
        }
        [[a00, a01, a02, a03], [a10, a11, a12, a13]]
    }
}

#[cfg(target_arch = "x86_64")]
mod x86_512 {
    use std::arch::x86_64::{
        __m256, __m512, _mm256_add_ps, _mm256_castps_pd, _mm256_loadu_pd, _mm256_loadu_ps,
        _mm256_mul_ps, _mm256_setzero_ps, _mm256_storeu_ps, _mm512_add_ps, _mm512_broadcast_f64x4,
        _mm512_castpd_ps, _mm512_castps256_ps512, _mm512_castps_pd, _mm512_insertf64x4,
        _mm512_mul_ps, _mm512_setzero_ps, _mm512_storeu_ps,
    };

    /// Row pairs of a tile: eight rows, four weight registers.
    const PAIRS: usize = 4;
    /// Inputs a tile meets: with [`PAIRS`], sixteen accumulators, four weight registers and
    /// one input register, 21 of the 32 `zmm` registers; a weight register serves four
    /// inputs, an input register eight rows. A hop alone (a live block) still has four
    /// independent chains.
    const HOPS: usize = 4;

    /// See [`super::dense`]; the module docs, "AVX-512", say how the lanes are laid out.
    ///
    /// # Safety
    /// The CPU must have AVX-512F.
    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn dense_avx512(
        l: &super::Layer,
        src: &[f32],
        count: usize,
        dst: &mut [f32],
        relu: bool,
    ) {
        let (w, n_in, n_out) = (&l.w[..], l.n_in, l.n_out);
        // Every pointer below stays inside these lengths.
        assert!(w.len() >= n_out * n_in && l.b.len() >= n_out);
        assert!(src.len() >= count * n_in && dst.len() >= count * n_out);
        let chunks = n_in / 8;
        let mut r = 0;
        while r + 2 * PAIRS <= n_out {
            let mut h = 0;
            while h + HOPS <= count {
                // SAFETY: rows `r..r + 8` and inputs `h..h + 4` are in bounds (loop bounds).
                let acc = unsafe { tile::<PAIRS, HOPS>(w, src, n_in, r, h, chunks) };
                // SAFETY: the CPU has AVX-512F; the same bounds.
                unsafe { finish(l, src, dst, relu, r, h, &acc) };
                h += HOPS;
            }
            while h < count {
                // SAFETY: as above, one input.
                let acc = unsafe { tile::<PAIRS, 1>(w, src, n_in, r, h, chunks) };
                // SAFETY: as above.
                unsafe { finish(l, src, dst, relu, r, h, &acc) };
                h += 1;
            }
            r += 2 * PAIRS;
        }
        while r + 2 <= n_out {
            for h in 0..count {
                // SAFETY: rows `r..r + 2` and input `h` are in bounds (loop bounds).
                let acc = unsafe { tile::<1, 1>(w, src, n_in, r, h, chunks) };
                // SAFETY: as above.
                unsafe { finish(l, src, dst, relu, r, h, &acc) };
            }
            r += 2;
        }
        if r < n_out {
            // The last of an odd number of rows: one 256-bit chain per input.
            let row = &w[r * n_in..(r + 1) * n_in];
            for h in 0..count {
                let x = &src[h * n_in..(h + 1) * n_in];
                let mut a = _mm256_setzero_ps();
                for c in 0..chunks {
                    // SAFETY: `8c + 8 ≤ n_in`, the length of `row` and of `x`.
                    let (wv, xv) = unsafe {
                        (
                            _mm256_loadu_ps(row.as_ptr().add(8 * c)),
                            _mm256_loadu_ps(x.as_ptr().add(8 * c)),
                        )
                    };
                    a = _mm256_add_ps(a, _mm256_mul_ps(wv, xv));
                }
                let mut lanes = [0f32; 8];
                // SAFETY: `lanes` holds eight values.
                unsafe { _mm256_storeu_ps(lanes.as_mut_ptr(), a) };
                dst[h * n_out + r] = reduce(&lanes, row, x, l.b[r], chunks * 8, relu);
            }
        }
    }

    /// `dot8`'s last steps on a row's eight lane sums: the lanes in order, the bias, then the
    /// tail from `split` one by one (the same expression as [`super::super::mlp::dot8`]'s,
    /// so the same bits), then `max(0)` when `relu`.
    #[inline(always)]
    fn reduce(lanes: &[f32], row: &[f32], x: &[f32], bias: f32, split: usize, relu: bool) -> f32 {
        let mut s: f32 = lanes[..8].iter().sum::<f32>() + bias;
        for (wt, v) in row[split..].iter().zip(&x[split..]) {
            s += wt * v;
        }
        if relu {
            s.max(0.0)
        } else {
            s
        }
    }

    /// Writes the outputs of rows `r..r + 2P` for inputs `h..h + H` from a tile's
    /// accumulators (lanes 0–7 of `acc[p][j]` row `r + 2p`, lanes 8–15 row `r + 2p + 1`).
    ///
    /// # Safety
    /// The CPU must have AVX-512F.
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn finish<const P: usize, const H: usize>(
        l: &super::Layer,
        src: &[f32],
        dst: &mut [f32],
        relu: bool,
        r: usize,
        h: usize,
        acc: &[[__m512; H]; P],
    ) {
        let (n_in, n_out) = (l.n_in, l.n_out);
        let split = n_in / 8 * 8;
        for (p, acc_p) in acc.iter().enumerate() {
            for (j, a) in acc_p.iter().enumerate() {
                let mut lanes = [0f32; 16];
                // SAFETY: `lanes` holds sixteen values.
                unsafe { _mm512_storeu_ps(lanes.as_mut_ptr(), *a) };
                let x = &src[(h + j) * n_in..(h + j + 1) * n_in];
                for half in 0..2 {
                    let ri = r + 2 * p + half;
                    let row = &l.w[ri * n_in..(ri + 1) * n_in];
                    dst[(h + j) * n_out + ri] =
                        reduce(&lanes[8 * half..], row, x, l.b[ri], split, relu);
                }
            }
        }
    }

    /// The accumulators of rows `r..r + 2P` of `w` against inputs `h..h + H` of `src` over
    /// the first `8·chunks` values: `acc[p][j]` holds row `r + 2p` in lanes 0–7 and row
    /// `r + 2p + 1` in lanes 8–15, each lane summed in ascending chunk order, a product
    /// rounded and then added (no fused multiply-add), as `dot8` sums it.
    ///
    /// # Safety
    /// The CPU must have AVX-512F; `(r + 2P)·n_in ≤ w.len()`, `(h + H)·n_in ≤ src.len()` and
    /// `8·chunks ≤ n_in`.
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn tile<const P: usize, const H: usize>(
        w: &[f32],
        src: &[f32],
        n_in: usize,
        r: usize,
        h: usize,
        chunks: usize,
    ) -> [[__m512; H]; P] {
        debug_assert!((r + 2 * P) * n_in <= w.len() && (h + H) * n_in <= src.len());
        let wp = w.as_ptr().add(r * n_in);
        let xp = src.as_ptr().add(h * n_in);
        let mut acc = [[_mm512_setzero_ps(); H]; P];
        for c in 0..chunks {
            let o = 8 * c;
            let mut wv = [_mm512_setzero_ps(); P];
            for (p, v) in wv.iter_mut().enumerate() {
                let lo: __m256 = _mm256_loadu_ps(wp.add(2 * p * n_in + o));
                let hi = _mm256_loadu_pd(wp.add((2 * p + 1) * n_in + o).cast::<f64>());
                *v = _mm512_castpd_ps(_mm512_insertf64x4::<1>(
                    _mm512_castps_pd(_mm512_castps256_ps512(lo)),
                    hi,
                ));
            }
            for j in 0..H {
                // The input's eight values in both halves.
                let xv = _mm512_castpd_ps(_mm512_broadcast_f64x4(_mm256_castps_pd(
                    _mm256_loadu_ps(xp.add(j * n_in + o)),
                )));
                for (acc_p, &w_p) in acc.iter_mut().zip(&wv) {
                    acc_p[j] = _mm512_add_ps(acc_p[j], _mm512_mul_ps(w_p, xv));
                }
            }
        }
        acc
    }
}

#[cfg(test)]
mod tests {
    use crate::nn::layer::Layer;
    use crate::nn::mlp::dot8;

    #[test]
    fn wide_dense_equals_dot8_bit_for_bit() {
        if !crate::simd::avx2() {
            // Without AVX2 the kernel must decline, so that the portable loop runs.
            let l = Layer {
                n_in: 1,
                n_out: 1,
                w: vec![1.0],
                b: vec![0.0],
            };
            assert!(!super::dense(&l, &[1.0], 1, &mut [0.0], false));
            return;
        }
        let mut seed = 0x9e37_79b9u32;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            (seed as f32 / u32::MAX as f32) * 2.0 - 1.0
        };
        // Inputs a multiple of eight and not, one to seventeen hops (batches of four and their
        // remainders), values of mixed sign and scale so that the order of the adds shows.
        for (n_in, n_out) in [
            (864usize, 7usize),
            (13, 5),
            (8, 3),
            (5, 2),
            (129, 9),
            (216, 17),
            (16, 8),
            (7, 1),
        ] {
            for count in 1..=17 {
                let l = Layer {
                    n_in,
                    n_out,
                    w: (0..n_in * n_out)
                        .map(|i| rnd() * (1 + i % 7) as f32)
                        .collect(),
                    b: (0..n_out).map(|_| rnd()).collect(),
                };
                let x: Vec<f32> = (0..count * n_in)
                    .map(|i| rnd() * 1e3f32.powi((i % 3) as i32 - 1))
                    .collect();
                for relu in [false, true] {
                    let mut got = vec![f32::NAN; count * n_out];
                    assert!(super::dense(&l, &x, count, &mut got, relu));
                    // Each wide kernel on its own, whichever `dense` chose: the same bits.
                    #[cfg(target_arch = "x86_64")]
                    {
                        let mut avx2 = vec![f32::NAN; count * n_out];
                        // SAFETY: the CPU has AVX2 (checked at the top).
                        unsafe { super::x86::dense_avx2(&l, &x, count, &mut avx2, relu) };
                        for (i, (g, a)) in got.iter().zip(&avx2).enumerate() {
                            assert_eq!(g.to_bits(), a.to_bits(), "AVX2, output {i}");
                        }
                        if std::arch::is_x86_feature_detected!("avx512f") {
                            let mut wide = vec![f32::NAN; count * n_out];
                            // SAFETY: the CPU has AVX-512F (checked on the line above).
                            unsafe { super::x86_512::dense_avx512(&l, &x, count, &mut wide, relu) };
                            for (i, (g, a)) in got.iter().zip(&wide).enumerate() {
                                assert_eq!(g.to_bits(), a.to_bits(), "AVX-512, output {i}");
                            }
                        }
                    }
                    // The portable layer, which a CPU without AVX2 runs: the same bits.
                    let mut portable = vec![f32::NAN; count * n_out];
                    crate::nn::mlp::dense_portable(&l, &x, count, &mut portable, relu);
                    for (i, (g, p)) in got.iter().zip(&portable).enumerate() {
                        assert_eq!(g.to_bits(), p.to_bits(), "portable, output {i}");
                    }
                    for h in 0..count {
                        for r in 0..n_out {
                            let row = &l.w[r * n_in..(r + 1) * n_in];
                            let s = dot8(row, &x[h * n_in..(h + 1) * n_in], l.b[r]);
                            let want = if relu { s.max(0.0) } else { s };
                            assert_eq!(
                                got[h * n_out + r].to_bits(),
                                want.to_bits(),
                                "n_in {n_in} n_out {n_out} count {count} hop {h} row {r}"
                            );
                        }
                    }
                }
            }
        }
    }
}
