//! The features file (`render --features`, docs/design.md "Files", a contract): the extracted
//! features behind a pattern, for plots, evaluation and debugging.
//!
//! ```json
//! { "hop_s": 0.01, "bin_s": 0.1,
//!   "pitch_hz": { "bass": [...], "vocals": [...], "other": [...] },
//!   "levels":   { "bass": [...], "vocals": [...], "other": [...] },
//!   "onsets_s": { "kick": [...], "snare": [...], "toms": [...], "cymbals": [...] },
//!   "beats":    { "kick": [...], "snare": [...], "toms": [...], "cymbals": [...] } }
//! ```
//!
//! * `pitch_hz[stem][i]` is the pitch at time `i * hop_s` (0 = unvoiced), after the gate and
//!   the fences; keys are melodic stems (bass, vocals, other).
//! * `levels[stem][b]` is the level of bin `b` (time `b * bin_s`), 0 = silent.
//! * `onsets_s[name]` are onset times in seconds, non-decreasing; `beats[name][b]` is 0 or 1.
//!   `name` is a drum band (kick, snare, toms, cymbals) or, for note onsets, a stem
//!   (drums, bass, vocals, other) — the contract lists bands; stems are our extension.
//!
//! Only what the scene computed appears; absent groups read as empty. Tactus writes
//! `"format": "tactus-features", "version": 1` as well (extra keys are allowed) and accepts
//! files without them; readers ignore unknown keys.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::json::{check_header, invalid, optional, parse_object, required};
use crate::{Band, GloveError, Stem};

/// The `format` value of a features file.
pub const FEATURES_FORMAT: &str = "tactus-features";
/// The features file version this build reads and writes.
pub const FEATURES_VERSION: u64 = 1;

/// Extracted features. See the module docs.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct Features {
    /// Seconds between pitch values (> 0).
    pub hop_s: f64,
    /// Seconds per bin (> 0).
    pub bin_s: f64,
    /// Pitch per hop in Hz, per melodic stem; 0 = unvoiced.
    pub pitch_hz: BTreeMap<String, Vec<f32>>,
    /// Level per bin, per melodic stem; 0 = silent.
    pub levels: BTreeMap<String, Vec<u8>>,
    /// Onset times in seconds, per band or stem.
    pub onsets_s: BTreeMap<String, Vec<f64>>,
    /// Beat (0/1) per bin, per band or stem.
    pub beats: BTreeMap<String, Vec<u8>>,
}

#[derive(Serialize)]
struct FeaturesOut<'a> {
    format: &'static str,
    version: u64,
    #[serde(flatten)]
    features: &'a Features,
}

fn check_melodic(group: &str, key: &str) -> Result<(), GloveError> {
    match Stem::from_name(key) {
        Some(Stem::Drums) => Err(invalid(
            format!("{group}.{key}"),
            "the drum stem has no pitch (expected bass, vocals or other)",
        )),
        Some(_) => Ok(()),
        None => Err(invalid(
            format!("{group}.{key}"),
            format!("unknown stem \"{key}\" (expected bass, vocals or other)"),
        )),
    }
}

fn check_onset_key(group: &str, key: &str) -> Result<(), GloveError> {
    if Band::from_name(key).is_some() || Stem::from_name(key).is_some() {
        Ok(())
    } else {
        Err(invalid(
            format!("{group}.{key}"),
            format!(
                "unknown band or stem \"{key}\" (expected kick, snare, toms, cymbals, \
                 drums, bass, vocals or other)"
            ),
        ))
    }
}

impl Features {
    /// Checks keys and values: known names, `hop_s` and `bin_s` finite and > 0, pitches
    /// finite and >= 0, onset times finite, >= 0 and non-decreasing, beats 0 or 1.
    pub fn validate(&self) -> Result<(), GloveError> {
        for (name, v) in [("hop_s", self.hop_s), ("bin_s", self.bin_s)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(invalid(name, format!("must be finite and > 0, found {v}")));
            }
        }
        for (key, values) in &self.pitch_hz {
            check_melodic("pitch_hz", key)?;
            if let Some(i) = values.iter().position(|x| !(x.is_finite() && *x >= 0.0)) {
                return Err(invalid(
                    format!("pitch_hz.{key}[{i}]"),
                    format!("must be finite and >= 0 Hz, found {}", values[i]),
                ));
            }
        }
        for key in self.levels.keys() {
            check_melodic("levels", key)?;
        }
        for (key, values) in &self.onsets_s {
            check_onset_key("onsets_s", key)?;
            let mut last = 0.0f64;
            for (i, &t) in values.iter().enumerate() {
                if !(t.is_finite() && t >= last) {
                    return Err(invalid(
                        format!("onsets_s.{key}[{i}]"),
                        format!("onset times must be finite, >= 0 and non-decreasing, found {t}"),
                    ));
                }
                last = t;
            }
        }
        for (key, values) in &self.beats {
            check_onset_key("beats", key)?;
            if let Some(i) = values.iter().position(|&b| b > 1) {
                return Err(invalid(
                    format!("beats.{key}[{i}]"),
                    format!("must be 0 or 1, found {}", values[i]),
                ));
            }
        }
        Ok(())
    }

    /// The features as JSON (validated first), with `format` and `version` keys.
    pub fn to_json_string(&self) -> Result<String, GloveError> {
        self.validate()?;
        let out = FeaturesOut {
            format: FEATURES_FORMAT,
            version: FEATURES_VERSION,
            features: self,
        };
        let mut s =
            serde_json::to_string(&out).map_err(|e| GloveError::Io(std::io::Error::other(e)))?;
        s.push('\n');
        Ok(s)
    }

    /// Parses features from JSON bytes and validates them.
    pub fn from_slice(bytes: &[u8]) -> Result<Features, GloveError> {
        let obj = parse_object(bytes, "features")?;
        check_header(&obj, FEATURES_FORMAT, "features", FEATURES_VERSION, false)?;
        let f = Features {
            hop_s: required(&obj, "hop_s")?,
            bin_s: required(&obj, "bin_s")?,
            pitch_hz: optional(&obj, "pitch_hz")?.unwrap_or_default(),
            levels: optional(&obj, "levels")?.unwrap_or_default(),
            onsets_s: optional(&obj, "onsets_s")?.unwrap_or_default(),
            beats: optional(&obj, "beats")?.unwrap_or_default(),
        };
        f.validate()?;
        Ok(f)
    }
}

crate::json::json_file_readers!(Features);
