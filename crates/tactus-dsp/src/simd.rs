//! The crate's `unsafe` code, with [`crate::nn`]'s AVX2 dense layer: the run-time check for
//! AVX2 ([`avx2`]), [`viterbi_step`], which compiles the trackers' Viterbi steps, written
//! in plain Rust, for AVX2, and [`relax`], the inner loop of those steps.
//!
//! # Safety
//! The `unsafe` is calling a `#[target_feature(enable = "avx2")]` function, done only after
//! `is_x86_feature_detected!("avx2")` said yes (which also checks that the OS saves the
//! 256-bit registers).

#![allow(unsafe_code)]

/// True when the AVX2 kernel can run here (cached by the standard library); always false in
/// a build with the `portable` feature.
pub(crate) fn avx2() -> bool {
    #[cfg(all(target_arch = "x86_64", not(feature = "portable")))]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(any(not(target_arch = "x86_64"), feature = "portable"))]
    {
        false
    }
}

/// True when the AVX-512 dense layer can run here ([`crate::nn`]; AVX-512F, cached by the
/// standard library); always false in a build with the `portable` or `avx2-only` feature.
pub(crate) fn avx512() -> bool {
    #[cfg(all(
        target_arch = "x86_64",
        not(feature = "portable"),
        not(feature = "avx2-only")
    ))]
    {
        std::arch::is_x86_feature_detected!("avx512f")
    }
    #[cfg(any(
        not(target_arch = "x86_64"),
        feature = "portable",
        feature = "avx2-only"
    ))]
    {
        false
    }
}

/// A tracker whose Viterbi step [`viterbi_step`] compiles for AVX2: `step` must be
/// `#[inline(always)]`, and so must what it calls, to be compiled inside the AVX2 frame.
pub(crate) trait ViterbiStep {
    /// One Viterbi step into backpointer slot `slot`, `l_unvoiced` the hop's unvoiced
    /// log-observation.
    fn step(&mut self, slot: usize, l_unvoiced: f32);
}

/// Runs `tracker`'s Viterbi step, compiled for AVX2 when the CPU has it (else as it is): its
/// select of the better predecessor becomes `vblendvps`, where SSE2 has no blend and stores
/// lane by lane. Only the instructions change, never the arithmetic: Rust does not contract
/// `a * b + c` into a fused multiply-add or reorder float operations, so the results are the
/// same bits on both paths (the step tests run both against their oracles).
#[inline(always)]
pub(crate) fn viterbi_step<T: ViterbiStep>(tracker: &mut T, slot: usize, l_unvoiced: f32) {
    #[cfg(target_arch = "x86_64")]
    {
        if avx2() {
            // SAFETY: the CPU has AVX2 (checked on the line above).
            return unsafe { x86::step_avx2(tracker, slot, l_unvoiced) };
        }
    }
    tracker.step(slot, l_unvoiced)
}

/// One offset of a Viterbi max: for every target `i`, when `src[i] + w > best[i]` (strictly;
/// false for NaN), `best[i] = src[i] + w` and `arg[i] = tag`. Over `min` of the three lengths.
///
/// The obvious loop compiles for AVX2 to a compare and a masked store (`vpmaskmovd`) of
/// `arg`, which AMD's cores run as microcode: that one instruction was most of the pYIN and
/// harmonic-sum Viterbi steps. The AVX2 path here blends both results in registers and
/// stores them whole; the same comparisons and sums, so the same bits
/// (`tests::relax_equals_the_obvious_loop`).
#[inline(always)]
pub(crate) fn relax(best: &mut [f32], arg: &mut [u32], src: &[f32], w: f32, tag: u32) {
    #[cfg(target_arch = "x86_64")]
    {
        if avx2() {
            // SAFETY: the CPU has AVX2 (checked on the line above).
            return unsafe { x86::relax_avx2(best, arg, src, w, tag) };
        }
    }
    relax_portable(best, arg, src, w, tag);
}

/// [`relax`] as plain Rust: a branch-free select per target.
#[inline(always)]
fn relax_portable(best: &mut [f32], arg: &mut [u32], src: &[f32], w: f32, tag: u32) {
    for ((b, a), &x) in best.iter_mut().zip(arg.iter_mut()).zip(src) {
        let v = x + w;
        let better = v > *b;
        let mask = (better as u32).wrapping_neg();
        *a = (tag & mask) | (*a & !mask);
        *b = if better { v } else { *b };
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    /// `tracker.step` in a frame compiled for AVX2, so that the step, inlined here, is too.
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn step_avx2<T: super::ViterbiStep>(
        tracker: &mut T,
        slot: usize,
        l_unvoiced: f32,
    ) {
        tracker.step(slot, l_unvoiced)
    }

    /// See [`super::relax`].
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) unsafe fn relax_avx2(
        best: &mut [f32],
        arg: &mut [u32],
        src: &[f32],
        w: f32,
        tag: u32,
    ) {
        use std::arch::x86_64::{
            _mm256_add_ps, _mm256_castps_si256, _mm256_castsi256_ps, _mm256_cmp_ps,
            _mm256_loadu_ps, _mm256_loadu_si256, _mm256_set1_epi32, _mm256_set1_ps,
            _mm256_storeu_ps, _mm256_storeu_si256, _CMP_GT_OQ,
        };
        let n = best.len().min(arg.len()).min(src.len());
        let (wv, tv) = (
            _mm256_set1_ps(w),
            _mm256_castsi256_ps(_mm256_set1_epi32(tag as i32)),
        );
        let mut i = 0;
        while i + 8 <= n {
            // SAFETY: `i + 8 ≤ n`, within all three slices.
            unsafe {
                let b = _mm256_loadu_ps(best.as_ptr().add(i));
                let v = _mm256_add_ps(_mm256_loadu_ps(src.as_ptr().add(i)), wv);
                // `v > b`, ordered: false when either is NaN, as Rust's `>`.
                let m = _mm256_cmp_ps::<_CMP_GT_OQ>(v, b);
                _mm256_storeu_ps(best.as_mut_ptr().add(i), blend(b, v, m));
                let a = _mm256_castsi256_ps(_mm256_loadu_si256(arg.as_ptr().add(i).cast()));
                let a = _mm256_castps_si256(blend(a, tv, m));
                _mm256_storeu_si256(arg.as_mut_ptr().add(i).cast(), a);
            }
            i += 8;
        }
        super::relax_portable(&mut best[i..n], &mut arg[i..n], &src[i..n], w, tag);
    }

    /// `vblendvps`: lane by lane `if m { y } else { x }` (by the mask's sign bit). Written
    /// as inline assembly because the compiler turns a blend of a loaded vector stored back
    /// to the same place into a masked store, the slow instruction [`super::relax`] avoids.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn blend(
        x: std::arch::x86_64::__m256,
        y: std::arch::x86_64::__m256,
        m: std::arch::x86_64::__m256,
    ) -> std::arch::x86_64::__m256 {
        let out;
        // SAFETY: a register-only instruction the CPU has (AVX2 implies AVX).
        unsafe {
            std::arch::asm!(
                "vblendvps {o}, {x}, {y}, {m}",
                o = lateout(ymm_reg) out,
                x = in(ymm_reg) x,
                y = in(ymm_reg) y,
                m = in(ymm_reg) m,
                options(pure, nomem, nostack, preserves_flags),
            );
        }
        out
    }
}

#[cfg(test)]
mod tests {
    /// The obvious loop, with branches.
    fn relax_by_hand(best: &mut [f32], arg: &mut [u32], src: &[f32], w: f32, tag: u32) {
        for i in 0..best.len().min(arg.len()).min(src.len()) {
            if src[i] + w > best[i] {
                best[i] = src[i] + w;
                arg[i] = tag;
            }
        }
    }

    #[test]
    fn relax_equals_the_obvious_loop() {
        let mut seed = 0x2545_f491u32;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed
        };
        // Small integers make exact ties common (a tie keeps the old tag); NaN, infinities
        // and -0.0 check the ordered comparison; lengths cover whole vectors and tails.
        let pick = |r: u32| match r % 11 {
            0 => f32::NAN,
            1 => f32::NEG_INFINITY,
            2 => f32::INFINITY,
            3 => -0.0,
            _ => (r % 7) as f32 - 3.0,
        };
        for n in 0..40 {
            for round in 0..20u32 {
                let best: Vec<f32> = (0..n).map(|_| pick(rnd())).collect();
                let src: Vec<f32> = (0..n).map(|_| pick(rnd())).collect();
                let arg: Vec<u32> = (0..n).map(|_| rnd()).collect();
                let w = [0.0, -1.0, -0.5, 2.0][round as usize % 4];
                let (mut b1, mut a1) = (best.clone(), arg.clone());
                let (mut b2, mut a2) = (best, arg);
                super::relax(&mut b1, &mut a1, &src, w, round);
                relax_by_hand(&mut b2, &mut a2, &src, w, round);
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&b1), bits(&b2), "n {n} round {round}");
                assert_eq!(a1, a2, "n {n} round {round}");
            }
        }
    }
}
