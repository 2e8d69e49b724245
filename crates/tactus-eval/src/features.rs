//! A minimal reader for the features file (docs/design.md "Files", `render --features`).
//! `tactus-glove` owns the canonical reader and writer; this one only takes what the
//! metrics need and ignores every other key. Missing stems or bands are simply absent.
use std::collections::BTreeMap;

use tactus_dsp::{Band, Stem};

use crate::EvalError;

/// The parts of a features file that the metrics use.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FeaturesLike {
    /// Hop of `pitch_hz` in seconds: value `i` is at `i·hop_s`.
    pub hop_s: f64,
    /// Bin length of `levels` and `beats` in seconds.
    pub bin_s: f64,
    /// Pitch in Hz per hop per melodic stem, 0 = unvoiced.
    #[serde(default)]
    pub pitch_hz: BTreeMap<String, Vec<f64>>,
    /// Pitch level per bin per melodic stem, 0 = silent.
    #[serde(default)]
    pub levels: BTreeMap<String, Vec<u8>>,
    /// Onset times in seconds per drum band.
    #[serde(default)]
    pub onsets_s: BTreeMap<String, Vec<f64>>,
    /// Beat (0/1) per bin per drum band.
    #[serde(default)]
    pub beats: BTreeMap<String, Vec<u8>>,
}

impl FeaturesLike {
    /// Parses a features file's text, checking that `hop_s` and `bin_s` are positive.
    pub fn from_json_str(text: &str) -> Result<FeaturesLike, EvalError> {
        let f: FeaturesLike = serde_json::from_str(text)?;
        for (name, v) in [("hop_s", f.hop_s), ("bin_s", f.bin_s)] {
            if !(v > 0.0 && v.is_finite()) {
                return Err(EvalError::Invalid {
                    name,
                    reason: format!("{v} is not positive"),
                });
            }
        }
        Ok(f)
    }

    /// Pitch contour of a stem, if present.
    pub fn pitch(&self, stem: Stem) -> Option<&[f64]> {
        self.pitch_hz.get(stem.name()).map(Vec::as_slice)
    }

    /// Levels of a stem, if present.
    pub fn stem_levels(&self, stem: Stem) -> Option<&[u8]> {
        self.levels.get(stem.name()).map(Vec::as_slice)
    }

    /// Onset times of a band, if present.
    pub fn onsets(&self, band: Band) -> Option<&[f64]> {
        self.onsets_s.get(band.name()).map(Vec::as_slice)
    }

    /// Beats of a band, if present.
    pub fn band_beats(&self, band: Band) -> Option<&[u8]> {
        self.beats.get(band.name()).map(Vec::as_slice)
    }
}
