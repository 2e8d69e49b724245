//! The tuning constants of the recipe table: what each does and how it was chosen. The
//! evidence behind each is in the decision record it cites (`docs/decisions/`).

use super::SureRule;

/// Quantile cut from each end of the voiced pitch for [`crate::LevelRule::Follow`]'s range
/// (`docs/decisions/0003-levels-follow-the-line.md`).
pub(super) const FOLLOW_RANGE_QUANTILE: f32 = 0.01;

/// Voiced hops after which the streaming prior's padding has halved (30 s of voiced hops;
/// `docs/decisions/0016-streaming-range-from-running-percentiles.md`).
pub(super) const FOLLOW_PRIOR_FADE_HOPS: f32 = 3000.0;

/// `--levels-rule follow` on a clean bass stem (not a band of a mixture): the range comes
/// from hops inside held notes, this many hops on each side within [`HELD_TOL_ST`]
/// (`tactus_dsp::discretize::HeldRange`). Chosen on the tuning songs: 8 hops lost the short
/// lowest notes of a line (`docs/decisions/0019-clean-bass-range-from-held-notes.md`).
pub(super) const CLEAN_BASS_HELD_HOPS: usize = 5;

/// Semitones a held note's hops stay within ([`CLEAN_BASS_HELD_HOPS`]).
pub(super) const HELD_TOL_ST: f32 = 1.0;

/// `--levels-rule follow` on the bass band of a mixture (the spectral separator's bass):
/// a hop whose octave above sounds within this many hops on either side is left out of the
/// level range (`tactus_dsp::discretize::shadow_mask`). Chosen on the tuning mixes and 16
/// validation songs over 10 / 25 / 50 / 100 hops
/// (`docs/decisions/0026-mix-bass-range-without-octave-shadows.md`).
pub(super) const MIX_BASS_SHADOW_HOPS: usize = 25;

/// `--levels-rule follow` on a mixture's lead tracked by the pair (the spectral separator's
/// vocals): a hop counts towards the level range when it sits inside a held note, this many
/// hops on each side within [`HELD_TOL_ST`], or when the pair's voicing tracker agrees with
/// its pitch within [`AGREE_TOL_ST`] (`tactus_dsp::discretize::range_quantiles_kept_or`).
/// Chosen on the tuning mixes, 16 validation songs and a spent held-out set
/// (`docs/decisions/0029-mix-lead-range-from-held-or-agreed-hops.md`).
pub(super) const MIX_LEAD_HELD_HOPS: usize = 8;

/// Semitones within which the pair's two trackers agree ([`MIX_LEAD_HELD_HOPS`]).
pub(super) const AGREE_TOL_ST: f32 = 1.0;

/// A mixture's lead through the pair: the level range of the held or agreed hops is
/// narrowed to at most [`MIX_LEAD_SURE_MARGIN_ST`] beyond the range ([`MIX_LEAD_SURE_QUANTILE`])
/// of those of them where the learned tracker is sure of its pitch: its confidence (the
/// network's probability within ⅔ semitone of it, `tactus_dsp::shs` module docs, "Learned
/// salience") is at least this (`tactus_dsp::discretize::narrow_range`). Chosen on 204
/// tuning mixes and checked on 96 spent ones
/// (`docs/decisions/0038-mix-lead-range-narrowed-to-sure-hops.md`). Streaming narrows the
/// running range once the sure hops hold a range of their own
/// (`tactus_dsp::discretize::HeldRange::holds`;
/// `docs/decisions/0040-streaming-ranges-narrowed-to-sure-hops.md`).
pub(super) const MIX_LEAD_SURE: f32 = 0.7;

/// Quantile cut from each end of the sure hops' range ([`MIX_LEAD_SURE`]).
pub(super) const MIX_LEAD_SURE_QUANTILE: f32 = 0.02;

/// Semitones the lead's level range may reach beyond its sure hops' range ([`MIX_LEAD_SURE`]).
pub(super) const MIX_LEAD_SURE_MARGIN_ST: f32 = 1.0;

/// The bass band of a mixture under the learned bass salience: the bottom of the
/// level range (held notes without octave shadows, [`MIX_BASS_HELD_HOPS`]) is raised to at
/// most [`MIX_BASS_SURE_MARGIN_ST`] under the bottom ([`FOLLOW_RANGE_QUANTILE`]) of those of
/// its hops where the learned tracker's confidence in its pitch is at least this; the top is
/// left alone. The unsure hops under a bass line are mostly a kick's body or a chord's
/// subharmonic; its unsure high notes are real. Chosen on 204 tuning mixes and checked on 96
/// spent ones (`docs/decisions/0039-mix-bass-range-bottom-from-sure-hops.md`). Streaming as
/// [`MIX_LEAD_SURE`].
pub(super) const MIX_BASS_SURE: f32 = 0.95;

/// Semitones the mix bass's level range may reach under its sure hops' bottom
/// ([`MIX_BASS_SURE`]).
pub(super) const MIX_BASS_SURE_MARGIN_ST: f32 = 1.0;

/// [`MIX_LEAD_SURE`].
pub(super) const LEAD_SURE: SureRule = SureRule {
    min_conf: MIX_LEAD_SURE,
    quantile: MIX_LEAD_SURE_QUANTILE,
    below_st: MIX_LEAD_SURE_MARGIN_ST,
    above_st: MIX_LEAD_SURE_MARGIN_ST,
};

/// [`MIX_BASS_SURE`].
pub(super) const BASS_SURE: SureRule = SureRule {
    min_conf: MIX_BASS_SURE,
    quantile: FOLLOW_RANGE_QUANTILE,
    below_st: MIX_BASS_SURE_MARGIN_ST,
    above_st: f32::INFINITY,
};

/// `--levels-rule follow` on the bass band of a mixture: besides leaving out octave shadows
/// ([`MIX_BASS_SHADOW_HOPS`]), a hop counts toward the level range only inside a held note,
/// this many hops on each side within [`HELD_TOL_ST`]. Chosen over 3 / 5 / 8 hops and shadow
/// windows of 25 / 50 / 100 / 200 on the tuning mixes, the validation songs and the spent
/// held-out sets (`docs/decisions/0030-mix-bass-range-from-held-notes.md`).
pub(super) const MIX_BASS_HELD_HOPS: usize = 3;

/// Below this share of held hops among the voiced ones every voiced hop sets the range.
pub(super) const HELD_MIN_SHARE: f32 = 0.25;

/// The held range is used once it holds this many hops (3 s of held notes); before, every
/// voiced hop sets it. Chosen on the tuning songs' streaming rows (1 / 50 / 300 hops: chorale
/// bass levels ±1 0.927 / 0.932 / 0.941, 0.941 without the held range; sung and `timgm`
/// gain 0.033–0.037 with each).
pub(super) const HELD_MIN_HOPS: u64 = 300;

/// Register prior of the bass stem's streaming range
/// ([`tactus_dsp::discretize::RangePrior::Register`]), Hz: E1 (the lowest open string of a
/// four-string bass) to D4, the top of a bass line's usual compass. Chosen on the tuning
/// songs' isolated streaming rows (`benches/bass_eval.py`) over E1–G3, E1–C4, C1–C4, D1–C4;
/// it also lifts the tuning mixes' streaming levels, so the mix's bass band uses it too
/// (`docs/decisions/0022-streaming-levels-from-a-register-prior.md`).
pub(super) const BASS_REGISTER_HZ: (f32, f32) = (41.203, 293.66);

/// Register prior of the lead (vocals) stem's streaming range, Hz: A3 to G5, where sung
/// and played melodies mostly lie. Chosen like [`BASS_REGISTER_HZ`] (over G3–G5,
/// C4–G5, C4–C6).
pub(super) const LEAD_REGISTER_HZ: (f32, f32) = (220.0, 783.99);

/// Voiced hops after which a register prior's pull has halved (2 s of voiced hops): a short
/// song's line shows most of its compass within its first phrases. Chosen with the registers
/// (100 / 150 / 200 / 300 / 500 / 1000 hops).
pub(super) const REGISTER_FADE_HOPS: f32 = 200.0;

/// Fixed Viterbi lag of streaming pYIN, in hops (100 ms at 10 ms hops).
pub(super) const PYIN_LAG_HOPS: usize = 10;

/// [`tactus_dsp::shs::ShsConfig::fundamental_ratio`] for bass tracked on a mixture's low
/// band. Chosen on the drum corpus's `timgm` family and the tuned chorales (mix bass RPA
/// 0.758 → 0.769 and 0.835 → 0.836; 0.15–0.2 helped the drum corpus more but cost the
/// chorales' organ basses up to 0.04); off on clean stems, where it cost isolated `timgm`
/// bass 0.982 → 0.957 (weak fundamentals of low plucked notes pushed an octave up;
/// `docs/decisions/0007-bass-on-mixes-longer-median-and-fundamental.md`).
pub(super) const MIXTURE_FUNDAMENTAL_RATIO: f32 = 0.1;

/// [`tactus_dsp::shs::ShsConfig::register_sigma_st`] for bass tracked on a mixture's low
/// band: a bass line keeps to its register, while a kick's or a floor tom's body left in
/// the low band pulls single notes an octave or a fifth under it. Chosen on the tuning
/// songs' mixes (`benches/bass_eval.py --inputs mix`, offline; sung / chorales / `timgm`):
/// bass RPA 0.804 / 0.852 / 0.891 → 0.823 / 0.885 / 0.896 and levels ±1 0.638 / 0.823 /
/// 0.872 → 0.627 / 0.896 / 0.924 at σ = 12 (σ = 9: RPA 0.831 / 0.862 / 0.895; σ = 15:
/// 0.815 / 0.877 / 0.895; time constants of 5 and 30 s within 0.005 of 10 s). Off on clean
/// stems and for the lead (a lead's register prior cost `timgm` mix vocals RPA 0.717 →
/// 0.684; `docs/decisions/0021-bass-register-weighting-on-mixes.md`).
pub(super) const MIXTURE_BASS_REGISTER_ST: f32 = 12.0;

/// [`tactus_dsp::shs::ShsConfig::learned_voicing_nats`] of the learned lead salience's
/// tracker, whose voicing vetoes the harmonic sum's
/// ([`tactus_dsp::pair::VoicingPitchPair::with_veto`]). Chosen on the tuning mixes and the
/// validation songs over 0 / 2 / 3 / 4 / 6
/// (`docs/decisions/0028-learned-lead-voicing-veto.md`).
pub(super) const LEARNED_LEAD_VOICING_NATS: f32 = 3.0;
/// Bias against "no pitch" of the live profile's learned bass and lead trackers, nats
/// ([`tactus_dsp::shs::ShsConfig::learned_voicing_nats`]). Chosen on 20 tuning mixes
/// (the live models' 16 validation songs and the 4 even sung songs): 0 / 2 / 3 / 4 gave bass
/// RPA 0.643 / 0.717 / 0.721 / 0.721, lead RPA 0.728 / 0.811 / 0.821 / 0.824 with lead
/// voicing false alarms 0.136 / 0.285 / 0.395 / 0.511
/// (`docs/decisions/0057-learned-live-pitch.md`).
pub(super) const LIVE_VOICING_NATS: f32 = 2.0;

/// [`tactus_dsp::shs::ShsConfig::learned_blend`] of the learned bass salience: the weight
/// of the harmonic sum's observation log-probabilities added to the network's. Chosen on the
/// tuning halves' mixes (`benches/bass_eval.py --inputs mix`, offline, sung / chorales /
/// `timgm`): bass RPA 0.875 / 0.908 / 0.900 for the network alone, 0.895 / 0.930 / 0.925 at
/// 0.2, 0.901 / 0.939 / 0.933 at 0.3, 0.904 / 0.943 / 0.939 at 0.4 (sung levels ±1 0.677 →
/// 0.596), 0.906 / 0.945 / 0.947 at 0.6 (chorale note F 0.687 → 0.652;
/// `docs/decisions/0024-learned-bass-salience.md`). The lead's pitch tracker takes the
/// network alone: the harmonic sum's 0.3 gave the same RPA for another harmonic sum per hop.
pub(super) const LEARNED_BASS_BLEND: f32 = 0.3;

/// Contour voicing of the lead on a band of the mix
/// ([`tactus_dsp::shs::ShsConfig::contour_gate_db`]): a decoded contour more than this many
/// dB below the running mean level of the voiced hops is reported unvoiced (the chords that
/// the separator leaves in the vocals band while the lead rests). Chosen on the tuning halves
/// (`timgm`, the 4 tuning chorales, the even sung songs): 3 dB cost 0.01–0.02 RPA, 8 dB kept
/// most false alarms. Off on clean stems, where it only removed quiet sung notes (isolated
/// sung vocals RPA 0.926 → 0.898; `docs/decisions/0011-contour-voicing-for-the-mix-lead.md`).
pub(super) const MIXTURE_MELODY_CONTOUR_GATE_DB: f32 = 6.0;

/// Harmonics summed by the harmonic-sum tracker on a lead that comes as its own stem (the
/// melody defaults sum 8). With 8, a low voice's candidate (130 Hz: up to 1.04 kHz) sees less
/// of the spectrum than its octave or twelfth (up to 2.1 or 3.1 kHz, where the formants
/// are), and low male voices were tracked an octave or a twelfth up. Chosen on the tuning
/// halves: isolated vocals RPA sung / chorales / `timgm` 0.926 / 0.881 / 0.927 → 0.960 /
/// 0.881 / 0.927. Only harmonics below the melody's 5 kHz are summed, so a lead above about
/// 420 Hz is unchanged. A lead on a band of the mix keeps 8 (12 gave 0.543 / 0.749 / 0.717 →
/// 0.545 / 0.741 / 0.713 there; `docs/decisions/0025-twelve-harmonics-for-a-clean-lead.md`).
pub(super) const CLEAN_LEAD_HARMONICS: usize = 12;

/// The attack alignment of a lead that comes as its own stem (`tactus_dsp::shs` module
/// docs, step 9; [`tactus_dsp::shs::ShsConfig::attack_rise_db`]): a soundfont lead's or
/// choir's decoded note change moves back to the foot of the band level's rise that starts
/// the new note, within the Viterbi's lag. The levels and the pattern read the aligned pitch;
/// the note onsets read the decoded one ([`crate::track::PitchTrack::note_f0`]), since their
/// own attack search was tuned on it
/// (`docs/decisions/0035-clean-lead-note-changes-at-the-attack.md`).
pub(super) const CLEAN_LEAD_ATTACK_RISE_DB: f32 = 0.5;

/// The attack alignment of a clean lead also follows the new note's own salience
/// ([`tactus_dsp::shs::ShsConfig::attack_salience_ratio`]; `tactus_dsp::shs` module docs,
/// step 9): a cross-fade between two sung notes (a choir patch's slow attack over the old
/// note's release) does not raise the band level. Chosen over 0.1–1.0 on 204 tuning songs
/// (`docs/decisions/0041-clean-lead-note-changes-through-a-cross-fade.md`).
pub(super) const CLEAN_LEAD_ATTACK_SALIENCE_RATIO: f32 = 0.3;

/// How many hops a pitch track on the spectral separator's bass or vocals stem is moved
/// earlier ([`crate::track::PitchTrack::set_advance_hops`]): the separator's harmonic time
/// median spans more past frames than look-ahead ones (5 + 2, the bass 8 + 2, of 23 ms), so a
/// new note reaches these stems later than its stated latency says. Render profile only
/// (`docs/decisions/0012-spectral-pitch-tracks-30-ms-earlier.md`).
pub(super) const SPECTRAL_PITCH_ADVANCE_HOPS: usize = 3;
