//! Shared by the engine's integration tests.

use tactus_engine::profile::Profile;
use tactus_engine::recipe::{recipe, LevelRecipe, Recipe, Role, SeparatorKind, Source};
use tactus_engine::track::{Geometry, PitchTrack};
use tactus_engine::{LevelRule, Mode, PitchMethod};

/// The engine rate of these tests.
pub const SR: u32 = 44_100;

/// A pitch track's geometry: 100 ms bins, 8 levels, the follow rule.
pub fn geo(mode: Mode, profile: Profile) -> Geometry {
    Geometry {
        sample_rate: SR,
        bin_samples: 4410,
        levels: 8,
        mode,
        level_rule: LevelRule::Follow,
        profile,
    }
}

/// The levels the default discretizer gives `f0` in `range` (0 unvoiced or without a range):
/// what a pitch track's `hop_levels` must equal once its range rule is replayed by hand.
/// (Not every test file uses it.)
#[allow(dead_code)]
pub fn levels(f0: &[f32], range: Option<(f32, f32)>) -> Vec<u8> {
    let d = tactus_dsp::discretize::Discretizer::default();
    f0.iter()
        .map(|&f| range.map_or(0, |r| d.level(f, r)))
        .collect()
}

/// The recipe of a `role` track searching `range_hz` with `method`, on a band of the mix
/// (`mixture`) or a clean stem, without the register prior and without the spectral
/// separator's own parts (harmonic view, advance): a tracker and level range to test on
/// their own. (Not every test file uses it.)
#[allow(dead_code)]
pub fn bare_recipe(
    role: Role,
    mixture: bool,
    profile: Profile,
    method: PitchMethod,
    range_hz: (f32, f32),
) -> Recipe {
    let source = if mixture {
        Source::Mix
    } else {
        Source::CleanStem
    };
    let mut r = recipe(role, source, profile, SeparatorKind::None, method);
    r.range_hz = range_hz;
    r.levels.register_hz = None;
    r
}

/// [`PitchTrack::new`] with [`bare_recipe`] in `geo`'s profile. (Not every test file uses it.)
#[allow(dead_code)]
pub fn pitch_track(
    geo: Geometry,
    role: Role,
    mixture: bool,
    method: PitchMethod,
    range_hz: (f32, f32),
) -> PitchTrack {
    PitchTrack::new(
        geo,
        &bare_recipe(role, mixture, geo.profile, method, range_hz),
    )
    .unwrap()
}

/// [`pitch_track`] without the plain guard (docs/decisions/0051-plain-guard.md): for tests
/// of a learned tracker on a synthetic line, which is a plain tone that YIN would take
/// where the tracker is silent. (Not every test file uses it.)
#[allow(dead_code)]
pub fn pitch_track_unguarded(
    geo: Geometry,
    role: Role,
    mixture: bool,
    method: PitchMethod,
    range_hz: (f32, f32),
) -> PitchTrack {
    let mut r = bare_recipe(role, mixture, geo.profile, method, range_hz);
    r.plain_guard = None;
    PitchTrack::new(geo, &r).unwrap()
}

/// The level recipe of a `role` track on a band of the mix (`mixture`) or a clean stem with
/// `method` (full profile), for replaying its range rule by hand. (Not every test file uses
/// it.)
#[allow(dead_code)]
pub fn levels_of(role: Role, mixture: bool, method: PitchMethod) -> LevelRecipe {
    bare_recipe(role, mixture, Profile::Full, method, (35.0, 400.0)).levels
}

/// A held range as `levels` builds it: with `prior` fading over `fade` voiced hops and the
/// octave-shadow window `shadow`, for replaying the rule by hand.
#[allow(dead_code)]
pub fn held_range(
    levels: &LevelRecipe,
    quantile: f32,
    prior: tactus_dsp::discretize::RangePrior,
    fade: f32,
    shadow: usize,
) -> tactus_dsp::discretize::HeldRange {
    tactus_dsp::discretize::HeldRange::with_prior(
        prior,
        fade,
        quantile,
        levels.held_hops,
        levels.held_tol_st,
        levels.held_min_share,
        levels.held_min_hops,
    )
    .unwrap()
    .with_shadow(shadow)
    .unwrap()
}

/// The streaming level range of a mixture's bass as the engine builds it: a held range
/// (the mix bass's held hops, the follow quantile) with `prior` fading over `fade` voiced
/// hops and the octave-shadow window `shadow`, for replaying the rule by hand.
/// (Not every test file uses it.)
#[allow(dead_code)]
pub fn mix_bass_held_range(
    prior: tactus_dsp::discretize::RangePrior,
    fade: f32,
    shadow: usize,
) -> tactus_dsp::discretize::HeldRange {
    let l = levels_of(Role::Bass, true, PitchMethod::Shs);
    held_range(&l, l.quantile, prior, fade, shadow)
}

/// The engine's tuning values that the tests replay by hand, read from the recipe table.
#[allow(dead_code)]
pub struct Tuning {
    pub follow_range_quantile: f32,
    pub follow_prior_fade_hops: f32,
    pub clean_bass_held_hops: usize,
    pub held_tol_st: f32,
    pub mix_bass_shadow_hops: usize,
    pub mix_lead_held_hops: usize,
    pub agree_tol_st: f32,
    pub mix_lead_sure: f32,
    pub mix_lead_sure_quantile: f32,
    pub mix_lead_sure_margin_st: f32,
    pub mix_bass_sure: f32,
    pub mix_bass_sure_margin_st: f32,
    pub mix_bass_held_hops: usize,
    pub held_min_share: f32,
    pub held_min_hops: u64,
    pub bass_register_hz: (f32, f32),
    pub lead_register_hz: (f32, f32),
    pub register_fade_hops: f32,
    pub bass_prior_span_st: f32,
    pub lead_prior_span_st: f32,
    pub clean_lead_harmonics: usize,
    pub clean_lead_attack_rise_db: f32,
    pub spectral_pitch_advance_hops: usize,
}

/// [`Tuning`] from the recipes of the full profile, read once per test binary.
#[allow(dead_code)]
pub fn tuning() -> &'static Tuning {
    static TUNING: std::sync::OnceLock<Tuning> = std::sync::OnceLock::new();
    TUNING.get_or_init(read_tuning)
}

fn read_tuning() -> Tuning {
    use tactus_engine::recipe::TrackerRecipe;
    let full = |role, source, sep, method| recipe(role, source, Profile::Full, sep, method);
    let mix_bass = full(
        Role::Bass,
        Source::Mix,
        SeparatorKind::None,
        PitchMethod::Shs,
    )
    .levels;
    let clean_bass = full(
        Role::Bass,
        Source::CleanStem,
        SeparatorKind::None,
        PitchMethod::Shs,
    );
    let mix_lead = full(
        Role::Lead,
        Source::Mix,
        SeparatorKind::None,
        PitchMethod::Learned,
    );
    let bass_sure = full(
        Role::Bass,
        Source::Mix,
        SeparatorKind::None,
        PitchMethod::Learned,
    )
    .levels
    .sure
    .unwrap();
    let lead_sure = mix_lead.levels.sure.unwrap();
    let clean_lead = match full(
        Role::Lead,
        Source::CleanStem,
        SeparatorKind::None,
        PitchMethod::Shs,
    )
    .tracker
    {
        TrackerRecipe::Aligned(t) => t,
        t => panic!("a clean lead's tracker is aligned: {t}"),
    };
    let spectral = full(
        Role::Lead,
        Source::Mix,
        SeparatorKind::Spectral,
        PitchMethod::Auto,
    );
    Tuning {
        follow_range_quantile: mix_bass.quantile,
        follow_prior_fade_hops: mix_bass.prior_fade_hops,
        clean_bass_held_hops: clean_bass.levels.held_hops,
        held_tol_st: mix_bass.held_tol_st,
        mix_bass_shadow_hops: mix_bass.shadow_hops,
        mix_lead_held_hops: mix_lead.levels.held_hops,
        agree_tol_st: mix_lead.levels.agree_tol_st.unwrap(),
        mix_lead_sure: lead_sure.min_conf,
        mix_lead_sure_quantile: lead_sure.quantile,
        mix_lead_sure_margin_st: lead_sure.below_st,
        mix_bass_sure: bass_sure.min_conf,
        mix_bass_sure_margin_st: bass_sure.below_st,
        mix_bass_held_hops: mix_bass.held_hops,
        held_min_share: mix_bass.held_min_share,
        held_min_hops: mix_bass.held_min_hops,
        bass_register_hz: mix_bass.register_hz.unwrap(),
        lead_register_hz: mix_lead.levels.register_hz.unwrap(),
        register_fade_hops: mix_bass.register_fade_hops,
        bass_prior_span_st: mix_bass.prior_span_st,
        lead_prior_span_st: mix_lead.levels.prior_span_st,
        clean_lead_harmonics: clean_lead.harmonics.unwrap(),
        clean_lead_attack_rise_db: clean_lead.attack_rise_db,
        spectral_pitch_advance_hops: spectral.advance_hops,
    }
}
