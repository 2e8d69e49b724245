//! The feature-to-pin map: which musical feature each of the 10 braille cells shows.
//!
//! The paper (Electronics 2025, 14(18), 3658, §3) assigns fixed features to fingers: bass,
//! vocals and other pitch levels plus the four drum bands. Tactus makes that assignment a
//! small TOML file (docs/design.md, "The glove"); the default, `maps/default.toml`, is the
//! contract's table:
//!
//! | finger | cell 0 | cell 1 |
//! |---|---|---|
//! | thumb | bass pitch level | bass note onsets |
//! | index | kick onsets (all 8 dots) | snare onsets (all 8 dots) |
//! | middle | toms onsets | cymbals onsets |
//! | ring | vocals pitch level | vocals note onsets |
//! | pinky | other pitch level | other note onsets |
//!
//! A cell is written `{ pitch = "bass" }` (one dot per bin, see [`level_dots`]),
//! `{ onsets = "vocals" }` (a stem's note onsets; `"drums"` means every drum onset),
//! `{ onsets = "kick" }` (a drum band's onsets), optionally with `dots = [1, 2, 3, 7]` to
//! raise only some dots (default: all 8), or `{}` / nothing for a cell that stays down.
//! Stem names (drums, bass, vocals, other) and band names (kick, snare, toms, cymbals) never
//! collide, so `onsets` needs no second key.
//!
//! The map decides what the engine computes ([`GloveMap::needs`], [`GloveMap::stems`]) and
//! turns one bin's features into a [`Frame`] ([`GloveMap::render`], allocation-free, no
//! latency). The same structure serialises to JSON for the pattern file.

use std::fmt::Write as _;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::glove::{level_dots, Dot, Finger, Frame, CELLS_PER_FINGER};
use crate::{Band, GloveError, Stem};

/// The text of `maps/default.toml`, the contract's default map.
pub const DEFAULT_MAP_TOML: &str = include_str!("../maps/default.toml");

/// The built-in maps by name (the files in `maps/`, embedded): `--map NAME`.
pub const BUILTIN_MAPS: [(&str, &str); 3] = [
    ("default", DEFAULT_MAP_TOML),
    ("drums-only", include_str!("../maps/drums-only.toml")),
    ("melody", include_str!("../maps/melody.toml")),
];
/// The text of `maps/drums-only.toml`.
pub const DRUMS_ONLY_MAP_TOML: &str = include_str!("../maps/drums-only.toml");
/// The text of `maps/melody.toml`.
pub const MELODY_MAP_TOML: &str = include_str!("../maps/melody.toml");

/// All 8 dots of a cell.
pub const ALL_DOTS: u8 = 0xFF;

/// What one braille cell shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum CellSource {
    /// Nothing: the cell stays down.
    #[default]
    Off,
    /// The stem's pitch level in the bin: one dot, see [`level_dots`]. Melodic stems only.
    PitchLevel(Stem),
    /// The stem's note onsets: `dots` rise for every bin holding an onset.
    /// For [`Stem::Drums`] these are onsets of the whole drum stem.
    NoteOnsets {
        /// The stem.
        stem: Stem,
        /// Dots raised on an onset (cell-byte mask; [`ALL_DOTS`] by default).
        dots: u8,
    },
    /// Onsets in one drum band: `dots` rise for every bin holding a beat in that band.
    BandOnsets {
        /// The band.
        band: Band,
        /// Dots raised on an onset (cell-byte mask; [`ALL_DOTS`] by default).
        dots: u8,
    },
}

/// One bin's features, the input of [`GloveMap::render`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BinFeatures {
    /// Pitch level per stem, indexed by `Stem as usize` ([`Stem::ALL`] order); 0 = silent.
    pub level: [u8; 4],
    /// Whether the stem has a note onset in the bin, indexed like `level`.
    pub note_onset: [bool; 4],
    /// Whether the band has a beat in the bin, indexed by `Band as usize` ([`Band::ALL`] order).
    pub band_beat: [bool; 4],
}

/// What a map needs the engine to compute. Every list is sorted and free of duplicates.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Needs {
    /// Stems whose pitch levels are shown.
    pub pitch: Vec<Stem>,
    /// Stems whose note onsets are shown.
    pub note_onsets: Vec<Stem>,
    /// Drum bands whose onsets are shown.
    pub bands: Vec<Band>,
}

/// The feature shown by each of the 10 cells: `cells[finger as usize][cell]`.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "RawMap", into = "RawMap")]
pub struct GloveMap {
    /// Per finger (wire order), per cell.
    pub cells: [[CellSource; CELLS_PER_FINGER]; 5],
}

impl Default for GloveMap {
    /// The contract's default map, parsed from the embedded `maps/default.toml`.
    ///
    /// # Panics
    /// Never in practice: the embedded file is fixed at compile time and the test suite
    /// checks that it parses to the contract's table.
    fn default() -> Self {
        GloveMap::from_toml_str(DEFAULT_MAP_TOML).expect("embedded maps/default.toml is valid")
    }
}

impl GloveMap {
    /// A map with every cell off.
    pub fn off() -> GloveMap {
        GloveMap {
            cells: [[CellSource::Off; CELLS_PER_FINGER]; 5],
        }
    }

    /// The source of `finger`'s `cell`.
    ///
    /// # Panics
    /// If `cell >= CELLS_PER_FINGER`.
    pub fn get(&self, finger: Finger, cell: usize) -> CellSource {
        self.cells[finger.index()][cell]
    }

    /// Sets the source of `finger`'s `cell`, checking that it makes sense (no pitch for
    /// drums, no empty dot mask).
    ///
    /// # Panics
    /// If `cell >= CELLS_PER_FINGER`.
    pub fn set(
        &mut self,
        finger: Finger,
        cell: usize,
        source: CellSource,
    ) -> Result<(), GloveError> {
        check_source(source).map_err(|reason| GloveError::Map {
            finger: finger.name(),
            cell: CELL_KEYS[cell],
            reason,
        })?;
        self.cells[finger.index()][cell] = source;
        Ok(())
    }

    /// Parses a map from TOML (see the module docs for the syntax).
    pub fn from_toml_str(s: &str) -> Result<GloveMap, GloveError> {
        let raw: RawMap = toml::from_str(s).map_err(|e| {
            // One line: "line L, column C: message" (the default text spans several lines).
            let message = e.message().trim().replace('\n', " ");
            GloveError::MapSyntax(match e.span() {
                Some(span) => {
                    let before = &s[..span.start.min(s.len())];
                    let line = before.matches('\n').count() + 1;
                    let column = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
                    format!("line {line}, column {column}: {message}")
                }
                None => message,
            })
        })?;
        GloveMap::try_from(raw)
    }

    /// Reads a TOML map file.
    pub fn from_path(path: impl AsRef<Path>) -> Result<GloveMap, GloveError> {
        let path = path.as_ref();
        std::fs::read_to_string(path)
            .map_err(GloveError::from)
            .and_then(|s| GloveMap::from_toml_str(&s))
            .map_err(|e| e.in_file(path))
    }

    /// A built-in map ([`BUILTIN_MAPS`]) by name, with or without `.toml`.
    pub fn builtin(name: &str) -> Option<GloveMap> {
        let name = name.strip_suffix(".toml").unwrap_or(name);
        BUILTIN_MAPS
            .iter()
            .find(|(n, _)| *n == name)
            .and_then(|(_, toml)| GloveMap::from_toml_str(toml).ok())
    }

    /// What `--map ARG` means: the file `arg` if it exists, else the built-in map of that
    /// name ([`GloveMap::builtin`]), else [`GloveError::UnknownMap`].
    pub fn from_name_or_path(arg: impl AsRef<Path>) -> Result<GloveMap, GloveError> {
        let arg = arg.as_ref();
        if arg.exists() {
            return GloveMap::from_path(arg);
        }
        let name = arg.to_string_lossy();
        GloveMap::builtin(&name).ok_or_else(|| GloveError::UnknownMap {
            name: name.into_owned(),
            known: BUILTIN_MAPS.map(|(n, _)| n).join(", "),
        })
    }

    /// The map as TOML, one `[finger]` table per finger with inline cell tables, in the
    /// style of `maps/default.toml`. [`GloveMap::from_toml_str`] reads it back unchanged.
    pub fn to_toml_string(&self) -> String {
        let mut s = String::new();
        for finger in Finger::ALL {
            if !s.is_empty() {
                s.push('\n');
            }
            let _ = writeln!(s, "[{}]", finger.name());
            for (cell, key) in CELL_KEYS.iter().enumerate() {
                let raw = RawCell::from(self.get(finger, cell));
                let mut parts = Vec::new();
                if let Some(p) = &raw.pitch {
                    parts.push(format!("pitch = \"{p}\""));
                }
                if let Some(o) = &raw.onsets {
                    parts.push(format!("onsets = \"{o}\""));
                }
                if let Some(d) = &raw.dots {
                    let list: Vec<String> = d.iter().map(|n| n.to_string()).collect();
                    parts.push(format!("dots = [{}]", list.join(", ")));
                }
                if parts.is_empty() {
                    let _ = writeln!(s, "{key} = {{}}");
                } else {
                    let _ = writeln!(s, "{key} = {{ {} }}", parts.join(", "));
                }
            }
        }
        s
    }

    /// Which features the map shows.
    pub fn needs(&self) -> Needs {
        let mut n = Needs::default();
        for source in self.cells.iter().flatten() {
            match *source {
                CellSource::Off => {}
                CellSource::PitchLevel(stem) => n.pitch.push(stem),
                CellSource::NoteOnsets { stem, .. } => n.note_onsets.push(stem),
                CellSource::BandOnsets { band, .. } => n.bands.push(band),
            }
        }
        n.pitch.sort();
        n.pitch.dedup();
        n.note_onsets.sort();
        n.note_onsets.dedup();
        n.bands.sort();
        n.bands.dedup();
        n
    }

    /// The stems the separator must produce, in [`Stem::ALL`] order: every stem with a pitch
    /// or onset cell, plus [`Stem::Drums`] when any band is shown.
    pub fn stems(&self) -> Vec<Stem> {
        let n = self.needs();
        let mut stems: Vec<Stem> = n.pitch.iter().chain(&n.note_onsets).copied().collect();
        if !n.bands.is_empty() {
            stems.push(Stem::Drums);
        }
        stems.sort();
        stems.dedup();
        stems
    }

    /// The frame for one bin. Pitch cells use [`level_dots`]`(level, levels)`; onset cells
    /// raise their dots when the bin holds an onset. Allocation-free.
    pub fn render(&self, f: &BinFeatures, levels: u8) -> Frame {
        let mut frame = Frame::DOWN;
        for (i, byte) in frame.0.iter_mut().enumerate() {
            *byte = match self.cells[i / CELLS_PER_FINGER][i % CELLS_PER_FINGER] {
                CellSource::Off => 0,
                CellSource::PitchLevel(stem) => level_dots(f.level[stem as usize], levels),
                CellSource::NoteOnsets { stem, dots } => {
                    if f.note_onset[stem as usize] {
                        dots
                    } else {
                        0
                    }
                }
                CellSource::BandOnsets { band, dots } => {
                    if f.band_beat[band as usize] {
                        dots
                    } else {
                        0
                    }
                }
            };
        }
        frame
    }
}

const CELL_KEYS: [&str; CELLS_PER_FINGER] = ["cell0", "cell1"];

fn check_source(source: CellSource) -> Result<(), String> {
    match source {
        CellSource::PitchLevel(Stem::Drums) => {
            Err("the drum stem has no pitch; use { onsets = \"drums\" } or a band".into())
        }
        CellSource::NoteOnsets { dots: 0, .. } | CellSource::BandOnsets { dots: 0, .. } => {
            Err("`dots` is empty: an onset cell must raise at least one dot".into())
        }
        _ => Ok(()),
    }
}

/// The serialised form of a cell: `{ pitch = "STEM" }`, `{ onsets = "STEM|BAND", dots = [...] }`
/// or `{}`.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCell {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pitch: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    onsets: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    dots: Option<Vec<i64>>,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFinger {
    #[serde(default)]
    cell0: RawCell,
    #[serde(default)]
    cell1: RawCell,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMap {
    #[serde(default)]
    thumb: RawFinger,
    #[serde(default)]
    index: RawFinger,
    #[serde(default)]
    middle: RawFinger,
    #[serde(default)]
    ring: RawFinger,
    #[serde(default)]
    pinky: RawFinger,
}

impl From<CellSource> for RawCell {
    fn from(source: CellSource) -> RawCell {
        let dots_list = |dots: u8| {
            (dots != ALL_DOTS).then(|| {
                Dot::ALL
                    .into_iter()
                    .filter(|d| dots & d.mask() != 0)
                    .map(|d| i64::from(d.number()))
                    .collect()
            })
        };
        match source {
            CellSource::Off => RawCell::default(),
            CellSource::PitchLevel(stem) => RawCell {
                pitch: Some(stem.name().into()),
                ..RawCell::default()
            },
            CellSource::NoteOnsets { stem, dots } => RawCell {
                onsets: Some(stem.name().into()),
                dots: dots_list(dots),
                ..RawCell::default()
            },
            CellSource::BandOnsets { band, dots } => RawCell {
                onsets: Some(band.name().into()),
                dots: dots_list(dots),
                ..RawCell::default()
            },
        }
    }
}

impl RawCell {
    fn to_source(&self) -> Result<CellSource, String> {
        let dots = match &self.dots {
            None => ALL_DOTS,
            Some(list) => {
                let mut mask = 0u8;
                for &n in list {
                    let dot = u8::try_from(n)
                        .ok()
                        .and_then(Dot::new)
                        .ok_or_else(|| format!("`dots`: {n} is not a braille dot number (1-8)"))?;
                    mask |= dot.mask();
                }
                mask
            }
        };
        let source = match (&self.pitch, &self.onsets) {
            (Some(_), Some(_)) => {
                return Err("set only one of `pitch` and `onsets` in a cell".into());
            }
            (None, None) => {
                if self.dots.is_some() {
                    return Err("`dots` without `onsets`".into());
                }
                CellSource::Off
            }
            (Some(p), None) => {
                if self.dots.is_some() {
                    return Err(
                        "`dots` is not allowed with `pitch` (a pitch level raises one dot)".into(),
                    );
                }
                match Stem::from_name(p) {
                    Some(stem) => CellSource::PitchLevel(stem),
                    None => {
                        return Err(format!(
                            "`pitch`: unknown stem \"{p}\" (expected bass, vocals or other)"
                        ))
                    }
                }
            }
            (None, Some(o)) => {
                if let Some(stem) = Stem::from_name(o) {
                    CellSource::NoteOnsets { stem, dots }
                } else if let Some(band) = Band::from_name(o) {
                    CellSource::BandOnsets { band, dots }
                } else {
                    return Err(format!(
                        "`onsets`: unknown stem or band \"{o}\" (expected a stem: drums, bass, \
                         vocals, other; or a drum band: kick, snare, toms, cymbals)"
                    ));
                }
            }
        };
        check_source(source)?;
        Ok(source)
    }
}

impl RawMap {
    fn fingers(&self) -> [&RawFinger; 5] {
        [
            &self.thumb,
            &self.index,
            &self.middle,
            &self.ring,
            &self.pinky,
        ]
    }
}

impl TryFrom<RawMap> for GloveMap {
    type Error = GloveError;

    fn try_from(raw: RawMap) -> Result<GloveMap, GloveError> {
        let mut map = GloveMap::off();
        for (finger, raw_finger) in Finger::ALL.into_iter().zip(raw.fingers()) {
            for (cell, raw_cell) in [&raw_finger.cell0, &raw_finger.cell1]
                .into_iter()
                .enumerate()
            {
                map.cells[finger.index()][cell] =
                    raw_cell.to_source().map_err(|reason| GloveError::Map {
                        finger: finger.name(),
                        cell: CELL_KEYS[cell],
                        reason,
                    })?;
            }
        }
        Ok(map)
    }
}

impl From<GloveMap> for RawMap {
    fn from(map: GloveMap) -> RawMap {
        let finger = |f: Finger| RawFinger {
            cell0: map.get(f, 0).into(),
            cell1: map.get(f, 1).into(),
        };
        RawMap {
            thumb: finger(Finger::Thumb),
            index: finger(Finger::Index),
            middle: finger(Finger::Middle),
            ring: finger(Finger::Ring),
            pinky: finger(Finger::Pinky),
        }
    }
}
