//! # tactus-testkit: test support shared by the Tactus crates
//!
//! A dev-dependency only. It holds what every crate's tests used to copy:
//!
//! * [`Counting`], a global allocator that counts the allocations of the current thread, and
//!   [`allocations`] to read the count: the allocation guard behind every "no allocation in
//!   `process`" test. The count is per thread, so the harness's other threads do not
//!   interfere.
//! * [`Rng`], SplitMix64: seeded, reproducible test signals.
//! * [`skip`] and [`in_ci`]: a test whose stand-in (a tool, a runtime, a model) is missing
//!   prints `SKIPPED` on a developer's machine and fails under `CI=true`.
//!
//! ```
//! use tactus_testkit::{allocations, Rng};
//!
//! // In a test binary: #[global_allocator] static A: tactus_testkit::Counting = tactus_testkit::Counting;
//! let mut rng = Rng::new(7);
//! let x = rng.next_f32();
//! assert!((-1.0..1.0).contains(&x));
//! let before = allocations();
//! let y = x * 2.0; // no allocation
//! assert_eq!(allocations(), before);
//! # let _ = y;
//! ```
//!
//! `unsafe` appears once in the project's libraries, here: `GlobalAlloc` can only be
//! implemented with `unsafe impl`. The implementation forwards every call unchanged to
//! [`System`].
#![deny(unsafe_code)]
#![warn(missing_docs)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

/// A global allocator that counts allocations and reallocations per thread. Install it in
/// a test binary with `#[global_allocator] static A: Counting = Counting;`.
#[derive(Debug, Clone, Copy, Default)]
pub struct Counting;

// SAFETY: forwards every call unchanged to `System`, which upholds the GlobalAlloc
// contract; the counter is a const-initialised thread-local that never allocates.
#[allow(unsafe_code)]
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// Allocations (and reallocations) of the current thread so far, when [`Counting`] is the
/// global allocator (always 0 otherwise).
pub fn allocations() -> usize {
    ALLOCATIONS.with(|c| c.get())
}

/// Runs `f` and returns how many allocations the current thread made inside it.
pub fn allocations_during(f: impl FnOnce()) -> usize {
    let before = allocations();
    f();
    allocations() - before
}

/// SplitMix64: a tiny seeded generator for reproducible test signals.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    /// A generator with this seed.
    pub fn new(seed: u64) -> Rng {
        Rng(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`, 53 bits.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Standard normal (Box–Muller, one draw per two uniforms).
    pub fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }

    /// Uniform in `[-1, 1)`.
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
    }

    /// `n` samples of white noise, uniform in `[-1, 1)`.
    pub fn noise(&mut self, n: usize) -> Vec<f32> {
        (0..n).map(|_| self.next_f32()).collect()
    }
}

/// Whether this run is CI (`CI=true` or `CI=1`; `.ci/run` exports `CI=true`): then a missing
/// stand-in is a failure, not a skip.
pub fn in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true" || v == "1")
}

/// Skips the calling test (the caller returns) with a `SKIPPED` line on a developer's
/// machine; panics under `CI=true`, so a broken install step cannot leave a real stand-in
/// untested while CI is green. `what` says which test and what is missing (and how to get
/// it).
pub fn skip(what: &str) {
    if in_ci() {
        panic!("CI=true and a stand-in is missing, so this is a failure, not a skip: {what}");
    }
    eprintln!("SKIPPED {what}");
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reference SplitMix64 sequence for seed 0 (Vigna's `splitmix64.c`): the tests'
    /// seeded signals depend on every bit of it.
    #[test]
    fn rng_is_splitmix64() {
        let mut r = Rng::new(0);
        assert_eq!(r.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(r.next_u64(), 0x6E78_9E6A_A1B9_65F4);
        assert_eq!(r.next_u64(), 0x06C4_5D18_8009_454F);
    }

    #[test]
    fn skip_fails_only_in_ci() {
        // Runs in both settings: the answer must follow the environment.
        let outcome = std::panic::catch_unwind(|| skip("skip_fails_only_in_ci: a test of skip"));
        assert_eq!(outcome.is_err(), in_ci());
    }
}
