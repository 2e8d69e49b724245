//! The stage shapes: [`SampleStage`], [`HopStage`] and [`HopFilter`].
//!
//! * **Sample-domain** ([`SampleStage`]: filters, median): samples in, as many samples out.
//! * **Hop-domain** ([`HopStage`]: YIN, pYIN, flux, RMS, the mel bank, the harmonic sum, the
//!   drum transcriber): samples in, one value per hop out through `emit(hop_index, value)`.
//!   A stage that reads a second signal of the same span beside its input (the harmonic
//!   view of a learned tracker, a drum signal's backing) takes it as the side input of
//!   [`HopStage::process_with`]; [`HopStage::process`] is the same call without one. What a
//!   stage emits per hop is its `Out`: a stage that has two estimates per hop (a
//!   [`crate::shs::WithDecoded`], a [`crate::pair::WithVoicing`]) emits both as a pair.
//! * **Per-hop** ([`HopFilter`]): the stages above the kernels, one value per hop in.
//!
//! Every shape has `reset` and `latency_samples`; the hop-domain ones `finish` too.
//!
//! ## Per-hop filters
//!
//! The kernels turn samples into one value per hop ([`HopStage`]: YIN, pYIN, flux,
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

/// A stage that maps input samples one-to-one to output samples (filters, median).
pub trait SampleStage: Send {
    /// Processes `input` into `output[..input.len()]`: by default, copies it and calls
    /// [`SampleStage::process_inplace`].
    ///
    /// # Panics
    /// If `output` is shorter than `input`.
    fn process(&mut self, input: &[f32], output: &mut [f32]) {
        let output = &mut output[..input.len()];
        output.copy_from_slice(input);
        self.process_inplace(output);
    }
    /// Processes a block in place.
    fn process_inplace(&mut self, block: &mut [f32]);
    /// Back to the just-constructed state.
    fn reset(&mut self);
    /// Group delay in samples that the stage adds (0 for IIR filters by convention).
    fn latency_samples(&self) -> usize;
}

/// A stage that turns samples into one value per hop (YIN, pYIN, flux, RMS).
/// See the crate docs for the hop/time convention.
pub trait HopStage: Send {
    /// What the stage emits per hop.
    type Out: Copy;
    /// Feeds a block of any length; calls `emit(hop_index, value)` in hop order.
    fn process(&mut self, input: &[f32], emit: &mut dyn FnMut(usize, Self::Out));
    /// [`HopStage::process`] with a side input: another signal of the same span as `input`
    /// (as many samples, hop for hop the same instants) that the stage reads beside it,
    /// e.g. the harmonic view of a learned tracker or the backing of a drum signal. With
    /// `None` it is [`HopStage::process`]. A stage that reads no side input ignores it (the
    /// default); one that does reads at most `input.len()` samples of it. Feed a stream
    /// either always with a side input or never.
    fn process_with(
        &mut self,
        input: &[f32],
        side: Option<&[f32]>,
        emit: &mut dyn FnMut(usize, Self::Out),
    ) {
        let _ = side;
        self.process(input, emit);
    }
    /// Ends the stream: emits every remaining hop (`n.div_ceil(hop)` in all).
    fn finish(&mut self, emit: &mut dyn FnMut(usize, Self::Out));
    /// Back to the just-constructed state.
    fn reset(&mut self);
    /// How many input samples after the centre of hop `i` must arrive before hop `i` is emitted.
    fn latency_samples(&self) -> usize;
    /// Samples between hops.
    fn hop(&self) -> usize;
}

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
