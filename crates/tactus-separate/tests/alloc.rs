//! No allocation in `process` / `finish` after construction, when the caller has reserved
//! the StemOutput capacity.
//!
//! The one use of `unsafe` in this crate is here, in a test binary: implementing
//! `GlobalAlloc` is an unsafe trait. The implementation only forwards to the system
//! allocator and counts calls on the current thread (a thread-local counter, so the test
//! harness's other threads do not interfere).
mod common;

use common::synthetic_mix;
use tactus_separate::none::NoneSeparator;
use tactus_separate::spectral::{SpectralConfig, SpectralSeparator};
use tactus_separate::{Separator, Stem, StemOutput, StemSet};

#[global_allocator]
static GLOBAL: tactus_testkit::Counting = tactus_testkit::Counting;

fn allocations() -> usize {
    tactus_testkit::allocations()
}

const SR: u32 = 44_100;

#[test]
fn process_and_finish_do_not_allocate() {
    let mix = synthetic_mix(SR, 1.5, 5);
    let n = mix.left.len();
    let sets = [
        StemSet::all(),
        StemSet::default().with(Stem::Bass),
        StemSet::default().with(Stem::Vocals),
    ];
    for set in sets {
        let mut seps: Vec<Box<dyn Separator>> = vec![
            Box::new(NoneSeparator::new(SR, set).unwrap()),
            Box::new(SpectralSeparator::new(SR, set, SpectralConfig::default()).unwrap()),
        ];
        for sep in seps.iter_mut() {
            let mut out = StemOutput::with_capacity(set, n);
            let before = allocations();
            let mut pos = 0;
            for (k, c) in [1usize, 7, 128, 513, 4096, 10_000]
                .iter()
                .cycle()
                .enumerate()
            {
                if pos >= n || k > 1000 {
                    break;
                }
                let end = (pos + c).min(n);
                sep.process(&mix.left[pos..end], &mix.right[pos..end], &mut out);
                pos = end;
            }
            sep.finish(&mut out);
            sep.reset();
            let used = allocations() - before;
            assert_eq!(out.get(set.iter().next().unwrap()).len(), n);
            assert_eq!(used, 0, "{} allocated {used} times", sep.name());
        }
    }
}

/// The counter works: without reserved capacity the output Vecs must grow.
#[test]
fn the_counter_sees_allocations() {
    let mix = synthetic_mix(SR, 0.2, 6);
    let mut sep = SpectralSeparator::new(SR, StemSet::all(), SpectralConfig::default()).unwrap();
    let mut out = StemOutput::new();
    let before = allocations();
    sep.process(&mix.left, &mix.right, &mut out);
    assert!(allocations() > before);
}
