//! The crate's `unsafe` code, with [`crate::nn`]'s AVX2 dense layer: the run-time check for
//! AVX2 ([`avx2`]) and [`viterbi_step`], which compiles the trackers' Viterbi steps, written
//! in plain Rust, for AVX2.
//!
//! # Safety
//! The `unsafe` is calling a `#[target_feature(enable = "avx2")]` function, done only after
//! `is_x86_feature_detected!("avx2")` said yes (which also checks that the OS saves the
//! 256-bit registers).

#![allow(unsafe_code)]

/// True when the AVX2 kernel can run here (cached by the standard library).
pub(crate) fn avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
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
}
