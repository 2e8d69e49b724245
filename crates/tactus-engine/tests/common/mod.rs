//! Shared by the engine's integration tests.

use tactus_engine::profile::Profile;
use tactus_engine::track::Geometry;
use tactus_engine::{LevelRule, Mode};

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

/// The streaming level range of a mixture's bass as the engine builds it: a held range
/// (`MIX_BASS_HELD_HOPS`, the follow quantile) with `prior` fading over `fade` voiced hops
/// and the octave-shadow window `shadow`, for replaying the rule by hand.
/// (Not every test file uses it.)
#[allow(dead_code)]
pub fn mix_bass_held_range(
    prior: tactus_dsp::discretize::RangePrior,
    fade: f32,
    shadow: usize,
) -> tactus_dsp::discretize::HeldRange {
    use tactus_engine::track::{
        FOLLOW_RANGE_QUANTILE, HELD_MIN_HOPS, HELD_MIN_SHARE, HELD_TOL_ST, MIX_BASS_HELD_HOPS,
    };
    tactus_dsp::discretize::HeldRange::with_prior(
        prior,
        fade,
        FOLLOW_RANGE_QUANTILE,
        MIX_BASS_HELD_HOPS,
        HELD_TOL_ST,
        HELD_MIN_SHARE,
        HELD_MIN_HOPS,
    )
    .unwrap()
    .with_shadow(shadow)
    .unwrap()
}
