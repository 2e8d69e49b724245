//! Two pitch trackers over one stream: one decides *whether* a hop is voiced, the other
//! *which* pitch it has ([`VoicingPitchPair`]).
//!
//! Why: on a mixture's lead band a learned salience picks the lead's pitch better than the
//! harmonic sum (it knows a low voice whose fundamental the band lacks, and a chord tone
//! from the tune), but on a drum kit it has never heard it falls silent where the lead
//! plays (`docs/decisions/0027-learned-lead-pitch-inside-harmonic-sum-voicing.md`).
//! The pair keeps the voicing tracker's decisions and replaces its pitch by the pitch
//! tracker's wherever both are voiced.
//!
//! # Algorithm
//! Both trackers get the same input, a block at a time, and emit hop `i` in order. For each
//! hop: unvoiced when the voicing tracker says so (its estimate unchanged); otherwise the
//! voicing tracker's estimate with `f0_hz` and `aperiodicity` (how sure of that pitch) taken
//! from the pitch tracker when that one is voiced there, else its own. Both trackers must
//! have the same hop.
//!
//! **Veto** ([`VoicingPitchPair::with_veto`]). Where the pitch tracker is unvoiced the hop is
//! unvoiced too, in the merged estimate and in the voicing tracker's own as emitted by
//! [`WithVoicing`]: on a mixture's lead the harmonic sum keeps a pitch through the lead's
//! rests while the chords sound, and the learned lead salience knows a rest
//! (`docs/decisions/0028-learned-lead-voicing-veto.md`).
//!
//! **Two views** (the side input of [`HopStage::process_with`]). The pitch tracker may read
//! another signal of the same span than the voicing tracker: on the spectral separator's
//! lead the learned lead models read the separator's harmonic sum (vocals + bass + other),
//! which keeps what the lead band's masks take from the voice, while the harmonic sum still
//! decides voicing on the lead band (`docs/decisions/0037-learned-lead-reads-the-harmonic-sum.md`).
//!
//! # Latency
//! The larger of the two trackers' latencies: a hop leaves once both have decided it.
//! No allocation after construction: the input goes to the trackers [`BLOCK_HOPS`] hops at a
//! time, so the queue between them holds at most the latency difference plus that block.
//! (A block of several hops lets a learned tracker run its network on several hops at
//! once; a hop at a time would cost it about twice as much. Every hop still leaves in the
//! call that makes it ready, so the block adds no latency.)

use std::collections::VecDeque;

use crate::yin::PitchEstimate;
use crate::{ConfigError, HopStage};

/// Hops of input handed to both trackers at a time (module docs, "Latency").
pub const BLOCK_HOPS: usize = 32;

/// See the module docs.
pub struct VoicingPitchPair {
    voicing: Box<dyn HopStage<Out = PitchEstimate>>,
    pitch: Box<dyn HopStage<Out = PitchEstimate>>,
    a: VecDeque<(usize, PitchEstimate)>,
    b: VecDeque<(usize, PitchEstimate)>,
    /// [`VoicingPitchPair::with_veto`].
    veto: bool,
}

impl std::fmt::Debug for VoicingPitchPair {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VoicingPitchPair")
            .field("queued", &(self.a.len(), self.b.len()))
            .finish_non_exhaustive()
    }
}

impl VoicingPitchPair {
    /// The pair of `voicing` (decides whether) and `pitch` (decides which). Errors when
    /// their hops differ.
    pub fn new(
        voicing: Box<dyn HopStage<Out = PitchEstimate>>,
        pitch: Box<dyn HopStage<Out = PitchEstimate>>,
    ) -> Result<Self, ConfigError> {
        if voicing.hop() != pitch.hop() || voicing.hop() == 0 {
            return Err(ConfigError::invalid(
                "pitch",
                "the two trackers of a pair need the same, non-zero hop",
            ));
        }
        let lead = voicing.latency_samples().abs_diff(pitch.latency_samples());
        let cap = lead / voicing.hop() + BLOCK_HOPS + 8;
        Ok(VoicingPitchPair {
            voicing,
            pitch,
            a: VecDeque::with_capacity(cap),
            b: VecDeque::with_capacity(cap),
            veto: false,
        })
    }

    /// The pitch tracker may also veto voicing: a hop is voiced only where both trackers
    /// are (module docs, "Veto"); both estimates of a vetoed hop are unvoiced.
    pub fn with_veto(mut self) -> Self {
        self.veto = true;
        self
    }

    /// The merged estimate of one hop (module docs): where both are voiced, the pitch
    /// tracker's `f0_hz` and `aperiodicity` (how sure it is of that pitch; a learned tracker's
    /// confidence, [`crate::shs`] module docs, "Learned salience") with the voicing tracker's
    /// `voiced_prob`.
    pub fn merge(voicing: PitchEstimate, pitch: PitchEstimate) -> PitchEstimate {
        if voicing.is_voiced() && pitch.is_voiced() {
            PitchEstimate {
                f0_hz: pitch.f0_hz,
                aperiodicity: pitch.aperiodicity,
                voiced_prob: voicing.voiced_prob,
            }
        } else {
            voicing
        }
    }

    fn drain(&mut self, emit: &mut dyn FnMut(usize, PitchEstimate, PitchEstimate)) {
        while let (Some(&(i, va)), Some(&(_, vb))) = (self.a.front(), self.b.front()) {
            self.a.pop_front();
            self.b.pop_front();
            if self.veto && !vb.is_voiced() {
                let off = PitchEstimate { f0_hz: 0.0, ..va };
                emit(i, off, off);
            } else {
                emit(i, Self::merge(va, vb), va);
            }
        }
    }

    /// The pair emitting the voicing tracker's own estimate beside the merged one
    /// ([`WithVoicing`]).
    pub fn with_voicing(self) -> WithVoicing {
        WithVoicing(self)
    }

    /// Feeds a block, emitting per hop the merged estimate and the voicing tracker's own:
    /// `voicing_input` goes to the voicing tracker, `pitch_input` (default: the same; as
    /// many samples, hop for hop the same instants) to the pitch tracker (module docs, "Two
    /// views"). Extra samples of the longer input are not read.
    fn feed(
        &mut self,
        voicing_input: &[f32],
        pitch_input: Option<&[f32]>,
        emit: &mut dyn FnMut(usize, PitchEstimate, PitchEstimate),
    ) {
        let pitch_input = pitch_input.unwrap_or(voicing_input);
        let n = voicing_input.len().min(pitch_input.len());
        let step = self.voicing.hop() * BLOCK_HOPS;
        for (va, pb) in voicing_input[..n]
            .chunks(step)
            .zip(pitch_input[..n].chunks(step))
        {
            let (a, b) = (&mut self.a, &mut self.b);
            self.voicing.process(va, &mut |i, e| a.push_back((i, e)));
            self.pitch.process(pb, &mut |i, e| b.push_back((i, e)));
            self.drain(emit);
        }
    }

    /// Ends the stream, emitting both estimates per hop ([`VoicingPitchPair::feed`]).
    fn end(&mut self, emit: &mut dyn FnMut(usize, PitchEstimate, PitchEstimate)) {
        let (a, b) = (&mut self.a, &mut self.b);
        self.voicing.finish(&mut |i, e| a.push_back((i, e)));
        self.pitch.finish(&mut |i, e| b.push_back((i, e)));
        self.drain(emit);
        // Both emit every hop of the stream, so nothing is left; if one tracker did emit
        // fewer, the voicing tracker's own estimates end the stream.
        while let Some((i, e)) = self.a.pop_front() {
            emit(i, e, e);
        }
        self.b.clear();
    }
}

impl HopStage for VoicingPitchPair {
    type Out = PitchEstimate;

    fn process(&mut self, input: &[f32], emit: &mut dyn FnMut(usize, PitchEstimate)) {
        self.feed(input, None, &mut |i, e, _| emit(i, e));
    }

    /// The side input is what the pitch tracker reads instead of `input` (module docs, "Two
    /// views").
    fn process_with(
        &mut self,
        input: &[f32],
        side: Option<&[f32]>,
        emit: &mut dyn FnMut(usize, PitchEstimate),
    ) {
        self.feed(input, side, &mut |i, e, _| emit(i, e));
    }

    fn finish(&mut self, emit: &mut dyn FnMut(usize, PitchEstimate)) {
        self.end(&mut |i, e, _| emit(i, e));
    }

    fn reset(&mut self) {
        self.voicing.reset();
        self.pitch.reset();
        self.a.clear();
        self.b.clear();
    }

    fn latency_samples(&self) -> usize {
        self.voicing
            .latency_samples()
            .max(self.pitch.latency_samples())
    }

    fn hop(&self) -> usize {
        self.voicing.hop()
    }
}

/// A [`VoicingPitchPair`] that emits two estimates per hop, `(merged, voicing)`: the merged
/// one and the voicing tracker's own (for a consumer that wants both, e.g. note onsets from
/// the voicing tracker's pitch). The side input is the pitch tracker's, as for the pair.
#[derive(Debug)]
pub struct WithVoicing(VoicingPitchPair);

impl HopStage for WithVoicing {
    type Out = (PitchEstimate, PitchEstimate);

    fn process(&mut self, input: &[f32], emit: &mut dyn FnMut(usize, Self::Out)) {
        self.0.feed(input, None, &mut |i, e, v| emit(i, (e, v)));
    }

    fn process_with(
        &mut self,
        input: &[f32],
        side: Option<&[f32]>,
        emit: &mut dyn FnMut(usize, Self::Out),
    ) {
        self.0.feed(input, side, &mut |i, e, v| emit(i, (e, v)));
    }

    fn finish(&mut self, emit: &mut dyn FnMut(usize, Self::Out)) {
        self.0.end(&mut |i, e, v| emit(i, (e, v)));
    }

    fn reset(&mut self) {
        self.0.reset();
    }

    fn latency_samples(&self) -> usize {
        self.0.latency_samples()
    }

    fn hop(&self) -> usize {
        self.0.hop()
    }
}
