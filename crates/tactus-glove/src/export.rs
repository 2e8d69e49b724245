//! Exports for the tools people already use (`render --export FILE.csv|FILE.ahap`).
//!
//! * **CSV** ([`to_csv`], read back with [`from_csv`]): one row per bin, `time_s` (the bin's
//!   start) then one 0/1 column per dot named `FINGER.cCELL.dDOT` (`thumb.c0.d1` …
//!   `pinky.c1.d8`; fingers thumb → pinky, cell 0 then 1, dots 1 → 8 = bit order of the
//!   pattern file's cell bytes). For spreadsheets, R and pandas.
//! * **AHAP** ([`to_ahap`]), Apple Core Haptics' JSON pattern format (keys `Version`,
//!   `Metadata`, `Pattern`, `Event`, `Time`, `EventType`, `EventDuration`,
//!   `EventParameters`, `ParameterID`, `ParameterValue`): every onset of a drum class the
//!   map shows becomes a `HapticTransient` (intensity 1.0: the features file carries no
//!   onset strength yet; sharpness per class, duller for low drums: kick 0.2,
//!   toms 0.4, snare 0.7, cymbals 0.9, the whole drum stem 0.5); the bass becomes
//!   `HapticContinuous` events, one per run of bins at one pitch level, whose
//!   `HapticSharpness` is `level / levels` (higher notes feel sharper), intensity 1.0,
//!   split so no event exceeds Core Haptics' 30 s limit.

use std::fmt::Write as _;

use serde_json::{json, Value};

use crate::glove::{Dot, Finger, Frame, CELLS_PER_FINGER};
use crate::map::CellSource;
use crate::{Band, Features, GloveError, Pattern, Stem};

/// An export format, chosen by the file's extension (`render --export`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExportFormat {
    /// [`to_csv`].
    Csv,
    /// [`to_ahap`].
    Ahap,
}

impl ExportFormat {
    /// `.csv` or `.ahap` (any case); `None` for anything else.
    pub fn of(path: &std::path::Path) -> Option<ExportFormat> {
        crate::atomic::by_extension(
            path,
            &[("csv", ExportFormat::Csv), ("ahap", ExportFormat::Ahap)],
        )
    }

    /// The export's bytes.
    pub fn bytes(self, pattern: &Pattern, features: &Features) -> Vec<u8> {
        match self {
            ExportFormat::Csv => to_csv(pattern).into_bytes(),
            ExportFormat::Ahap => to_ahap(pattern, features).into_bytes(),
        }
    }
}

/// Longest `HapticContinuous` event Core Haptics plays, in seconds.
pub const AHAP_MAX_CONTINUOUS_S: f64 = 30.0;

/// The 81 CSV column names: `time_s`, then `thumb.c0.d1` … `pinky.c1.d8`.
pub fn csv_header() -> Vec<String> {
    let mut h = vec!["time_s".to_string()];
    for f in Finger::ALL {
        for c in 0..CELLS_PER_FINGER {
            for d in Dot::ALL {
                h.push(format!("{}.c{c}.d{}", f.name(), d.number()));
            }
        }
    }
    h
}

/// The pattern as CSV (see the module docs). Times are exact decimal milliseconds.
pub fn to_csv(pattern: &Pattern) -> String {
    let mut s = csv_header().join(",");
    s.push('\n');
    for (i, frame) in pattern.frames.iter().enumerate() {
        let ms = i as u64 * u64::from(pattern.bin_ms);
        let _ = write!(s, "{}", ms as f64 / 1000.0);
        for byte in frame.0 {
            for bit in 0..8 {
                s.push_str(if byte >> bit & 1 == 1 { ",1" } else { ",0" });
            }
        }
        s.push('\n');
    }
    s
}

/// Reads a CSV written by [`to_csv`] back into `(time_s, frame)` rows. Columns may come in
/// any order (they are matched by name); every dot column must be present, values 0 or 1.
pub fn from_csv(text: &str) -> Result<Vec<(f64, Frame)>, GloveError> {
    let bad = |row: usize, why: String| GloveError::InvalidField {
        field: format!("csv line {}", row + 1),
        reason: why,
    };
    let mut lines = text.lines();
    let header: Vec<&str> = lines
        .next()
        .ok_or_else(|| bad(0, "empty file".into()))?
        .split(',')
        .collect();
    let want = csv_header();
    let mut column = Vec::with_capacity(want.len());
    for name in &want {
        column.push(
            header
                .iter()
                .position(|h| h.trim() == name)
                .ok_or_else(|| bad(0, format!("column {name} missing")))?,
        );
    }
    let mut rows = Vec::new();
    for (n, line) in lines.enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let v: Vec<&str> = line.split(',').map(str::trim).collect();
        if v.len() != header.len() {
            return Err(bad(
                n + 1,
                format!("{} fields, header has {}", v.len(), header.len()),
            ));
        }
        let t: f64 = v[column[0]]
            .parse()
            .map_err(|_| bad(n + 1, format!("time_s {:?} is not a number", v[column[0]])))?;
        let mut frame = Frame::DOWN;
        for (k, &col) in column[1..].iter().enumerate() {
            match v[col] {
                "0" => {}
                "1" => frame.0[k / 8] |= 1 << (k % 8),
                other => {
                    return Err(bad(
                        n + 1,
                        format!("{}: {other:?} is not 0 or 1", want[k + 1]),
                    ))
                }
            }
        }
        rows.push((t, frame));
    }
    Ok(rows)
}

fn sharpness_of(group: &str) -> f64 {
    match group {
        "kick" => 0.2,
        "toms" => 0.4,
        "snare" => 0.7,
        "cymbals" => 0.9,
        _ => 0.5,
    }
}

fn param(id: &str, value: f64) -> Value {
    json!({ "ParameterID": id, "ParameterValue": (value.clamp(0.0, 1.0) * 1e4).round() / 1e4 })
}

fn secs(t: f64) -> f64 {
    (t * 1e4).round() / 1e4
}

/// The pattern's drums and bass as an AHAP document (see the module docs). `features` are
/// those rendered with the pattern.
pub fn to_ahap(pattern: &Pattern, features: &Features) -> String {
    let mut drum_groups: Vec<&str> = Vec::new();
    let mut bass = false;
    for source in pattern.map.cells.iter().flatten() {
        let g = match *source {
            CellSource::BandOnsets { band, .. } => Some(band.name()),
            CellSource::NoteOnsets {
                stem: Stem::Drums, ..
            } => Some(Stem::Drums.name()),
            CellSource::PitchLevel(Stem::Bass)
            | CellSource::NoteOnsets {
                stem: Stem::Bass, ..
            } => {
                bass = true;
                None
            }
            _ => None,
        };
        if let Some(g) = g {
            if !drum_groups.contains(&g) {
                drum_groups.push(g);
            }
        }
    }
    // Order: bands in Band::ALL order, then the drum stem.
    drum_groups.sort_by_key(|g| Band::from_name(g).map_or(4, |b| b as usize));

    let mut events: Vec<(f64, Value)> = Vec::new();
    for g in &drum_groups {
        for &t in features.onsets_s.get(*g).map(Vec::as_slice).unwrap_or(&[]) {
            events.push((
                t,
                json!({ "Event": {
                    "Time": secs(t),
                    "EventType": "HapticTransient",
                    "EventParameters": [param("HapticIntensity", 1.0), param("HapticSharpness", sharpness_of(g))],
                }}),
            ));
        }
    }
    if bass {
        let levels = features
            .levels
            .get("bass")
            .map(Vec::as_slice)
            .unwrap_or(&[]);
        let bin_s = f64::from(pattern.bin_ms) / 1000.0;
        let max_bins = ((AHAP_MAX_CONTINUOUS_S / bin_s).floor() as usize).max(1);
        let mut i = 0;
        while i < levels.len() {
            let level = levels[i];
            let mut j = i + 1;
            while j < levels.len() && levels[j] == level && j - i < max_bins {
                j += 1;
            }
            if level > 0 {
                let t = i as f64 * bin_s;
                events.push((
                    t,
                    json!({ "Event": {
                        "Time": secs(t),
                        "EventType": "HapticContinuous",
                        "EventDuration": secs((j - i) as f64 * bin_s),
                        "EventParameters": [
                            param("HapticIntensity", 1.0),
                            param("HapticSharpness", f64::from(level) / f64::from(pattern.levels.max(1))),
                        ],
                    }}),
                ));
            }
            i = j;
        }
    }
    events.sort_by(|a, b| a.0.total_cmp(&b.0));
    let doc = json!({
        "Version": 1.0,
        "Metadata": {
            "Project": "Tactus",
            "Created": "tactus render --export",
            "Description": format!(
                "{}: drum onsets ({}) as transients, bass pitch level as continuous sharpness",
                pattern.source.path,
                drum_groups.join(", ")
            ),
        },
        "Pattern": events.into_iter().map(|(_, e)| e).collect::<Vec<_>>(),
    });
    let mut s = serde_json::to_string_pretty(&doc).unwrap_or_default();
    s.push('\n');
    s
}
