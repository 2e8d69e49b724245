//! The one shape of the per-hop stages above the kernels: [`HopFilter`].
//!
//! The kernels turn samples into one value per hop ([`crate::HopStage`]: YIN, pYIN, flux,
//! RMS). What follows them works on those per-hop values: the gate
//! ([`StreamingGate`](crate::rms::StreamingGate)), the Tukey fences
//! ([`SlidingTukey`](crate::tukey::SlidingTukey)), the ranges
//! ([`RunningRange`](crate::discretize::RunningRange),
//! [`PriorRange`](crate::discretize::PriorRange)), the
//! [`Discretizer`](crate::discretize::Discretizer) and the binners
//! ([`Binner`](crate::binner::Binner)). They share this shape: a value per hop in, in hop
//! order; what it completes out through `emit`; `finish`, `reset`, and the latency it adds in
//! samples, so that a chain's latency adds up from its stages.
//!
//! The per-hop filters are causal and emit one value per hop at once (latency 0); a binner
//! emits a bin when its last hop arrives, so the first hop of a bin waits for the others:
//! `(⌈bin / hop⌉ − 1) · hop` samples at most.

/// A per-hop stage above the kernels. See the module docs.
pub trait HopFilter {
    /// What comes in per hop.
    type In;
    /// What goes out: one per hop, or one per bin for a binner.
    type Out;
    /// Feeds hop `hop_index` (in increasing order); calls `emit(index, value)` for every value
    /// it completes: `(hop_index, value)` for a per-hop filter, `(bin, value)` for a binner.
    fn push(&mut self, hop_index: usize, v: Self::In, emit: &mut dyn FnMut(usize, Self::Out));
    /// Ends the stream: emits what is held back (a binner's last, partial bin).
    fn finish(&mut self, emit: &mut dyn FnMut(usize, Self::Out)) {
        let _ = emit;
    }
    /// Back to the just-constructed state.
    fn reset(&mut self);
    /// How many samples after a hop arrives the last value that depends on it may be
    /// emitted.
    fn latency_samples(&self) -> usize;
}

/// One value per hop out, at once: the causal per-hop filters.
macro_rules! per_hop {
    ($($t:ty: $in:ty => $out:ty = $method:ident;)*) => {$(
        impl HopFilter for $t {
            type In = $in;
            type Out = $out;
            #[inline]
            fn push(&mut self, i: usize, v: $in, emit: &mut dyn FnMut(usize, $out)) {
                emit(i, self.$method(v))
            }
            fn reset(&mut self) {
                <$t>::reset(self)
            }
            fn latency_samples(&self) -> usize {
                0
            }
        }
    )*};
}

per_hop! {
    crate::rms::StreamingGate: f32 => bool = process;
    crate::tukey::SlidingTukey: f32 => f32 = process;
    crate::discretize::RunningRange: f32 => Option<(f32, f32)> = update;
    crate::discretize::PriorRange: f32 => Option<(f32, f32)> = update;
    crate::discretize::HeldRange: f32 => Option<(f32, f32)> = update;
}

/// A pitch and the range to place it in → its level (0 without a range).
impl HopFilter for crate::discretize::Discretizer {
    type In = (f32, Option<(f32, f32)>);
    type Out = u8;
    #[inline]
    fn push(&mut self, i: usize, (f0_hz, range): Self::In, emit: &mut dyn FnMut(usize, u8)) {
        emit(i, range.map_or(0, |r| self.level(f0_hz, r)))
    }
    /// Stateless: nothing to reset.
    fn reset(&mut self) {}
    fn latency_samples(&self) -> usize {
        0
    }
}
