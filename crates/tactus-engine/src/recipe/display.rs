//! The recipe table's one-line form of a recipe (`tests/recipe_table.rs` pins it).

use std::fmt;

use super::{LevelRecipe, Network, Recipe, ShsTuning, TrackerRecipe};

impl fmt::Display for ShsTuning {
    /// The settings that differ from the defaults, e.g. `melody gate 6 fr 0.1`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let ShsTuning {
            melody,
            harmonics,
            fundamental_ratio,
            contour_gate_db,
            register_sigma_st,
            attack_rise_db,
            attack_salience_ratio,
            network,
            learned_blend,
            learned_voicing_nats,
        } = self;
        f.write_str(if *melody { "melody" } else { "bass" })?;
        if let Some(h) = harmonics {
            write!(f, " h {h}")?;
        }
        for (name, v) in [
            ("fr", fundamental_ratio),
            ("gate", contour_gate_db),
            ("reg", register_sigma_st),
            ("rise", attack_rise_db),
            ("sal", attack_salience_ratio),
        ] {
            if *v != 0.0 {
                write!(f, " {name} {v}")?;
            }
        }
        if *network != Network::None {
            write!(f, " net {}", network.name())?;
        }
        for (name, v) in [("blend", learned_blend), ("veto", learned_voicing_nats)] {
            if *v != 0.0 {
                write!(f, " {name} {v}")?;
            }
        }
        Ok(())
    }
}

impl fmt::Display for TrackerRecipe {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TrackerRecipe::Yin => f.write_str("yin"),
            TrackerRecipe::Pyin => f.write_str("pyin"),
            TrackerRecipe::Shs(t) => write!(f, "shs({t})"),
            TrackerRecipe::Aligned(t) => write!(f, "aligned({t})"),
            TrackerRecipe::View(t) => write!(f, "view({t})"),
            TrackerRecipe::Pair { voicing, pitch } => write!(f, "pair({voicing} / {pitch})"),
        }
    }
}

impl fmt::Display for LevelRecipe {
    /// The settings that differ between stems, e.g. `iqr 12 span 20 held 3 shadow 25`;
    /// the shared ones (quantile, tolerances, fades) are left out.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let LevelRecipe {
            min_iqr_st,
            held_hops,
            shadow_hops,
            agree_tol_st,
            sure,
            prior_span_st,
            register_hz,
            quantile: _,
            held_tol_st: _,
            held_min_share: _,
            held_min_hops: _,
            prior_fade_hops: _,
            register_fade_hops: _,
        } = self;
        write!(f, "iqr {min_iqr_st} span {prior_span_st}")?;
        if let Some((lo, hi)) = register_hz {
            write!(f, " register {lo}-{hi}")?;
        }
        if *held_hops > 0 {
            write!(f, " held {held_hops}")?;
        }
        if *shadow_hops > 0 {
            write!(f, " shadow {shadow_hops}")?;
        }
        if let Some(t) = agree_tol_st {
            write!(f, " agree {t}")?;
        }
        if let Some(s) = sure {
            write!(
                f,
                " sure {} q {} -{} +{}",
                s.min_conf, s.quantile, s.below_st, s.above_st
            )?;
        }
        Ok(())
    }
}

impl fmt::Display for Recipe {
    /// One line of the recipe table: range, tracker, lag, then what is on, then the levels.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let Recipe {
            range_hz,
            tracker,
            lag_hops,
            harmonic_view,
            advance_hops,
            plain_guard,
            levels,
            notes,
        } = self;
        write!(
            f,
            "{}-{} Hz {tracker} lag {lag_hops}",
            range_hz.0, range_hz.1
        )?;
        if *harmonic_view {
            f.write_str(" harmonic-view")?;
        }
        if *advance_hops > 0 {
            write!(f, " advance {advance_hops}")?;
        }
        if let Some(hz) = plain_guard {
            write!(f, " plain-guard {hz}")?;
        }
        if notes.plucked_mix {
            f.write_str(" plucked-mix")?;
        }
        if notes.clean_lead {
            f.write_str(" clean-lead")?;
        }
        write!(f, " | {levels}")
    }
}
