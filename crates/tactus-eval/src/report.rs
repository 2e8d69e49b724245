//! [`evaluate`]: scores a features file against a corpus truth, one row per melodic stem
//! and per drum band, printable as Markdown and serializable as JSON.
//!
//! Per melodic stem (truth f0 and features `pitch_hz` / `levels`):
//! * RPA, RCA, voicing recall and false alarm ([`crate::melody`]) of `pitch_hz` against the
//!   truth contour, after nearest-neighbour resampling to the truth hop if the hops differ;
//! * level accuracy ([`crate::levels`]): the truth contour is binned to the features'
//!   `bin_s` and discretized into `levels` (default 8) levels, then compared to `levels`;
//! * the paper's MAE and normalized DTW ([`crate::paper`]) between the min–max normalized
//!   binned truth pitch (Hz, 0 = silent) and the min–max normalized tactile levels, the
//!   shorter padded with 0 — the paper's audio-vs-tactile comparison with the audio pitch
//!   replaced by exact truth.
//!
//! Per drum band (truth hits mapped from GM notes, features `onsets_s` / `beats`):
//! * onset P/R/F within ±50 ms ([`crate::onset`]) against two truths (docs/design.md "Known
//!   weakness"): per instrument (`onsets`, the band's instruments: what a listener calls
//!   "kick") and, when the truth file has `band_onsets`, per band (every hit loud in the
//!   band: what band-pass detection can see);
//! * the paper's rhythm accuracy per bin: truth beats binned to `bin_s` vs the features'
//!   `beats` (or `onsets_s` binned when `beats` is absent), over the longer of the two and
//!   `ceil(duration / bin_s)` bins, missing bins counting as "no beat".
//!
//! A metric whose input is missing is `None` (shown as "–").
use tactus_dsp::{Band, Stem};

use crate::{levels, melody, onset, paper, FeaturesLike, Truth};

/// Knobs of [`evaluate_with`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EvalOptions {
    /// Number of pitch levels used to discretize the truth (docs/design.md: 8).
    pub levels: u8,
    /// Onset matching window in seconds (±50 ms).
    pub onset_window_s: f64,
    /// RPA/RCA tolerance in cents (50).
    pub cent_tolerance: f64,
}

impl Default for EvalOptions {
    fn default() -> Self {
        EvalOptions {
            levels: 8,
            onset_window_s: onset::WINDOW_S,
            cent_tolerance: melody::CENT_TOLERANCE,
        }
    }
}

/// Scores of one melodic stem.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StemRow {
    /// Stem name.
    pub stem: String,
    /// Voiced hops in the truth.
    pub truth_voiced_hops: usize,
    /// Raw pitch accuracy (50 cents).
    pub rpa: Option<f64>,
    /// Raw chroma accuracy (50 cents).
    pub rca: Option<f64>,
    /// Voicing recall.
    pub voicing_recall: Option<f64>,
    /// Voicing false alarm.
    pub voicing_false_alarm: Option<f64>,
    /// Fraction of bins whose level equals the truth level.
    pub level_exact: Option<f64>,
    /// Fraction of bins whose level is within ±1 of the truth level.
    pub level_within_1: Option<f64>,
    /// The paper's normalized MAE.
    pub paper_mae: Option<f64>,
    /// The paper's normalized DTW distance.
    pub paper_dtw: Option<f64>,
    /// Plain SDR of the separated stem in dB, filled by [`Report::set_sdr`].
    pub sdr_db: Option<f64>,
    /// Note starts in the truth ([`Truth::note_onset_times`]).
    #[serde(default)]
    pub truth_notes: Option<usize>,
    /// Note onsets in the features (`onsets_s.<stem>`), None if absent.
    #[serde(default)]
    pub est_notes: Option<usize>,
    /// Note-onset precision (±50 ms).
    #[serde(default)]
    pub note_precision: Option<f64>,
    /// Note-onset recall (±50 ms).
    #[serde(default)]
    pub note_recall: Option<f64>,
    /// Note-onset F-measure (±50 ms).
    #[serde(default)]
    pub note_f_measure: Option<f64>,
}

/// Scores of one drum band.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BandRow {
    /// Band name.
    pub band: String,
    /// Truth onsets.
    pub truth_onsets: usize,
    /// Estimated onsets (None if the features lack the band).
    pub est_onsets: Option<usize>,
    /// Onset precision (±50 ms).
    pub precision: Option<f64>,
    /// Onset recall (±50 ms).
    pub recall: Option<f64>,
    /// Onset F-measure (±50 ms).
    pub f_measure: Option<f64>,
    /// Onsets in the per-band truth (None if the truth has none).
    #[serde(default)]
    pub band_truth_onsets: Option<usize>,
    /// Onset precision against the per-band truth.
    #[serde(default)]
    pub band_precision: Option<f64>,
    /// Onset recall against the per-band truth.
    #[serde(default)]
    pub band_recall: Option<f64>,
    /// Onset F-measure against the per-band truth.
    #[serde(default)]
    pub band_f_measure: Option<f64>,
    /// The paper's rhythm accuracy per bin.
    pub paper_rhythm_accuracy: Option<f64>,
}

/// All scores of one song.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Report {
    /// Song name from the truth.
    pub song: String,
    /// Bin length used for levels and beats.
    pub bin_s: f64,
    /// One row per melodic stem that the truth has.
    pub stems: Vec<StemRow>,
    /// One row per drum band.
    pub bands: Vec<BandRow>,
}

/// [`evaluate_with`] with default options.
pub fn evaluate(features: &FeaturesLike, truth: &Truth) -> Report {
    evaluate_with(features, truth, &EvalOptions::default())
}

/// Scores `features` against `truth`; see the module docs.
pub fn evaluate_with(features: &FeaturesLike, truth: &Truth, opts: &EvalOptions) -> Report {
    let bin_s = if features.bin_s > 0.0 {
        features.bin_s
    } else {
        0.1
    };
    let stems = Stem::MELODIC
        .into_iter()
        .filter_map(|stem| {
            truth
                .f0(stem)
                .map(|f0| stem_row(stem, f0, features, truth, bin_s, opts))
        })
        .collect();
    let bands = Band::ALL
        .into_iter()
        .map(|band| band_row(band, features, truth, bin_s, opts))
        .collect();
    Report {
        song: truth.song.clone(),
        bin_s,
        stems,
        bands,
    }
}

fn stem_row(
    stem: Stem,
    truth_f0: &[f64],
    features: &FeaturesLike,
    truth: &Truth,
    bin_s: f64,
    opts: &EvalOptions,
) -> StemRow {
    let mut row = StemRow {
        stem: stem.name().to_string(),
        truth_voiced_hops: truth_f0.iter().filter(|&&f| f > 0.0).count(),
        rpa: None,
        rca: None,
        voicing_recall: None,
        voicing_false_alarm: None,
        level_exact: None,
        level_within_1: None,
        paper_mae: None,
        paper_dtw: None,
        sdr_db: None,
        truth_notes: None,
        est_notes: None,
        note_precision: None,
        note_recall: None,
        note_f_measure: None,
    };
    if let Some(reference) = truth.note_onset_times(stem) {
        row.truth_notes = Some(reference.len());
        if let Some(est) = features.onsets_s.get(stem.name()) {
            row.est_notes = Some(est.len());
            if let Ok(s) = onset::onset_scores(&reference, est, opts.onset_window_s) {
                row.note_precision = Some(s.precision);
                row.note_recall = Some(s.recall);
                row.note_f_measure = Some(s.f_measure);
            }
        }
    }
    if let Some(est) = features.pitch(stem) {
        let est = if (features.hop_s - truth.hop_s).abs() < 1e-12 {
            Ok(est.to_vec())
        } else {
            melody::resample_nearest(est, features.hop_s, truth.hop_s, truth_f0.len())
        };
        if let Ok(s) = est.and_then(|e| melody::melody_scores(truth_f0, &e, opts.cent_tolerance)) {
            row.rpa = Some(s.raw_pitch_accuracy);
            row.rca = Some(s.raw_chroma_accuracy);
            row.voicing_recall = Some(s.voicing_recall);
            row.voicing_false_alarm = Some(s.voicing_false_alarm);
        }
    }
    let (Some(est_levels), Ok(binned)) = (
        features.stem_levels(stem),
        levels::bin_pitch(truth_f0, truth.hop_s, bin_s),
    ) else {
        return row;
    };
    if let Ok(truth_levels) = levels::discretize(&binned, opts.levels) {
        if let Ok((exact, near)) = levels::level_accuracy(&truth_levels, est_levels) {
            row.level_exact = Some(exact);
            row.level_within_1 = Some(near);
        }
    }
    let n = binned.len().max(est_levels.len());
    let mut y = binned.clone();
    y.resize(n, 0.0);
    let mut y_hat: Vec<f64> = est_levels.iter().map(|&l| f64::from(l)).collect();
    y_hat.resize(n, 0.0);
    let (y, y_hat) = (
        paper::normalize_min_max(&y),
        paper::normalize_min_max(&y_hat),
    );
    row.paper_mae = paper::mae(&y, &y_hat).ok();
    row.paper_dtw = paper::normalized_dtw(&y, &y_hat).ok();
    row
}

fn band_row(
    band: Band,
    features: &FeaturesLike,
    truth: &Truth,
    bin_s: f64,
    opts: &EvalOptions,
) -> BandRow {
    let reference = truth.onset_times(band);
    let est = features.onsets(band);
    let mut row = BandRow {
        band: band.name().to_string(),
        truth_onsets: reference.len(),
        est_onsets: est.map(<[f64]>::len),
        precision: None,
        recall: None,
        f_measure: None,
        band_truth_onsets: None,
        band_precision: None,
        band_recall: None,
        band_f_measure: None,
        paper_rhythm_accuracy: None,
    };
    if let Some(Ok(s)) = est.map(|e| onset::onset_scores(&reference, e, opts.onset_window_s)) {
        row.precision = Some(s.precision);
        row.recall = Some(s.recall);
        row.f_measure = Some(s.f_measure);
    }
    if let Some(band_ref) = truth.band_onset_times(band) {
        row.band_truth_onsets = Some(band_ref.len());
        if let Some(Ok(s)) = est.map(|e| onset::onset_scores(&band_ref, e, opts.onset_window_s)) {
            row.band_precision = Some(s.precision);
            row.band_recall = Some(s.recall);
            row.band_f_measure = Some(s.f_measure);
        }
    }
    let est_beats: Option<Vec<bool>> = match (features.band_beats(band), est) {
        (Some(b), _) => Some(b.iter().map(|&x| x != 0).collect()),
        (None, Some(e)) => {
            let n = (truth.duration_s / bin_s - 1e-9).ceil().max(0.0) as usize;
            paper::onsets_to_bins(e, bin_s, n).ok()
        }
        (None, None) => None,
    };
    if let Some(mut est_beats) = est_beats {
        let n = est_beats
            .len()
            .max((truth.duration_s / bin_s - 1e-9).ceil().max(0.0) as usize);
        est_beats.resize(n, false);
        if let Ok(truth_beats) = paper::onsets_to_bins(&reference, bin_s, n) {
            row.paper_rhythm_accuracy = paper::rhythm_accuracy(&truth_beats, &est_beats).ok();
        }
    }
    row
}

fn cell(v: Option<f64>) -> String {
    match v {
        Some(x) if x.is_finite() => format!("{x:.4}"),
        Some(x) => format!("{x}"),
        None => "–".to_string(),
    }
}

fn mean(values: impl Iterator<Item = Option<f64>>) -> Option<f64> {
    let v: Vec<f64> = values.flatten().filter(|x| x.is_finite()).collect();
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

impl Report {
    /// Records the SDR of a stem's separation (no-op if the report has no row for it).
    pub fn set_sdr(&mut self, stem: Stem, sdr_db: f64) {
        if let Some(r) = self.stems.iter_mut().find(|r| r.stem == stem.name()) {
            r.sdr_db = Some(sdr_db);
        }
    }

    /// Mean of the paper's MAE over the stems that have one (the paper's "average MAE").
    pub fn mean_paper_mae(&self) -> Option<f64> {
        mean(self.stems.iter().map(|r| r.paper_mae))
    }

    /// Mean of the paper's normalized DTW over the stems.
    pub fn mean_paper_dtw(&self) -> Option<f64> {
        mean(self.stems.iter().map(|r| r.paper_dtw))
    }

    /// Mean onset F-measure over the bands, per-instrument truth.
    pub fn mean_onset_f(&self) -> Option<f64> {
        mean(self.bands.iter().map(|r| r.f_measure))
    }

    /// Mean onset F-measure over the bands, per-band truth.
    pub fn mean_band_onset_f(&self) -> Option<f64> {
        mean(self.bands.iter().map(|r| r.band_f_measure))
    }

    /// Mean of the paper's rhythm accuracy over the bands.
    pub fn mean_paper_rhythm_accuracy(&self) -> Option<f64> {
        mean(self.bands.iter().map(|r| r.paper_rhythm_accuracy))
    }

    /// Two Markdown tables (stems, bands) and a line with the paper-metric means.
    pub fn to_markdown(&self) -> String {
        let mut s = format!(
            "### {} (bins of {} ms)\n\n",
            self.song,
            (self.bin_s * 1000.0).round()
        );
        s.push_str("| stem | voiced hops | RPA | RCA | voicing recall | voicing FA | level exact | level ±1 | paper MAE | paper DTW | SDR dB | notes | note onsets | note P | note R | note F |\n");
        s.push_str("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
        for r in &self.stems {
            s.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
                r.stem,
                r.truth_voiced_hops,
                cell(r.rpa),
                cell(r.rca),
                cell(r.voicing_recall),
                cell(r.voicing_false_alarm),
                cell(r.level_exact),
                cell(r.level_within_1),
                cell(r.paper_mae),
                cell(r.paper_dtw),
                cell(r.sdr_db),
                r.truth_notes.map_or("–".to_string(), |n| n.to_string()),
                r.est_notes.map_or("–".to_string(), |n| n.to_string()),
                cell(r.note_precision),
                cell(r.note_recall),
                cell(r.note_f_measure)
            ));
        }
        s.push_str("\n| band | est onsets | instrument truth onsets | P | R | F | band truth onsets | band P | band R | band F | paper rhythm acc |\n");
        s.push_str("|---|---|---|---|---|---|---|---|---|---|---|\n");
        for r in &self.bands {
            s.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
                r.band,
                r.est_onsets.map_or("–".to_string(), |n| n.to_string()),
                r.truth_onsets,
                cell(r.precision),
                cell(r.recall),
                cell(r.f_measure),
                r.band_truth_onsets
                    .map_or("–".to_string(), |n| n.to_string()),
                cell(r.band_precision),
                cell(r.band_recall),
                cell(r.band_f_measure),
                cell(r.paper_rhythm_accuracy)
            ));
        }
        s.push_str(&format!(
            "\nOnset F, mean of the bands: per instrument {}, per band {}\n",
            cell(self.mean_onset_f()),
            cell(self.mean_band_onset_f())
        ));
        s.push_str(&format!(
            "\nPaper metrics, mean: MAE {}, DTW {}, rhythm accuracy {} (paper: 0.1020, 0.1518, 0.9756)\n",
            cell(self.mean_paper_mae()),
            cell(self.mean_paper_dtw()),
            cell(self.mean_paper_rhythm_accuracy())
        ));
        s
    }

    /// The report as pretty JSON.
    pub fn to_json(&self) -> String {
        // Serializing plain structs of strings, numbers and options cannot fail, except
        // that serde_json writes non-finite floats as null, which is what we want.
        serde_json::to_string_pretty(self).unwrap_or_default()
    }
}
