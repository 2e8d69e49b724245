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
