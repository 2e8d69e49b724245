//! One table of what each melodic stem gets: which pitch tracker, with which tuning, which
//! learned network, and how its levels and note onsets are read.
//!
//! The recipe of a stem is a pure function ([`recipe`]) of five things:
//!
//! * its [`Role`]: the bass line, the lead (the vocals stem), or the polyphonic rest;
//! * its [`Source`]: a clean stem (supplied with `--stem`, or from an ONNX separator) or a
//!   band of the mix (the spectral separator's stems, or the mix itself with no separator);
//! * the latency [`Profile`];
//! * the [`SeparatorKind`] that runs (the learned networks were trained on the spectral
//!   separator's stems, so only those get them);
//! * the user's [`PitchMethod`] (`--pitch`; [`PitchMethod::Auto`] unless named).
//!
//! [`Recipe`] is a plain value: the engine builds a stem's chain from it
//! ([`crate::track::PitchTrack::new`]), and `tests/recipe_table.rs` pins every combination.
//! Each tuning constant below states what it does and how it was chosen.

use tactus_dsp::Stem;

use crate::profile::{self, Profile};

mod display;
mod tuning;

use tuning::*;

/// Which pitch tracker a melodic track runs (`--pitch`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PitchMethod {
    /// Plain YIN, as in the paper.
    Yin,
    /// Probabilistic YIN with fixed-lag Viterbi tracking (fewer octave errors).
    Pyin,
    /// Harmonic-sum salience with fixed-lag Viterbi ([`tactus_dsp::shs`]), made for a bass
    /// line or a lead melody in a mixture.
    Shs,
    /// The learned salience ([`tactus_dsp::bassnet`]), made for the spectral separator's
    /// stems (the data it was trained on). On the bass: the bass model times the harmonic
    /// sum (blended as [`ShsTuning::learned_blend`] says), decoded like [`PitchMethod::Shs`]. On the lead (and any
    /// stem but the bass): a [`tactus_dsp::pair::VoicingPitchPair`] whose harmonic-sum
    /// tracker decides whether a hop is voiced (its own pitch,
    /// [`crate::track::PitchTrack::voicing_f0`], marks the hops the level range trusts) and
    /// whose lead-model tracker decides which pitch; note onsets read the pair's pitch.
    Learned,
    /// [`PitchMethod::Learned`] for the spectral separator's bass and lead (vocals) stems,
    /// [`PitchMethod::Shs`] for other basses and leads (supplied stems, other separators),
    /// pYIN for the polyphonic rest. In the live profile the live models for the spectral
    /// separator's bass and lead, plain YIN for every other stem.
    #[default]
    Auto,
    /// The default before the learned bass salience: [`PitchMethod::Shs`] for every bass and
    /// the lead, pYIN for the polyphonic rest; plain YIN in the live profile.
    AutoShs,
}

impl PitchMethod {
    /// Every method, in the order of the CLI's `--pitch` values (then `learned`).
    pub const ALL: [PitchMethod; 6] = [
        PitchMethod::Auto,
        PitchMethod::Yin,
        PitchMethod::Pyin,
        PitchMethod::Shs,
        PitchMethod::AutoShs,
        PitchMethod::Learned,
    ];

    /// Name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            PitchMethod::Yin => "yin",
            PitchMethod::Pyin => "pyin",
            PitchMethod::Shs => "shs",
            PitchMethod::Learned => "learned",
            PitchMethod::Auto => "auto",
            PitchMethod::AutoShs => "auto-shs",
        }
    }
}

/// The pitch tracker a driver runs when the user names none: [`PitchMethod::Auto`] (the
/// table then decides per stem), except for the live driver asked for the full profile
/// (`tactus live --profile full`), which gets pYIN: the harmonic-sum trackers' 200 ms
/// frames and the learned networks' context are the full profile's quality at a latency
/// the live glove cannot spend, while pYIN's lag is short.
pub fn default_pitch(live_driver: bool, profile: Profile) -> PitchMethod {
    if live_driver && profile == Profile::Full {
        PitchMethod::Pyin
    } else {
        PitchMethod::Auto
    }
}

/// What a melodic stem plays, for the choices that differ by instrument.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Role {
    /// The bass line (the bass stem): one low note at a time, plucked or held.
    Bass,
    /// The lead melody (the vocals stem): a voice or a lead instrument.
    Lead,
    /// The polyphonic rest (the other stem).
    Other,
}

impl Role {
    /// Every role.
    pub const ALL: [Role; 3] = [Role::Bass, Role::Lead, Role::Other];

    /// The role of a stem's pitch track; `None` for drums, which have none.
    pub fn of(stem: Stem) -> Option<Role> {
        match stem {
            Stem::Bass => Some(Role::Bass),
            Stem::Vocals => Some(Role::Lead),
            Stem::Other => Some(Role::Other),
            Stem::Drums => None,
        }
    }

    /// The stem that plays this role.
    pub fn stem(self) -> Stem {
        match self {
            Role::Bass => Stem::Bass,
            Role::Lead => Stem::Vocals,
            Role::Other => Stem::Other,
        }
    }

    /// Name used in the recipe table.
    pub fn name(self) -> &'static str {
        match self {
            Role::Bass => "bass",
            Role::Lead => "lead",
            Role::Other => "other",
        }
    }
}

/// What a stem's chain receives.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Source {
    /// The instrument on its own: a stem supplied with `--stem`, or an ONNX separator's.
    CleanStem,
    /// A band of the mix: the spectral separator's stem, or the mix itself when no separator
    /// runs. Chord tones, the kick and the other instruments share it.
    Mix,
}

impl Source {
    /// Both sources.
    pub const ALL: [Source; 2] = [Source::CleanStem, Source::Mix];

    /// The source of a stem that is `supplied` directly or comes from `separator`.
    pub fn of(supplied: bool, separator: SeparatorKind) -> Source {
        match (supplied, separator) {
            (false, SeparatorKind::Spectral | SeparatorKind::None) => Source::Mix,
            _ => Source::CleanStem,
        }
    }

    /// Name used in the recipe table.
    pub fn name(self) -> &'static str {
        match self {
            Source::CleanStem => "clean",
            Source::Mix => "mix",
        }
    }
}

/// Which kind of separator the engine runs (`--separator`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SeparatorKind {
    /// The embedded spectral separator: its stems are bands of the mix, and the learned
    /// networks were trained on them.
    Spectral,
    /// No separator: the mix feeds every stem chain.
    None,
    /// An ONNX network (htdemucs, Spleeter): its stems count as clean.
    Onnx,
}

impl SeparatorKind {
    /// Every kind.
    pub const ALL: [SeparatorKind; 3] = [
        SeparatorKind::Spectral,
        SeparatorKind::None,
        SeparatorKind::Onnx,
    ];

    /// Name used on the command line (`onnx` for htdemucs and spleeter).
    pub fn name(self) -> &'static str {
        match self {
            SeparatorKind::Spectral => "spectral",
            SeparatorKind::None => "none",
            SeparatorKind::Onnx => "onnx",
        }
    }
}

/// Everything that decides how one melodic stem becomes pitch levels and note onsets.
#[derive(Debug, Clone, PartialEq)]
pub struct Recipe {
    /// The pitch search range, Hz (the stem's; the live profile starts the bass at E1).
    pub range_hz: (f32, f32),
    /// The pitch tracker and its tuning.
    pub tracker: TrackerRecipe,
    /// Fixed Viterbi lag of pYIN and the harmonic-sum trackers, hops.
    pub lag_hops: usize,
    /// Whether the tracker's network reads the separator's harmonic sum (vocals + bass +
    /// other) beside the stem: the harmonic-view models ([`Network::BassHarmonic`],
    /// [`Network::LeadHarmonic`]).
    pub harmonic_view: bool,
    /// Hops the whole track is moved earlier: the spectral separator's stems lag their stated
    /// latency (3 hops on its bass and lead in the full profile,
    /// `docs/decisions/0012-spectral-pitch-tracks-30-ms-earlier.md`).
    pub advance_hops: usize,
    /// Whether YIN backs the tracker on plain tones ([`tactus_dsp::plain`]), and up to what
    /// f0 (Hz): a learned tracker's hop where the stem is a plain periodic tone between the
    /// range's floor and this ceiling takes YIN's estimate
    /// (docs/decisions/0051-plain-guard.md).
    pub plain_guard: Option<f32>,
    /// How the level range is chosen.
    pub levels: LevelRecipe,
    /// The note-onset rule's stem-specific parts.
    pub notes: NoteRole,
}

/// A pitch tracker and its tuning.
#[derive(Debug, Clone, PartialEq)]
pub enum TrackerRecipe {
    /// Plain YIN ([`tactus_dsp::yin`]); in the live profile over two frames when the range
    /// spans more than [`profile::TWO_FRAME_SPLIT`] ([`tactus_dsp::twoframe`]).
    Yin,
    /// pYIN ([`tactus_dsp::pyin`]).
    Pyin,
    /// One harmonic-sum tracker ([`tactus_dsp::shs::Shs`]), with or without a network.
    Shs(ShsTuning),
    /// A harmonic-sum tracker with the attack alignment (a clean lead): its decoded pitch is
    /// kept beside the aligned one for the note onsets.
    Aligned(ShsTuning),
    /// A learned harmonic-sum tracker whose network reads the harmonic view.
    View(ShsTuning),
    /// A voicing/pitch pair ([`tactus_dsp::pair::VoicingPitchPair`], with the veto): the
    /// `voicing` tracker decides whether a hop is voiced, the learned `pitch` tracker which
    /// pitch.
    Pair {
        /// The harmonic sum that decides voicing.
        voicing: ShsTuning,
        /// The learned tracker that decides pitch.
        pitch: ShsTuning,
    },
}

/// The settings of a harmonic-sum tracker that differ from its defaults
/// ([`tactus_dsp::shs::ShsConfig::new`] or [`tactus_dsp::shs::ShsConfig::melody`]). Zero
/// (or [`Network::None`]) leaves a setting off, as in the defaults.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ShsTuning {
    /// The melody defaults (a lead) rather than the bass defaults.
    pub melody: bool,
    /// Harmonics summed (`None`: the defaults' 6 for the bass, 8 for a melody).
    pub harmonics: Option<usize>,
    /// [`tactus_dsp::shs::ShsConfig::fundamental_ratio`].
    pub fundamental_ratio: f32,
    /// [`tactus_dsp::shs::ShsConfig::contour_gate_db`].
    pub contour_gate_db: f32,
    /// [`tactus_dsp::shs::ShsConfig::register_sigma_st`].
    pub register_sigma_st: f32,
    /// [`tactus_dsp::shs::ShsConfig::attack_rise_db`].
    pub attack_rise_db: f32,
    /// [`tactus_dsp::shs::ShsConfig::attack_salience_ratio`].
    pub attack_salience_ratio: f32,
    /// The learned network ([`tactus_dsp::shs::ShsConfig::learned`],
    /// [`tactus_dsp::shs::ShsConfig::learned_harmonic`],
    /// [`tactus_dsp::shs::ShsConfig::learned_ensemble`]).
    pub network: Network,
    /// [`tactus_dsp::shs::ShsConfig::learned_blend`].
    pub learned_blend: f32,
    /// [`tactus_dsp::shs::ShsConfig::learned_voicing_nats`].
    pub learned_voicing_nats: f32,
}

/// The learned salience network a harmonic-sum tracker runs (the weights embedded in
/// `tactus-dsp`, [`tactus_dsp::bassnet`]); the tracker's candidate grid picks the bass or
/// the lead model, these say which of them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Network {
    /// None: the harmonic sum alone.
    #[default]
    None,
    /// The bass model on the bass stem.
    Bass,
    /// The harmonic-view bass model: it reads the separator's harmonic sum (vocals + bass +
    /// other), the harmonic sum it is blended with still the bass stem. The bass stem keeps
    /// only what lies under the separator's 250 Hz crossover, so a note of 100–175 Hz reached
    /// the plain model as one partial and was read an octave low
    /// (`docs/decisions/0042-bass-reads-the-harmonic-sum.md`).
    BassHarmonic,
    /// The mean of the three lead models on the stem (the committed one, one trained with 80
    /// more sung songs, one with another seed on other songs;
    /// `docs/decisions/0031-lead-ensemble.md`,
    /// `docs/decisions/0033-third-lead-ensemble-member.md`).
    Lead,
    /// The mean of the three harmonic-view lead models (seeds 7, 11 and 13), reading the
    /// separator's harmonic sum (`docs/decisions/0037-learned-lead-reads-the-harmonic-sum.md`).
    LeadHarmonic,
    /// The live bass model: the live separator's harmonic sum on short frames, a past-only
    /// context (`docs/decisions/0057-learned-live-pitch.md`).
    BassLive,
    /// The live lead model, the same for the lead's grid.
    LeadLive,
}

impl Network {
    /// Whether the network reads the harmonic view.
    pub fn harmonic(self) -> bool {
        matches!(
            self,
            Network::BassHarmonic | Network::LeadHarmonic | Network::BassLive | Network::LeadLive
        )
    }

    /// Whether the network is one of the live profile's (short frames, no look-ahead).
    pub fn live(self) -> bool {
        matches!(self, Network::BassLive | Network::LeadLive)
    }

    /// Whether the network is an ensemble (the lead's).
    pub fn ensemble(self) -> bool {
        matches!(self, Network::Lead | Network::LeadHarmonic)
    }

    /// Name used in the recipe table.
    pub fn name(self) -> &'static str {
        match self {
            Network::None => "none",
            Network::Bass => "bass",
            Network::BassHarmonic => "bass-harmonic",
            Network::Lead => "lead",
            Network::LeadHarmonic => "lead-harmonic",
            Network::BassLive => "bass-live",
            Network::LeadLive => "lead-live",
        }
    }
}

/// How a pitch track's level range is chosen under [`crate::LevelRule::Follow`] (the paper's
/// rule reads none of it).
#[derive(Debug, Clone, PartialEq)]
pub struct LevelRecipe {
    /// IQR floor of the Tukey fences, semitones.
    pub min_iqr_st: f32,
    /// Quantile cut from each end of the kept hops' range.
    pub quantile: f32,
    /// Hops on each side a pitch must hold to count towards the range (0: every voiced hop).
    pub held_hops: usize,
    /// Semitones a held note's hops stay within.
    pub held_tol_st: f32,
    /// Below this share of held hops among the voiced ones every voiced hop sets the range.
    pub held_min_share: f32,
    /// The held range is used once it holds this many hops.
    pub held_min_hops: u64,
    /// Octave-shadow window, hops (0: off).
    pub shadow_hops: usize,
    /// A hop whose pitch the pair's voicing tracker agrees with within this many semitones
    /// counts as held (`None`: off).
    pub agree_tol_st: Option<f32>,
    /// The narrowing of the range to the hops the learned tracker is sure of (`None`: off).
    pub sure: Option<SureRule>,
    /// Span of the streaming range's prior, semitones.
    pub prior_span_st: f32,
    /// Voiced hops after which the span prior's padding has halved.
    pub prior_fade_hops: f32,
    /// The instrument's register, Hz, that the streaming range leans on instead of the span
    /// (`None`: the span).
    pub register_hz: Option<(f32, f32)>,
    /// Voiced hops after which the register prior's pull has halved.
    pub register_fade_hops: f32,
}

/// How a track's level range is narrowed to the hops its learned tracker is sure of
/// (`tactus_dsp::discretize::narrow_range`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SureRule {
    /// Confidence at which a hop is sure.
    pub min_conf: f32,
    /// Quantile cut of the sure hops' range.
    pub quantile: f32,
    /// Semitones the range may reach under the sure range (∞: that end is kept).
    pub below_st: f32,
    /// Semitones the range may reach over the sure range (∞: that end is kept).
    pub above_st: f32,
}

/// What the stem is, for the note-onset rule's stem-specific parts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct NoteRole {
    /// The bass of a mixture: a change of note must be attacked
    /// ([`tactus_dsp::notes::NoteConfig::pitch_needs_attack`]).
    pub plucked_mix: bool,
    /// The lead (vocals) on its own stem, not a band of a mixture: an onset at an attack
    /// moves back to the foot of its rise ([`tactus_dsp::notes::NoteConfig::backtrack_hops`],
    /// [`crate::notes`]) and a pitch onset without an attack moves back
    /// ([`tactus_dsp::notes::NoteConfig::pitch_back_hops`]): a sung syllable starts with its
    /// consonant before the vowel's rise, and a voice patch's release holds the old pitch
    /// into the new note.
    pub clean_lead: bool,
}

/// The recipe of a stem in `role` from `source`, in `profile`, with `separator` running
/// and the user's `pitch` choice. See the module docs.
pub fn recipe(
    role: Role,
    source: Source,
    profile: Profile,
    separator: SeparatorKind,
    pitch: PitchMethod,
) -> Recipe {
    let mix = source == Source::Mix;
    let bass = role == Role::Bass;
    let live = profile == Profile::Live;
    // The spectral separator's bands of the mix: what the learned networks were trained on.
    let spectral_mix = mix && separator == SeparatorKind::Spectral;
    let line = matches!(role, Role::Bass | Role::Lead);
    let method = match pitch {
        // The live profile: the spectral separator's bass and lead from the live models on
        // its harmonic sum (docs/decisions/0057-learned-live-pitch.md); every other stem from
        // plain YIN on short frames (pYIN's HMM needs more than its 2-hop lag to trust a new
        // note: 89 ms against 60 ms median in benches/live_latency.py; the harmonic-sum
        // tracker's 200 ms frames do not fit at all).
        PitchMethod::Auto if live && line && spectral_mix => PitchMethod::Learned,
        PitchMethod::Auto | PitchMethod::AutoShs if live => PitchMethod::Yin,
        // The spectral separator's bass: the learned salience times the harmonic sum
        // (trained on that stem); its lead: the harmonic sum decides whether, the learned
        // lead salience which pitch. Supplied stems and other separators: the harmonic sum.
        PitchMethod::Auto if line && spectral_mix => PitchMethod::Learned,
        PitchMethod::Auto | PitchMethod::AutoShs if line => PitchMethod::Shs,
        PitchMethod::Auto | PitchMethod::AutoShs => PitchMethod::Pyin,
        m => m,
    };
    let learned = method == PitchMethod::Learned;
    // The harmonic sum where `auto` chose it for a clean bass (a supplied stem, an ONNX
    // separator's): its lowest candidates share FFT bins, so a plain low tone comes out up
    // to a semitone off (docs/decisions/0061-plain-guard-beside-the-clean-bass.md).
    let auto_shs = bass
        && !mix
        && method == PitchMethod::Shs
        && matches!(pitch, PitchMethod::Auto | PitchMethod::AutoShs);
    // The spectral separator's lead and bass through the learned trackers: their networks
    // read the separator's harmonic sum.
    let harmonic_view = line && learned && spectral_mix;
    let tracker = match method {
        PitchMethod::Yin => TrackerRecipe::Yin,
        PitchMethod::Pyin | PitchMethod::Auto | PitchMethod::AutoShs => TrackerRecipe::Pyin,
        PitchMethod::Learned if live && harmonic_view => live_tracker(bass),
        PitchMethod::Shs | PitchMethod::Learned => shs_tracker(bass, mix, learned, harmonic_view),
    };
    Recipe {
        // A learned tracker searches its network's grid (the live bass's too: the live
        // profile's higher floor is for YIN's frame).
        range_hz: if learned {
            role.stem().pitch_range_hz()
        } else {
            profile::pitch_range_hz(profile, role.stem())
        }
        .unwrap_or_default(),
        levels: levels(
            role,
            mix,
            learned,
            matches!(tracker, TrackerRecipe::Pair { .. }),
        ),
        tracker,
        lag_hops: if live && learned && bass {
            profile::LIVE_BASS_LAG_HOPS
        } else if live && learned {
            profile::LIVE_LEAD_LAG_HOPS
        } else if live {
            profile::PITCH_LAG_HOPS
        } else {
            PYIN_LAG_HOPS
        },
        harmonic_view,
        // A learned network may not know a plain tone; YIN does. The spectral separator
        // sends a centred tone up to its vocal band's top to the lead, so the lead's guard
        // reaches the glove's highest pitch (the other stem's top): a whistle or a flute.
        plain_guard: (learned || auto_shs).then(|| {
            let top = |stem| profile::pitch_range_hz(profile, stem).map_or(0.0, |r| r.1);
            match role {
                Role::Lead => top(tactus_dsp::Stem::Other).max(top(role.stem())),
                _ => top(role.stem()),
            }
        }),
        // The spectral separator's stems lag their stated latency.
        advance_hops: if !live && line && spectral_mix {
            SPECTRAL_PITCH_ADVANCE_HOPS
        } else {
            0
        },
        notes: NoteRole {
            // A bass band of the mix: a change of note without an attack is mostly a chord
            // tone.
            plucked_mix: mix && bass,
            // A lead on its own stem: onsets at the foot of the attack, and pitch onsets a
            // little earlier.
            clean_lead: !mix && role == Role::Lead,
        },
    }
}

/// The live profile's learned tracker of a bass (or of a higher line) on a band of the
/// spectral separator's mix: the live model alone decides whether and which pitch, reading
/// the separator's harmonic sum (docs/decisions/0057-learned-live-pitch.md).
fn live_tracker(bass: bool) -> TrackerRecipe {
    TrackerRecipe::View(ShsTuning {
        melody: !bass,
        fundamental_ratio: MIXTURE_FUNDAMENTAL_RATIO,
        network: if bass {
            Network::BassLive
        } else {
            Network::LeadLive
        },
        learned_blend: 0.0,
        learned_voicing_nats: LIVE_VOICING_NATS,
        ..ShsTuning::default()
    })
}

/// The harmonic-sum tracker of a bass (or of a higher line), on a band of the `mix` or a
/// clean stem, with the `learned` network (reading the `harmonic_view`) or without.
fn shs_tracker(bass: bool, mix: bool, learned: bool, harmonic_view: bool) -> TrackerRecipe {
    // The bass range gets the bass defaults; a higher range (the lead) the melody defaults
    // (`tactus_dsp::shs` module docs).
    let mut t = ShsTuning {
        melody: !bass,
        ..ShsTuning::default()
    };
    if mix {
        t.fundamental_ratio = MIXTURE_FUNDAMENTAL_RATIO;
        if bass {
            t.register_sigma_st = MIXTURE_BASS_REGISTER_ST;
        } else {
            t.contour_gate_db = MIXTURE_MELODY_CONTOUR_GATE_DB;
        }
    } else if !bass {
        // A clean lead.
        t.harmonics = Some(CLEAN_LEAD_HARMONICS);
        t.attack_rise_db = CLEAN_LEAD_ATTACK_RISE_DB;
        t.attack_salience_ratio = CLEAN_LEAD_ATTACK_SALIENCE_RATIO;
    }
    match (bass, learned) {
        (true, true) => {
            t.network = if harmonic_view {
                Network::BassHarmonic
            } else {
                Network::Bass
            };
            t.learned_blend = LEARNED_BASS_BLEND;
            if harmonic_view {
                TrackerRecipe::View(t)
            } else {
                TrackerRecipe::Shs(t)
            }
        }
        // A higher line: the harmonic sum decides whether, the learned lead salience which
        // pitch (the network alone, without the harmonic sum's blend;
        // docs/decisions/0027-learned-lead-pitch-inside-harmonic-sum-voicing.md).
        (false, true) => TrackerRecipe::Pair {
            pitch: ShsTuning {
                network: if harmonic_view {
                    Network::LeadHarmonic
                } else {
                    Network::Lead
                },
                learned_voicing_nats: LEARNED_LEAD_VOICING_NATS,
                contour_gate_db: 0.0,
                ..t.clone()
            },
            voicing: t,
        },
        (false, false) if !mix => TrackerRecipe::Aligned(t),
        _ => TrackerRecipe::Shs(t),
    }
}

/// The level range of a stem in `role`, on a band of the `mix` or not, tracked by a
/// `learned` tracker or not, by a voicing/pitch `pair` or not.
fn levels(role: Role, mix: bool, learned: bool, pair: bool) -> LevelRecipe {
    let bass = role == Role::Bass;
    // A mixture's lead through the pair: from held notes or hops both trackers agree on,
    // narrowed to the hops where the learned tracker is sure of its pitch. A mixture's
    // learned lead alone (the live profile's) from held notes, narrowed the same way
    // (docs/decisions/0058-live-lead-levels-from-held-sure-notes.md).
    let agree = mix && pair;
    let held_lead = agree || (mix && role == Role::Lead && learned);
    LevelRecipe {
        // A bass line: 12, so the fences (k = 1.5) stay 18 semitones beyond the quartiles
        // and root–octave patterns survive; its octave errors are left to the percentile
        // range. A higher line: 4 (6 semitones), which still cuts a singer's octave errors.
        // Tuned on the chorale and drum corpora (tuned songs).
        min_iqr_st: if bass { 12.0 } else { 4.0 },
        quantile: FOLLOW_RANGE_QUANTILE,
        held_hops: match (bass, mix) {
            (true, false) => CLEAN_BASS_HELD_HOPS,
            (true, true) => MIX_BASS_HELD_HOPS,
            (false, _) if held_lead => MIX_LEAD_HELD_HOPS,
            (false, _) => 0,
        },
        held_tol_st: HELD_TOL_ST,
        held_min_share: HELD_MIN_SHARE,
        held_min_hops: HELD_MIN_HOPS,
        // The bass band of a mixture: the range without octave shadows.
        shadow_hops: if mix && bass { MIX_BASS_SHADOW_HOPS } else { 0 },
        agree_tol_st: agree.then_some(AGREE_TOL_ST),
        // Narrowed to the hops the learned tracker is sure of: both ends for the lead, the
        // bottom for the mix's learned bass.
        sure: if held_lead {
            Some(LEAD_SURE)
        } else if mix && bass && learned {
            Some(BASS_SURE)
        } else {
            None
        },
        // A bass line 20, a higher line 16 (tuned on the chorale corpus,
        // `benches/bass_eval.py`).
        prior_span_st: if bass { 20.0 } else { 16.0 },
        prior_fade_hops: FOLLOW_PRIOR_FADE_HOPS,
        // The bass and the lead lean on the instrument's register; the polyphonic rest keeps
        // the span prior.
        register_hz: match role {
            Role::Bass => Some(BASS_REGISTER_HZ),
            Role::Lead => Some(LEAD_REGISTER_HZ),
            Role::Other => None,
        },
        register_fade_hops: REGISTER_FADE_HOPS,
    }
}
