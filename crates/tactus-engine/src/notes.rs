//! Note onsets of a melodic stem (cell 1 of the thumb, ring and pinky).
//!
//! * [`NoteTrack::Pitch`] (default when the stem has a pitch track): note onsets from the
//!   tracked pitch ([`tactus_dsp::notes`]): where voicing begins or the pitch settles on a new
//!   note; with [`NoteRule::Attack`] (the default) also where the stem's level attacks a held
//!   pitch, each onset at its attack. Reads the pitch track's note pitch after gate and
//!   fences (`PitchTrack::note_f0`: its f0, or for a clean lead the decoded pitch before the
//!   attack alignment) and its
//!   RMS per hop (`PitchTrack::level_db`, the same hops, advanced with the track), hop by hop
//!   in streaming mode and once at the end offline, so both modes see the same values.
//! * [`NoteTrack::Flux`]: spectral-flux onsets of the stem ([`OnsetTrack`]), the first
//!   implementation; used when a map asks for note onsets of a stem without its pitch.
//!
//! Measured on the chorale corpus (`benches/bass_eval.py`, tuned songs, isolated stems,
//! offline): bass note-onset F 0.40 with flux, 0.94 from pitch; merging the flux onsets that
//! lie more than 80 ms from every pitch onset (to catch repeated notes) added at most 0.02 F
//! there, so the pitch rule stood alone. Repeated notes on pop bass lines and sung leads
//! needed the level instead (held-out isolated bass note F 0.73 → 0.97 on the sung and drum
//! corpora; `docs/decisions/0004-note-onsets-from-the-pitch-track.md`,
//! `docs/decisions/0017-note-onsets-from-the-attack.md`).

use tactus_dsp::notes::{note_onsets_offline_guided, NoteConfig, NoteOnsets};
use tactus_dsp::ConfigError;

use crate::profile::Profile;
pub use crate::recipe::NoteRole;
use tactus_dsp::Stem;
use tactus_glove::BinFeatures;

use crate::track::{
    held, Beats, Feature, Geometry, Mode, OnsetTrack, PitchTrack, Track, TrackInput,
};

/// How note onsets are read from a pitch track. See the module docs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum NoteRule {
    /// The pitch alone (the first implementation): voicing begins or the pitch settles on a
    /// new note ([`NoteConfig::pitch_only`]).
    Pitch,
    /// The pitch and the stem's level: also re-attacks inside a held pitch, each onset
    /// moved back to its attack, a minimum interval, dropouts that resume the same note
    /// without an attack ignored ([`NoteConfig::default`]). The live profile keeps the
    /// pitch rule's latency: the attack search keeps or drops an onset but never moves it
    /// ([`NoteConfig::attack_move_hops`]).
    #[default]
    Attack,
    /// [`NoteRule::Attack`], but a change of note never needs an attack, also for the bass
    /// of a mixture (for legato bass lines: bowed, blown, synth).
    Legato,
}

/// [`NoteConfig::backtrack_hops`] of a clean lead
/// (`docs/decisions/0018-clean-lead-onsets-at-the-foot-of-the-attack.md`).
const CLEAN_LEAD_BACKTRACK_HOPS: usize = 3;

/// [`NoteConfig::pitch_back_hops`] of a clean lead (the same record).
const CLEAN_LEAD_PITCH_BACK_HOPS: usize = 2;

/// [`NoteConfig::reattack_min_hops`] of a clean lead: a re-attack of the held pitch at least
/// 250 ms after the previous onset (`docs/decisions/0036-clean-lead-reattack-interval.md`).
const CLEAN_LEAD_REATTACK_MIN_HOPS: usize = 25;

/// [`NoteConfig::guide_back_hops`] of a clean lead whose tracker reports an attack-aligned
/// pitch beside the decoded one (`PitchTrack::note_guide`): 0, off. At 5 (a pitch onset
/// without an attack moves back to where the aligned pitch already holds the new note, at
/// most 50 ms) it raised isolated lead note F on the tuning songs (mean +0.013) and the
/// Choir Aahs chorales of its held-out draw (+0.05–0.07 each), but the held-out mean only by
/// 0.006, under the 0.01 a default must gain there to be adopted.
const CLEAN_LEAD_GUIDE_BACK_HOPS: usize = 0;

impl NoteRule {
    /// The detector's configuration for `profile` and the stem's `role`. The clean lead's
    /// moves need the attack search (the full profile): they never reach before it, so
    /// the latency is unchanged.
    pub fn config(self, profile: Profile, role: NoteRole) -> NoteConfig {
        let lead = |c: NoteConfig| {
            if role.clean_lead {
                NoteConfig {
                    backtrack_hops: CLEAN_LEAD_BACKTRACK_HOPS,
                    pitch_back_hops: CLEAN_LEAD_PITCH_BACK_HOPS,
                    reattack_min_hops: CLEAN_LEAD_REATTACK_MIN_HOPS,
                    guide_back_hops: CLEAN_LEAD_GUIDE_BACK_HOPS,
                    ..c
                }
            } else {
                c
            }
        };
        match (self, profile) {
            (NoteRule::Pitch, _) => NoteConfig::pitch_only(),
            // Live: the attack search judges in place, so it adds no latency
            // (docs/decisions/0059-live-note-onsets-judge-attacks-in-place.md).
            (NoteRule::Attack | NoteRule::Legato, Profile::Live) => NoteConfig {
                pitch_needs_attack: self == NoteRule::Attack && role.plucked_mix,
                attack_move_hops: Some(0),
                ..NoteConfig::default()
            },
            (NoteRule::Attack, Profile::Full) => lead(NoteConfig {
                pitch_needs_attack: role.plucked_mix,
                ..NoteConfig::default()
            }),
            (NoteRule::Legato, Profile::Full) => lead(NoteConfig::default()),
        }
    }
}

/// Note onsets from the pitch track. See the module docs.
pub struct PitchNotes {
    det: NoteOnsets,
    cfg: NoteConfig,
    geo: Geometry,
    hop: usize,
    /// The pitch track's latency, before this detector's own.
    pitch_latency: usize,
    /// Pitch hops consumed so far (streaming).
    consumed: usize,
    /// Onset flag per pitch hop, note onset per bin.
    pub beats: Beats,
}

impl PitchNotes {
    /// A detector reading `pitch` (its hops and its latency; the track itself is handed to
    /// [`PitchNotes::update`] and [`PitchNotes::finish`]). `role`: see [`NoteRule::config`].
    pub fn new(
        geo: Geometry,
        pitch: &PitchTrack,
        rule: NoteRule,
        role: NoteRole,
    ) -> Result<Self, ConfigError> {
        let cfg = rule.config(geo.profile, role);
        let hop = pitch.hop();
        Ok(PitchNotes {
            det: NoteOnsets::new(cfg)?,
            cfg,
            geo,
            hop,
            pitch_latency: pitch.latency_samples(),
            consumed: 0,
            beats: Beats::new(hop, geo.bin_samples)?,
        })
    }

    /// Streaming: consumes the hops the pitch track has finished since the last call.
    pub fn update(&mut self, pitch: &PitchTrack) {
        if self.geo.mode != Mode::Streaming {
            return;
        }
        let (det, beats) = (&mut self.det, &mut self.beats);
        let f0 = pitch.note_f0();
        let guide = pitch.note_guide();
        for (k, &f) in f0.iter().enumerate().skip(self.consumed) {
            let l = pitch.level_db.get(k).copied().unwrap_or(f32::NAN);
            let g = guide.get(k).copied().unwrap_or(f32::NAN);
            det.push_guided(f, l, g, &mut |j, o| beats.push(j, o));
        }
        self.consumed = f0.len();
    }

    /// Ends the stream (offline: runs over the whole pitch track).
    pub fn finish(&mut self, pitch: &PitchTrack) {
        if self.geo.mode == Mode::Streaming {
            self.update(pitch);
            let beats = &mut self.beats;
            self.det.finish(&mut |j, o| beats.push(j, o));
            self.beats.finish();
        } else {
            // The config was validated in `new`, so this cannot fail; stay silent if it did.
            let f0 = pitch.note_f0();
            let onsets =
                note_onsets_offline_guided(f0, &pitch.level_db, pitch.note_guide(), self.cfg)
                    .unwrap_or_else(|_| vec![false; f0.len()]);
            self.beats
                .set_offline(onsets, self.hop, self.geo.bin_samples);
        }
    }

    /// Input samples of look-ahead: the pitch track's, then the detector's own.
    pub fn latency_samples(&self) -> usize {
        self.pitch_latency + self.own_latency_samples()
    }

    /// Input samples of look-ahead of the detector beyond the pitch track's.
    pub fn own_latency_samples(&self) -> usize {
        self.det.latency_hops() * self.hop
    }

    /// Onset times in seconds (streaming: those decided so far).
    pub fn onset_times(&self) -> Vec<f64> {
        crate::track::onset_times(&self.beats.onsets, self.hop, self.geo.sample_rate)
    }

    /// Per-hop and per-bin values held.
    pub fn retained(&self) -> usize {
        self.beats.retained()
    }

    /// Back to the initial state.
    pub fn reset(&mut self) {
        self.det.reset();
        self.consumed = 0;
        self.beats.reset();
    }
}

/// Where a melodic stem's note onsets come from. See the module docs.
#[allow(clippy::large_enum_variant)] // one per stem, built once
pub enum NoteTrack {
    /// From the stem's pitch track.
    Pitch(PitchNotes),
    /// Spectral flux of the stem.
    Flux(OnsetTrack),
}

impl NoteTrack {
    /// Note onset per bin.
    pub fn bins(&self) -> &[bool] {
        match self {
            NoteTrack::Pitch(p) => &p.beats.bins,
            NoteTrack::Flux(f) => &f.beats.bins,
        }
    }

    /// Onset times in seconds.
    pub fn onset_times(&self) -> Vec<f64> {
        match self {
            NoteTrack::Flux(f) => f.onset_times(),
            NoteTrack::Pitch(p) => p.onset_times(),
        }
    }
}

impl Track for NoteTrack {
    fn process(&mut self, input: &TrackInput<'_>) {
        match self {
            NoteTrack::Pitch(n) => {
                if let Some(p) = input.pitch {
                    n.update(p);
                }
            }
            NoteTrack::Flux(n) => n.process(input.stem),
        }
    }

    fn finish(&mut self, input: &TrackInput<'_>) {
        match self {
            NoteTrack::Pitch(n) => {
                if let Some(p) = input.pitch {
                    n.finish(p);
                }
            }
            NoteTrack::Flux(n) => n.finish(),
        }
    }

    fn reset(&mut self) {
        match self {
            NoteTrack::Pitch(p) => p.reset(),
            NoteTrack::Flux(f) => f.reset(),
        }
    }

    /// For [`NoteTrack::Pitch`] the pitch track's latency and the detector's own.
    fn latency_samples(&self) -> usize {
        match self {
            NoteTrack::Pitch(p) => p.latency_samples(),
            NoteTrack::Flux(f) => f.latency_samples(),
        }
    }

    /// The pitch track forgets its consumed hops at the same time, so a pitch detector
    /// counts them from 0 again.
    fn discard_before(&mut self, bins: usize) {
        match self {
            NoteTrack::Pitch(p) => {
                p.beats.discard(bins);
                p.consumed = 0;
            }
            NoteTrack::Flux(f) => f.discard(bins),
        }
    }

    fn feature(&self) -> Feature {
        Feature::Notes
    }

    fn ready_bins(&self) -> usize {
        self.bins().len()
    }

    fn read_bin(&self, bin: usize, hold: usize, stem: Stem, frame: &mut BinFeatures) {
        frame.note_onset[stem as usize] = held(self.bins(), bin, hold);
    }

    fn retained(&self) -> usize {
        match self {
            NoteTrack::Pitch(t) => t.retained(),
            NoteTrack::Flux(t) => t.retained(),
        }
    }
}
