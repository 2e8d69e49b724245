//! Reader for the corpus ground truth, `truth.json` (schema in `corpus/README.md`,
//! written by `corpus/generate.py`). Validates `format == "tactus-truth"` and
//! `version == 1`; unknown keys are ignored.
use std::collections::BTreeMap;

use tactus_dsp::{Band, Stem};

use crate::EvalError;

/// The `format` value of a truth file.
pub const FORMAT: &str = "tactus-truth";
/// The supported `version`.
pub const VERSION: u32 = 1;

/// One drum hit.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DrumHit {
    /// Onset time in seconds from the start of the audio.
    pub time_s: f64,
    /// MIDI velocity 1..=127.
    pub velocity: u8,
    /// General MIDI drum note number.
    pub note: u8,
}

/// Ground truth for one song.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Truth {
    /// Always [`FORMAT`].
    pub format: String,
    /// Always [`VERSION`].
    pub version: u32,
    /// Song name (its folder name).
    #[serde(default)]
    pub song: String,
    /// Sample rate of the audio files.
    pub sample_rate: u32,
    /// Length of the audio in seconds.
    pub duration_s: f64,
    /// Hop of the f0 contours: value `i` is at time `i·hop_s`.
    pub hop_s: f64,
    /// f0 in Hz per hop per melodic stem name; 0 = silent.
    #[serde(default)]
    pub f0_hz: BTreeMap<String, Vec<f64>>,
    /// Drum hits per band name (GM note mapped to a band), sorted by time.
    #[serde(default)]
    pub onsets: BTreeMap<String, Vec<DrumHit>>,
    /// Per-band truth: the hits whose isolated sound is loud in each band (`corpus/README.md`,
    /// `band_truth_rule`); a hit may be in several bands. Absent in older truth files.
    #[serde(default)]
    pub band_onsets: Option<BTreeMap<String, Vec<DrumHit>>>,
    /// Note start times in seconds per melodic stem (`other`: its top line), from the MIDI
    /// events rendered. Absent in older truth files: [`Truth::note_onset_times`] then derives
    /// them from `f0_hz`.
    #[serde(default)]
    pub note_onsets_s: Option<BTreeMap<String, Vec<f64>>>,
}

impl Truth {
    /// Parses and validates a truth file's text.
    pub fn from_json_str(text: &str) -> Result<Truth, EvalError> {
        let t: Truth = serde_json::from_str(text)?;
        if t.format != FORMAT || t.version != VERSION {
            return Err(EvalError::Invalid {
                name: "truth format",
                reason: format!(
                    "expected {FORMAT} v{VERSION}, got {} v{}",
                    t.format, t.version
                ),
            });
        }
        if !(t.hop_s > 0.0 && t.hop_s.is_finite()) {
            return Err(EvalError::Invalid {
                name: "hop_s",
                reason: format!("{} is not positive", t.hop_s),
            });
        }
        for v in t.f0_hz.values() {
            crate::check_finite("truth f0_hz", v)?;
        }
        for v in t.note_onsets_s.iter().flat_map(|m| m.values()) {
            crate::check_finite("truth note_onsets_s", v)?;
        }
        for hits in t
            .onsets
            .values()
            .chain(t.band_onsets.iter().flat_map(|b| b.values()))
        {
            if !hits.iter().all(|h| h.time_s.is_finite()) {
                return Err(EvalError::NonFinite("truth onsets"));
            }
        }
        Ok(t)
    }

    /// The f0 contour of a melodic stem, if the truth has one.
    pub fn f0(&self, stem: Stem) -> Option<&[f64]> {
        self.f0_hz.get(stem.name()).map(Vec::as_slice)
    }

    /// Sorted onset times of the per-band truth of `band`, `None` if the file has none.
    pub fn band_onset_times(&self, band: Band) -> Option<Vec<f64>> {
        let b = self.band_onsets.as_ref()?;
        let mut t: Vec<f64> = b
            .get(band.name())
            .map(|h| h.iter().map(|x| x.time_s).collect())
            .unwrap_or_default();
        t.sort_by(f64::total_cmp);
        Some(t)
    }

    /// Sorted onset times of a band's instruments, the per-instrument truth (empty if none).
    pub fn onset_times(&self, band: Band) -> Vec<f64> {
        let mut t: Vec<f64> = self
            .onsets
            .get(band.name())
            .map(|h| h.iter().map(|x| x.time_s).collect())
            .unwrap_or_default();
        t.sort_by(f64::total_cmp);
        t
    }

    /// Sorted note start times of a melodic stem: `note_onsets_s` when the file has it, else
    /// derived from the f0 contour by [`note_onsets_from_f0`]. `None` without an f0 contour.
    pub fn note_onset_times(&self, stem: Stem) -> Option<Vec<f64>> {
        if let Some(v) = self.note_onsets_s.as_ref().and_then(|m| m.get(stem.name())) {
            let mut t = v.clone();
            t.sort_by(f64::total_cmp);
            return Some(t);
        }
        self.f0(stem).map(|f0| note_onsets_from_f0(f0, self.hop_s))
    }
}

/// Note starts of a monophonic f0 contour (Hz per hop, 0 = silent): a hop where voicing
/// begins, or where the pitch moves by at least half a semitone from the previous hop (a new
/// note; vibrato and scoops move by far less per 10 ms hop). Repeated notes of the same pitch
/// without a gap are invisible here, which is why the corpus writes `note_onsets_s`.
pub fn note_onsets_from_f0(f0_hz: &[f64], hop_s: f64) -> Vec<f64> {
    let mut out = Vec::new();
    let mut prev = 0.0f64;
    for (i, &f) in f0_hz.iter().enumerate() {
        let voiced = f > 0.0 && f.is_finite();
        if voiced && (prev <= 0.0 || (12.0 * (f / prev).log2()).abs() >= 0.5) {
            out.push(i as f64 * hop_s);
        }
        prev = if voiced { f } else { 0.0 };
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn note_starts_from_f0() {
        // 10 ms hops: a note, a scoop-free jump of a tone, a gap, the same note again,
        // and vibrato of ±35 cents that must not start notes.
        let a = 220.0;
        let b = 220.0 * 2f64.powf(2.0 / 12.0);
        let mut f = vec![0.0, a, a, a, b, b, 0.0, 0.0, b, b];
        for i in 0..20 {
            f.push(b * 2f64.powf(0.35 / 12.0 * (i as f64).sin()));
        }
        let t = note_onsets_from_f0(&f, 0.01);
        let want = [0.01, 0.04, 0.08];
        assert_eq!(t.len(), want.len(), "{t:?}");
        for (x, y) in t.iter().zip(want) {
            assert!((x - y).abs() < 1e-9);
        }
    }
}
