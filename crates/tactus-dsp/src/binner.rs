//! Per-hop values into fixed time Bins (the paper, §2: "aligned to 100 ms bins and empty values
//! are set to zero").
//!
//! **Assignment.** Hop `i` (time `i·hop_samples`) belongs to Bin `⌊i·hop_samples / bin_samples⌋`,
//! in exact integer arithmetic (64-bit, 128-bit if a product overflows), so bins need not be a multiple of the hop
//! and no rounding drift accumulates. Bin `b` holds the hops `first(b) .. first(b + 1)` with
//! `first(b) = ⌈b·bin_samples / hop_samples⌉`; when the hop is longer than the bin, some bins hold
//! no hop at all and are emitted as 0 / `false`.
//!
//! **Level bins** ([`LevelBinner`]). A bin is voiced when *more than half* of its hops are voiced
//! (level > 0); its level is then the median of its voiced levels, the **lower** median for an
//! even count (the `⌊(v − 1)/2⌋`-th smallest of `v` values, so the result is always a level that
//! occurred). Otherwise the bin is 0. The median is read from a 256-entry histogram.
//!
//! **Beat bins** ([`BeatBinner`]). A bin is a beat when at least one of its hops is an onset.
//!
//! **Streaming.** `push(hop_index, value, emit)` takes hops in increasing order and calls
//! `emit(bin, value)` for every bin as soon as its last hop has arrived (no added latency), in
//! bin order, each bin exactly once. A bin with no hops is emitted when the first hop of a later
//! bin arrives. `finish(emit)` emits the last, possibly partial, bin (its majority is taken over
//! the hops that arrived); call `reset()` before reusing a finished binner.
//! * A **skipped** hop index counts as unvoiced / no onset (it still counts in its bin's total).
//! * A hop index lower than or equal to one already pushed is **ignored**.
//!
//! A stream of `n > 0` hops yields exactly `⌊(n − 1)·hop_samples / bin_samples⌋ + 1` bins.
//! Allocation-free after construction. The offline functions [`bin_levels`] and [`bin_beats`]
//! run the same code and allocate their output `Vec`.
//!
//! **Defaults.** 100 ms bins offline (paper), 25 ms live (docs/design.md); the caller passes both
//! sizes in samples (e.g. hop 441, bin 4410 at 44.1 kHz).

use crate::ConfigError;

/// Which bins are complete given the hop indices seen: the integer clock shared by both binners.
#[derive(Debug, Clone)]
struct BinClock {
    hop: u64,
    bin: u64,
    /// Bin currently being filled.
    cur_bin: usize,
    /// `first_hop(cur_bin + 1)`, cached so that most pushes need no division.
    boundary: usize,
    /// One past the highest hop index pushed.
    next_hop: usize,
}

/// `⌊a·m / d⌋` (or `⌈…⌉`), exact: `u64` while the product fits, else `u128`.
#[inline]
fn mul_div(a: usize, m: u64, d: u64, ceil: bool) -> usize {
    match (a as u64).checked_mul(m) {
        Some(p) if ceil => p.div_ceil(d) as usize,
        Some(p) => (p / d) as usize,
        None => {
            let p = a as u128 * u128::from(m);
            let d = u128::from(d);
            (if ceil { p.div_ceil(d) } else { p / d }) as usize
        }
    }
}

impl BinClock {
    fn new(hop_samples: usize, bin_samples: usize) -> Result<Self, ConfigError> {
        if hop_samples == 0 {
            return Err(ConfigError::invalid("hop_samples", "must be at least 1"));
        }
        if bin_samples == 0 {
            return Err(ConfigError::invalid("bin_samples", "must be at least 1"));
        }
        let mut c = BinClock {
            hop: hop_samples as u64,
            bin: bin_samples as u64,
            cur_bin: 0,
            boundary: 0,
            next_hop: 0,
        };
        c.reset();
        Ok(c)
    }

    /// The bin of hop `i`.
    #[inline]
    fn bin_of(&self, i: usize) -> usize {
        mul_div(i, self.hop, self.bin, false)
    }

    /// The first hop of bin `b`: `⌈b·bin / hop⌉`.
    #[inline]
    fn first_hop(&self, b: usize) -> usize {
        mul_div(b, self.bin, self.hop, true)
    }

    /// Hops in bin `b` (all of them, whether pushed, skipped or empty).
    #[inline]
    fn hops_in(&self, b: usize) -> usize {
        self.first_hop(b + 1) - self.first_hop(b)
    }

    /// Moves on to bin `b`.
    #[inline]
    fn enter(&mut self, b: usize) {
        self.cur_bin = b;
        self.boundary = self.first_hop(b + 1);
    }

    fn reset(&mut self) {
        self.enter(0);
        self.next_hop = 0;
    }
}

/// Accumulates one bin's hops; both binners differ only here.
pub trait BinAcc {
    /// A hop's value.
    type In: Copy;
    /// A bin's value.
    type Out: Copy;
    /// Adds one hop.
    fn add(&mut self, v: Self::In);
    /// The bin's value given its total hop count; then clears.
    fn take(&mut self, total_hops: usize) -> Self::Out;
}

/// Pushes one hop through the shared clock logic.
#[inline]
fn push_hop<A: BinAcc>(
    clock: &mut BinClock,
    acc: &mut A,
    i: usize,
    v: A::In,
    emit: &mut dyn FnMut(usize, A::Out),
) {
    if i < clock.next_hop {
        return;
    }
    if i >= clock.boundary {
        // Hop i lies in a later bin: close the current one and any (empty or skipped) between.
        let b = clock.bin_of(i);
        while clock.cur_bin < b {
            let total = clock.hops_in(clock.cur_bin);
            emit(clock.cur_bin, acc.take(total));
            clock.cur_bin += 1;
        }
        clock.enter(b);
    }
    acc.add(v);
    clock.next_hop = i + 1;
    if clock.next_hop == clock.boundary {
        let b = clock.cur_bin;
        emit(b, acc.take(clock.hops_in(b)));
        clock.enter(b + 1);
    }
}

#[inline]
fn finish_bins<A: BinAcc>(clock: &mut BinClock, acc: &mut A, emit: &mut dyn FnMut(usize, A::Out)) {
    let first = clock.first_hop(clock.cur_bin);
    if clock.next_hop > first {
        emit(clock.cur_bin, acc.take(clock.next_hop - first));
        clock.enter(clock.cur_bin + 1);
    }
}

/// A bin's pitch levels: the lower median of its voiced hops when most hops are voiced,
/// else 0.
#[derive(Debug, Clone)]
pub struct LevelAcc {
    hist: [u32; 256],
    voiced: usize,
    max_level: u8,
}

impl Default for LevelAcc {
    fn default() -> Self {
        LevelAcc {
            hist: [0; 256],
            voiced: 0,
            max_level: 0,
        }
    }
}

impl BinAcc for LevelAcc {
    type In = u8;
    type Out = u8;

    #[inline]
    fn add(&mut self, level: u8) {
        if level > 0 {
            self.hist[usize::from(level)] += 1;
            self.voiced += 1;
            self.max_level = self.max_level.max(level);
        }
    }

    fn take(&mut self, total_hops: usize) -> u8 {
        let mut out = 0;
        if self.voiced * 2 > total_hops {
            // Lower median: the k-th smallest voiced level, k = (v - 1) / 2 (0-based).
            let k = (self.voiced - 1) / 2;
            let mut seen = 0usize;
            for level in 1..=self.max_level {
                seen += self.hist[usize::from(level)] as usize;
                if seen > k {
                    out = level;
                    break;
                }
            }
        }
        self.hist[..=usize::from(self.max_level)].fill(0);
        self.voiced = 0;
        self.max_level = 0;
        out
    }
}

/// A bin's beat: whether any of its hops is an onset.
#[derive(Debug, Clone, Default)]
pub struct BeatAcc {
    any: bool,
}

impl BinAcc for BeatAcc {
    type In = bool;
    type Out = bool;

    #[inline]
    fn add(&mut self, onset: bool) {
        self.any |= onset;
    }

    fn take(&mut self, _total_hops: usize) -> bool {
        std::mem::take(&mut self.any)
    }
}

/// Values per hop into values per bin, on hop indices (see the module docs); `A` says how
/// one bin's hops become its value: [`LevelBinner`] and [`BeatBinner`].
#[derive(Debug, Clone)]
pub struct Binner<A> {
    clock: BinClock,
    acc: A,
}

/// Pitch levels per hop into levels per bin (median of voiced hops, majority voicing).
/// See the module docs.
pub type LevelBinner = Binner<LevelAcc>;

/// Onset flags per hop into beats per bin (a bin is a beat if any hop is an onset).
/// See the module docs.
pub type BeatBinner = Binner<BeatAcc>;

impl<A: BinAcc + Default> Binner<A> {
    /// Hops of `hop_samples`, bins of `bin_samples`. Errors when either is 0.
    pub fn new(hop_samples: usize, bin_samples: usize) -> Result<Self, ConfigError> {
        Ok(Binner {
            clock: BinClock::new(hop_samples, bin_samples)?,
            acc: A::default(),
        })
    }

    /// The bin hop `hop_index` belongs to.
    pub fn bin_of(&self, hop_index: usize) -> usize {
        self.clock.bin_of(hop_index)
    }

    /// Feeds hop `hop_index` with its value (a level, 0 = unvoiced; an onset flag); emits
    /// every bin it completes.
    pub fn push(&mut self, hop_index: usize, v: A::In, emit: &mut dyn FnMut(usize, A::Out)) {
        push_hop(&mut self.clock, &mut self.acc, hop_index, v, emit);
    }

    /// Emits the last, partial bin (if any hop of it arrived).
    pub fn finish(&mut self, emit: &mut dyn FnMut(usize, A::Out)) {
        finish_bins(&mut self.clock, &mut self.acc, emit);
    }

    /// Back to the just-constructed state.
    pub fn reset(&mut self) {
        self.clock.reset();
        self.acc.take(0);
    }
}

/// The binners in the hop-filter shape: a bin out when its last hop arrives.
impl<A: BinAcc + Default> crate::HopFilter for Binner<A> {
    type In = A::In;
    type Out = A::Out;
    fn push(&mut self, hop_index: usize, v: A::In, emit: &mut dyn FnMut(usize, A::Out)) {
        Binner::push(self, hop_index, v, emit)
    }
    fn finish(&mut self, emit: &mut dyn FnMut(usize, A::Out)) {
        Binner::finish(self, emit)
    }
    fn reset(&mut self) {
        Binner::reset(self)
    }
    /// The first hop of the longest bin waits for the others: `(⌈bin / hop⌉ − 1) · hop`.
    fn latency_samples(&self) -> usize {
        let (hop, bin) = (self.clock.hop, self.clock.bin);
        ((bin.div_ceil(hop) - 1) * hop) as usize
    }
}

impl<A: BinAcc + Default> Binner<A> {
    /// Offline: values per hop (hop `i` at `i·hop_samples`) into values per bin, with a
    /// fresh binner. Empty when `hops` is empty or a size is 0.
    pub fn bin_all(hops: &[A::In], hop_samples: usize, bin_samples: usize) -> Vec<A::Out> {
        let Ok(mut b) = Self::new(hop_samples, bin_samples) else {
            return Vec::new();
        };
        let mut out = Vec::new();
        let mut emit = |_: usize, v: A::Out| out.push(v);
        for (i, &v) in hops.iter().enumerate() {
            b.push(i, v, &mut emit);
        }
        b.finish(&mut emit);
        out
    }
}

/// Offline: levels per hop (hop `i` at `i·hop_samples`) into levels per bin. Returns an empty
/// `Vec` when `levels` is empty or a size is 0.
pub fn bin_levels(levels: &[u8], hop_samples: usize, bin_samples: usize) -> Vec<u8> {
    LevelBinner::bin_all(levels, hop_samples, bin_samples)
}

/// Offline: onset flags per hop into beats per bin. Returns an empty `Vec` when `onsets` is
/// empty or a size is 0.
pub fn bin_beats(onsets: &[bool], hop_samples: usize, bin_samples: usize) -> Vec<bool> {
    BeatBinner::bin_all(onsets, hop_samples, bin_samples)
}
