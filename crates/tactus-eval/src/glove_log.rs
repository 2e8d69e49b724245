//! The paper's Table 3 fidelity from what the glove actually received: the virtual glove's
//! actuation log (`tactus emulate --log`, JSON Lines, format in `tactus-transport`'s
//! `emulator` module) is turned back into per-bin pitch levels and beats and scored with
//! the paper's metrics ([`crate::paper`]), as the paper did with its app log (§3: "the log
//! files were later used in Python to reconstruct the tactile signals").
//!
//! ## Algorithm
//! 1. **Parse** ([`parse_actuation_log`]): each line's `type`, 16-bit `time_ms` (unwrapped:
//!    a drop of more than 32.768 s means one more wrap of 65.536 s) and `frame` (20 hex).
//! 2. **Replay** ([`frames_from_log`]): the log holds only packets that changed a pin, so
//!    the commanded state of pattern bin `k` is the frame of the last `pins` line whose
//!    `time_ms` falls in a bin `≤ k` (held over missing or superseded frames); before the
//!    first line all pins are down. An `all_down` line carries the time of the last frame
//!    sent, so it lowers the pins from the *next* bin on. The timeline is the packet's
//!    stream time, not its arrival: this measures what reached the glove, not the link's
//!    jitter (which `tactus-transport`'s tests measure).
//! 3. **Decode** ([`decode_frames`]) through the pattern's own map: a `pitch` cell's byte is
//!    read back through the level→dot table ([`tactus_glove::glove::level_dots`]; with more
//!    than 8 levels, where levels share a dot, the lowest such level); a byte that is no
//!    level's dot counts as undecodable and reads as 0. A band's cell is a beat when any of
//!    its `dots` is up.
//! 4. **Paper bins** (100 ms, the paper's "10 discrete time bins per second"): pattern bins
//!    are grouped by start time; a level bin holds the lower median of its voiced sub-bins
//!    when at least half are voiced, else 0 ([`crate::levels::bin_pitch`]'s rule); a beat
//!    bin is a beat when any sub-bin is.
//! 5. **Score** ([`glove_fidelity`]) per melodic stem: normalized MAE and normalized DTW
//!    (min–max, as [`crate::paper`]) of the log's levels against (a) the pattern's own
//!    levels (the link: 0 when every frame arrived) and (b) the audio pitch, the features
//!    file's `pitch_hz` binned the same way (the paper's audio-vs-tactile comparison);
//!    per drum band: rhythm accuracy of the log's beats against (a) the pattern's beats and
//!    (b) the features' detected onsets `onsets_s` binned to 100 ms (the paper's "beat onset
//!    detected for the particular 100 ms time bin"). The pattern's own scores against the
//!    audio are reported too: they are the floor that the link cannot improve on.
//!    Sequences of different lengths are padded with 0 / no beat to the longer.
//!
//! Offline only; cost O(N²) for DTW in the number of paper bins.
use std::collections::BTreeMap;

use tactus_dsp::{Band, Stem};
use tactus_glove::glove::level_dots;
use tactus_glove::{CellSource, Frame, GloveMap, Pattern};

use crate::{levels, paper, EvalError, FeaturesLike};

/// The paper's bin length in seconds (§3.1.2: 10 bins per second).
pub const PAPER_BIN_S: f64 = 0.1;

/// One line of the actuation log.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoggedFrame {
    /// Stream time of the packet in ms, unwrapped from the wire's 16 bits.
    pub time_ms: u64,
    /// The commanded state after the packet.
    pub frame: Frame,
    /// True for an `all_down` packet.
    pub all_down: bool,
}

#[derive(serde::Deserialize)]
struct RawLine {
    time_ms: u64,
    #[serde(rename = "type", default)]
    kind: String,
    frame: String,
}

/// Parses the emulator's JSON Lines actuation log; blank lines are skipped, unknown keys
/// ignored, `keep_alive` lines (never written by the emulator) skipped.
pub fn parse_actuation_log(text: &str) -> Result<Vec<LoggedFrame>, EvalError> {
    let mut out = Vec::new();
    let (mut last_raw, mut wraps) = (None::<u64>, 0u64);
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let raw: RawLine = serde_json::from_str(line)?;
        let all_down = match raw.kind.as_str() {
            "pins" | "" => false,
            "all_down" => true,
            "keep_alive" => continue,
            other => {
                return Err(EvalError::Invalid {
                    name: "log type",
                    reason: format!("line {}: unknown packet type {other:?}", i + 1),
                })
            }
        };
        if raw.time_ms > u64::from(u16::MAX) {
            return Err(EvalError::Invalid {
                name: "log time_ms",
                reason: format!("line {}: {} does not fit 16 bits", i + 1, raw.time_ms),
            });
        }
        if let Some(prev) = last_raw {
            if prev > raw.time_ms && prev - raw.time_ms > 32_768 {
                wraps += 1;
            }
        }
        last_raw = Some(raw.time_ms);
        let frame = Frame::from_hex(&raw.frame).map_err(|e| EvalError::Invalid {
            name: "log frame",
            reason: format!("line {}: {e}", i + 1),
        })?;
        out.push(LoggedFrame {
            time_ms: wraps * 65_536 + raw.time_ms,
            frame: if all_down { Frame::DOWN } else { frame },
            all_down,
        });
    }
    Ok(out)
}

/// The commanded frame of each of `n_frames` bins of `bin_ms`; see the module docs.
/// `bin_ms` must be > 0.
pub fn frames_from_log(
    log: &[LoggedFrame],
    bin_ms: u32,
    n_frames: usize,
) -> Result<Vec<Frame>, EvalError> {
    if bin_ms == 0 {
        return Err(EvalError::Invalid {
            name: "bin_ms",
            reason: "must be at least 1".into(),
        });
    }
    let bin = u64::from(bin_ms);
    // (first bin it applies to, order in the log, frame); a stable sort keeps log order
    // among lines of the same bin, so the last one to arrive wins.
    let mut events: Vec<(u64, usize, Frame)> = log
        .iter()
        .enumerate()
        .map(|(i, l)| (l.time_ms / bin + u64::from(l.all_down), i, l.frame))
        .collect();
    events.sort_by_key(|e| (e.0, e.1));
    let mut frames = Vec::with_capacity(n_frames);
    let (mut state, mut next) = (Frame::DOWN, 0usize);
    for k in 0..n_frames as u64 {
        while next < events.len() && events[next].0 <= k {
            state = events[next].2;
            next += 1;
        }
        frames.push(state);
    }
    Ok(frames)
}

/// Levels and beats read back from frames.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Tactile {
    /// Pitch level per bin per melodic stem shown by the map (0 = no dot).
    pub levels: BTreeMap<Stem, Vec<u8>>,
    /// Beat per bin per drum band shown by the map.
    pub beats: BTreeMap<Band, Vec<bool>>,
    /// Pitch-cell bytes that were not any level's dot (read as level 0).
    pub undecodable: usize,
}

/// Reads levels and beats back from frames through `map` (the first cell showing a stem's
/// pitch or a band's onsets is used); see the module docs.
pub fn decode_frames(frames: &[Frame], map: &GloveMap, n_levels: u8) -> Tactile {
    let mut inverse = [0u8; 256];
    for l in (1..=n_levels).rev() {
        inverse[level_dots(l, n_levels) as usize] = l;
    }
    let mut t = Tactile::default();
    for (cell_index, source) in map.cells.iter().flatten().enumerate() {
        match *source {
            CellSource::PitchLevel(stem) if !t.levels.contains_key(&stem) => {
                let v = frames
                    .iter()
                    .map(|f| {
                        let b = f.0[cell_index];
                        let l = inverse[b as usize];
                        if b != 0 && l == 0 {
                            t.undecodable += 1;
                        }
                        l
                    })
                    .collect();
                t.levels.insert(stem, v);
            }
            CellSource::BandOnsets { band, dots } if !t.beats.contains_key(&band) => {
                let v = frames.iter().map(|f| f.0[cell_index] & dots != 0).collect();
                t.beats.insert(band, v);
            }
            _ => {}
        }
    }
    t
}

/// Groups levels of bins of `bin_s` into bins of `paper_bin_s` (module docs, step 4).
pub fn levels_to_paper_bins(
    levels: &[u8],
    bin_s: f64,
    paper_bin_s: f64,
) -> Result<Vec<f64>, EvalError> {
    let v: Vec<f64> = levels.iter().map(|&l| f64::from(l)).collect();
    levels::bin_pitch(&v, bin_s, paper_bin_s)
}

/// Groups beats of bins of `bin_s` into bins of `paper_bin_s`: a beat when any sub-bin is.
pub fn beats_to_paper_bins(
    beats: &[bool],
    bin_s: f64,
    paper_bin_s: f64,
) -> Result<Vec<bool>, EvalError> {
    if !(bin_s > 0.0 && paper_bin_s > 0.0 && bin_s.is_finite() && paper_bin_s.is_finite()) {
        return Err(EvalError::Invalid {
            name: "bin_s/paper_bin_s",
            reason: format!("must be positive ({bin_s}, {paper_bin_s})"),
        });
    }
    let bin_of = |i: usize| (i as f64 * bin_s / paper_bin_s + 1e-9).floor() as usize;
    let n = if beats.is_empty() {
        0
    } else {
        bin_of(beats.len() - 1) + 1
    };
    let mut out = vec![false; n];
    for (i, &b) in beats.iter().enumerate() {
        out[bin_of(i)] |= b;
    }
    Ok(out)
}

/// Fidelity of one melodic stem. `*_vs_pattern` compare the log with the pattern's levels;
/// `*_vs_audio` compare with the features' pitch (None without a features file or pitch).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FidelityStem {
    /// Stem name.
    pub stem: String,
    /// Normalized MAE, log levels vs pattern levels.
    pub mae_vs_pattern: f64,
    /// Normalized DTW, log levels vs pattern levels.
    pub dtw_vs_pattern: f64,
    /// Normalized MAE, log levels vs audio pitch (the paper's Table 3 MAE).
    pub mae_vs_audio: Option<f64>,
    /// Normalized DTW, log levels vs audio pitch (the paper's Table 3 DTW).
    pub dtw_vs_audio: Option<f64>,
    /// Normalized MAE, pattern levels vs audio pitch (the floor).
    pub pattern_mae_vs_audio: Option<f64>,
    /// Normalized DTW, pattern levels vs audio pitch (the floor).
    pub pattern_dtw_vs_audio: Option<f64>,
}

/// Fidelity of one drum band.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FidelityBand {
    /// Band name.
    pub band: String,
    /// Rhythm accuracy per paper bin, log beats vs pattern beats.
    pub rhythm_vs_pattern: f64,
    /// Rhythm accuracy, log beats vs the features' onsets (the paper's Table 3 accuracy).
    pub rhythm_vs_audio: Option<f64>,
    /// Rhythm accuracy, pattern beats vs the features' onsets (the floor).
    pub pattern_rhythm_vs_audio: Option<f64>,
}

/// Table 3 fidelity of one glove log.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Fidelity {
    /// The pattern's bin in ms.
    pub bin_ms: u32,
    /// The scoring bin in seconds (0.1).
    pub paper_bin_s: f64,
    /// Pattern frames.
    pub frames: usize,
    /// Pattern frames whose replayed state equals the pattern's frame exactly.
    pub frames_matching: usize,
    /// Paper bins scored.
    pub paper_bins: usize,
    /// Pitch-cell bytes in the log that no level raises.
    pub undecodable: usize,
    /// One row per melodic stem the map shows.
    pub stems: Vec<FidelityStem>,
    /// One row per drum band the map shows.
    pub bands: Vec<FidelityBand>,
}

fn pad<T: Clone>(mut v: Vec<T>, n: usize, fill: T) -> Vec<T> {
    v.resize(n, fill);
    v
}

fn mae_dtw(y: &[f64], y_hat: &[f64]) -> Result<(f64, f64), EvalError> {
    let n = y.len().max(y_hat.len());
    let y = paper::normalize_min_max(&pad(y.to_vec(), n, 0.0));
    let y_hat = paper::normalize_min_max(&pad(y_hat.to_vec(), n, 0.0));
    Ok((paper::mae(&y, &y_hat)?, paper::normalized_dtw(&y, &y_hat)?))
}

fn rhythm(y: &[bool], y_hat: &[bool]) -> Result<f64, EvalError> {
    let n = y.len().max(y_hat.len());
    paper::rhythm_accuracy(&pad(y.to_vec(), n, false), &pad(y_hat.to_vec(), n, false))
}

/// Signs that `log` is not a recording of `pattern` being played, one sentence each (empty
/// when they agree): the log's span differs from the pattern's length by more than
/// max(3 bins, 5 %), or its first pin frame comes later than max(3 bins, 200 ms) (a player
/// may supersede the first few frames, never more).
pub fn log_mismatch(log: &[LoggedFrame], pattern_frames: usize, bin_ms: u32) -> Vec<String> {
    let bin = u64::from(bin_ms.max(1));
    let pins: Vec<&LoggedFrame> = log.iter().filter(|f| !f.all_down).collect();
    let (Some(first), Some(last)) = (pins.first(), pins.last()) else {
        return vec!["the log holds no pin frames: was the pattern played into this log?".into()];
    };
    let mut w = Vec::new();
    let span = (last.time_ms / bin + 1) as usize;
    let slack = 3usize.max(pattern_frames / 20);
    if span.abs_diff(pattern_frames) > slack {
        w.push(format!(
            "the log covers {span} bins ({:.1} s) but the pattern has {pattern_frames} \
             ({:.1} s): is this the pattern that was played, played to the end?",
            span as f64 * bin as f64 / 1e3,
            pattern_frames as f64 * bin as f64 / 1e3
        ));
    }
    if first.time_ms > (3 * bin).max(200) {
        w.push(format!(
            "the log's first frame is at {} ms, the pattern's at 0 ms: was it played from \
             the start?",
            first.time_ms
        ));
    }
    w
}

/// Scores an actuation log against the pattern it played and, if given, the features file
/// rendered with it; see the module docs. `paper_bin_s` is normally [`PAPER_BIN_S`].
pub fn glove_fidelity(
    log: &[LoggedFrame],
    pattern: &Pattern,
    features: Option<&FeaturesLike>,
    paper_bin_s: f64,
) -> Result<Fidelity, EvalError> {
    if pattern.frames.is_empty() {
        return Err(EvalError::Empty("pattern frames"));
    }
    let bin_s = f64::from(pattern.bin_ms) / 1000.0;
    let replayed = frames_from_log(log, pattern.bin_ms, pattern.frames.len())?;
    let frames_matching = replayed
        .iter()
        .zip(&pattern.frames)
        .filter(|(a, b)| a == b)
        .count();
    let got = decode_frames(&replayed, &pattern.map, pattern.levels);
    let want = decode_frames(&pattern.frames, &pattern.map, pattern.levels);
    let mut paper_bins = 0;
    let mut stems = Vec::new();
    for (stem, log_levels) in &got.levels {
        let y_log = levels_to_paper_bins(log_levels, bin_s, paper_bin_s)?;
        let y_pat = levels_to_paper_bins(&want.levels[stem], bin_s, paper_bin_s)?;
        paper_bins = paper_bins.max(y_log.len());
        let (mae_vs_pattern, dtw_vs_pattern) = mae_dtw(&y_pat, &y_log)?;
        let audio = features
            .and_then(|f| f.pitch(*stem).map(|p| (p, f.hop_s)))
            .map(|(p, hop)| levels::bin_pitch(p, hop, paper_bin_s))
            .transpose()?;
        let (mut mae_a, mut dtw_a, mut pmae_a, mut pdtw_a) = (None, None, None, None);
        if let Some(a) = audio.filter(|a| !a.is_empty()) {
            let (m, d) = mae_dtw(&a, &y_log)?;
            let (pm, pd) = mae_dtw(&a, &y_pat)?;
            (mae_a, dtw_a, pmae_a, pdtw_a) = (Some(m), Some(d), Some(pm), Some(pd));
        }
        stems.push(FidelityStem {
            stem: stem.name().to_string(),
            mae_vs_pattern,
            dtw_vs_pattern,
            mae_vs_audio: mae_a,
            dtw_vs_audio: dtw_a,
            pattern_mae_vs_audio: pmae_a,
            pattern_dtw_vs_audio: pdtw_a,
        });
    }
    let mut bands = Vec::new();
    for (band, log_beats) in &got.beats {
        let b_log = beats_to_paper_bins(log_beats, bin_s, paper_bin_s)?;
        let b_pat = beats_to_paper_bins(&want.beats[band], bin_s, paper_bin_s)?;
        paper_bins = paper_bins.max(b_log.len());
        let audio = features
            .and_then(|f| f.onsets(*band))
            .map(|o| paper::onsets_to_bins(o, paper_bin_s, b_log.len()))
            .transpose()?;
        bands.push(FidelityBand {
            band: band.name().to_string(),
            rhythm_vs_pattern: rhythm(&b_pat, &b_log)?,
            rhythm_vs_audio: audio.as_ref().map(|a| rhythm(a, &b_log)).transpose()?,
            pattern_rhythm_vs_audio: audio.as_ref().map(|a| rhythm(a, &b_pat)).transpose()?,
        });
    }
    Ok(Fidelity {
        bin_ms: pattern.bin_ms,
        paper_bin_s,
        frames: pattern.frames.len(),
        frames_matching,
        paper_bins,
        undecodable: got.undecodable,
        stems,
        bands,
    })
}

fn mean(v: impl Iterator<Item = Option<f64>>) -> Option<f64> {
    let v: Vec<f64> = v.flatten().collect();
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

fn cell(v: Option<f64>) -> String {
    v.map_or("–".to_string(), |x| format!("{x:.4}"))
}

impl Fidelity {
    /// Means over stems / bands: (MAE, DTW, rhythm accuracy) of the log against the audio
    /// features, the paper's Table 3 triple.
    pub fn table3_vs_audio(&self) -> (Option<f64>, Option<f64>, Option<f64>) {
        (
            mean(self.stems.iter().map(|s| s.mae_vs_audio)),
            mean(self.stems.iter().map(|s| s.dtw_vs_audio)),
            mean(self.bands.iter().map(|b| b.rhythm_vs_audio)),
        )
    }

    /// The same triple for the pattern itself against the audio features (the floor).
    pub fn table3_pattern_vs_audio(&self) -> (Option<f64>, Option<f64>, Option<f64>) {
        (
            mean(self.stems.iter().map(|s| s.pattern_mae_vs_audio)),
            mean(self.stems.iter().map(|s| s.pattern_dtw_vs_audio)),
            mean(self.bands.iter().map(|b| b.pattern_rhythm_vs_audio)),
        )
    }

    /// The same triple for the log against the pattern (the link alone).
    pub fn table3_vs_pattern(&self) -> (Option<f64>, Option<f64>, Option<f64>) {
        (
            mean(self.stems.iter().map(|s| Some(s.mae_vs_pattern))),
            mean(self.stems.iter().map(|s| Some(s.dtw_vs_pattern))),
            mean(self.bands.iter().map(|b| Some(b.rhythm_vs_pattern))),
        )
    }

    /// Markdown: per-stem and per-band rows and the Table 3 means next to the paper's.
    pub fn to_markdown(&self) -> String {
        let mut s = format!(
            "### Glove log fidelity ({} of {} frames exact, {} bins of {} ms, {} undecodable)\n\n",
            self.frames_matching,
            self.frames,
            self.paper_bins,
            (self.paper_bin_s * 1000.0).round(),
            self.undecodable
        );
        s.push_str("| stem | MAE log vs audio | DTW log vs audio | MAE pattern vs audio | DTW pattern vs audio | MAE log vs pattern | DTW log vs pattern |\n|---|---|---|---|---|---|---|\n");
        for r in &self.stems {
            s.push_str(&format!(
                "| {} | {} | {} | {} | {} | {:.4} | {:.4} |\n",
                r.stem,
                cell(r.mae_vs_audio),
                cell(r.dtw_vs_audio),
                cell(r.pattern_mae_vs_audio),
                cell(r.pattern_dtw_vs_audio),
                r.mae_vs_pattern,
                r.dtw_vs_pattern
            ));
        }
        s.push_str("\n| band | rhythm acc log vs audio | pattern vs audio | log vs pattern |\n|---|---|---|---|\n");
        for r in &self.bands {
            s.push_str(&format!(
                "| {} | {} | {} | {:.4} |\n",
                r.band,
                cell(r.rhythm_vs_audio),
                cell(r.pattern_rhythm_vs_audio),
                r.rhythm_vs_pattern
            ));
        }
        let (m, d, a) = self.table3_vs_audio();
        let (pm, pd, pa) = self.table3_vs_pattern();
        s.push_str(&format!(
            "\nTable 3, log vs audio: MAE {}, DTW {}, rhythm accuracy {} (paper: 0.1020, 0.1518, 0.9756)\nlog vs pattern (link only): MAE {}, DTW {}, rhythm accuracy {}\n",
            cell(m), cell(d), cell(a), cell(pm), cell(pd), cell(pa)
        ));
        s
    }

    /// The report as pretty JSON.
    pub fn to_json(&self) -> String {
        // Plain structs of strings, numbers and options: serialization cannot fail.
        serde_json::to_string_pretty(self).unwrap_or_default()
    }
}
