//! The pattern file v1 (`render -o`, docs/design.md "Files", a contract): the glove frames of a
//! whole song, one per bin, plus where they came from and the map that made them.
//!
//! ```json
//! { "format": "tactus-pattern", "version": 1,
//!   "source": { "path": "...", "sha256": "...", "duration_s": 0.0, "sample_rate": 44100 },
//!   "bin_ms": 100, "levels": 8, "map": { ... },
//!   "frames": [ "20 hex chars = 10 cell bytes", ... ] }
//! ```
//!
//! Frame `i` holds the pins for time `[i * bin_ms, (i + 1) * bin_ms)` ms. Reading validates
//! everything (format, version, types, `bin_ms > 0`, `levels >= 1`, every frame's hex) and
//! names the offending key or frame index; unknown keys are ignored so later minor additions
//! stay readable. Writing is pretty-printed, one frame per line, so patterns diff well.

use std::io::Read;
use std::path::Path;

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::glove::Frame;
use crate::json::{check_header, invalid, parse_object, required, typed};
use crate::{GloveError, GloveMap};

/// The `format` value of a pattern file.
pub const PATTERN_FORMAT: &str = "tactus-pattern";
/// The pattern file version this build reads and writes.
pub const PATTERN_VERSION: u64 = 1;

/// Where a pattern's audio came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SourceInfo {
    /// The input path as given on the command line.
    pub path: String,
    /// SHA-256 of the input file's bytes, 64 lower-case hex digits (see [`sha256_hex`]).
    pub sha256: String,
    /// Duration of the decoded audio in seconds.
    pub duration_s: f64,
    /// Sample rate of the decoded audio in Hz.
    pub sample_rate: u32,
}

/// A rendered pattern. See the module docs for the file layout.
#[derive(Debug, Clone, PartialEq)]
pub struct Pattern {
    /// The audio the pattern was rendered from.
    pub source: SourceInfo,
    /// Bin length in ms (> 0).
    pub bin_ms: u32,
    /// Number of pitch levels (>= 1).
    pub levels: u8,
    /// The map that produced the frames.
    pub map: GloveMap,
    /// One frame per bin.
    pub frames: Vec<Frame>,
}

#[derive(Serialize)]
struct PatternOut<'a> {
    format: &'static str,
    version: u64,
    source: &'a SourceInfo,
    bin_ms: u32,
    levels: u8,
    map: &'a GloveMap,
    frames: Vec<String>,
}

impl Pattern {
    /// Checks the values that the types alone do not: `bin_ms > 0`, `levels >= 1`, a finite,
    /// non-negative duration.
    pub fn validate(&self) -> Result<(), GloveError> {
        if self.bin_ms == 0 {
            return Err(invalid("bin_ms", "must be at least 1 ms"));
        }
        if self.levels == 0 {
            return Err(invalid("levels", "must be at least 1"));
        }
        if !(self.source.duration_s.is_finite() && self.source.duration_s >= 0.0) {
            return Err(invalid(
                "source.duration_s",
                format!("must be finite and >= 0, found {}", self.source.duration_s),
            ));
        }
        Ok(())
    }

    /// Start time of frame `index` in seconds.
    pub fn frame_time_s(&self, index: usize) -> f64 {
        index as f64 * f64::from(self.bin_ms) / 1000.0
    }

    /// The pattern as pretty-printed JSON (validated first).
    pub fn to_json_string(&self) -> Result<String, GloveError> {
        self.validate()?;
        let out = PatternOut {
            format: PATTERN_FORMAT,
            version: PATTERN_VERSION,
            source: &self.source,
            bin_ms: self.bin_ms,
            levels: self.levels,
            map: &self.map,
            frames: self.frames.iter().map(Frame::to_hex).collect(),
        };
        let mut s = serde_json::to_string_pretty(&out)
            .map_err(|e| GloveError::Io(std::io::Error::other(e)))?;
        s.push('\n');
        Ok(s)
    }

    /// Parses a pattern from JSON bytes.
    pub fn from_slice(bytes: &[u8]) -> Result<Pattern, GloveError> {
        let obj = parse_object(bytes, "pattern")?;
        check_header(&obj, PATTERN_FORMAT, "pattern", PATTERN_VERSION, true)?;
        let source_value = obj
            .get("source")
            .ok_or(GloveError::MissingField("source"))?;
        let source_obj = source_value
            .as_object()
            .ok_or_else(|| invalid("source", "expected an object"))?;
        let source = SourceInfo {
            path: sub(source_obj, "source.path", "path")?,
            sha256: sub(source_obj, "source.sha256", "sha256")?,
            duration_s: sub(source_obj, "source.duration_s", "duration_s")?,
            sample_rate: sub(source_obj, "source.sample_rate", "sample_rate")?,
        };
        let bin_ms: u32 = required(&obj, "bin_ms")?;
        let levels: u8 = required(&obj, "levels")?;
        let map: GloveMap = required(&obj, "map")?;
        let hex: Vec<String> = required(&obj, "frames")?;
        let frames = hex
            .iter()
            .enumerate()
            .map(|(index, h)| {
                Frame::from_hex(h).map_err(|e| match e {
                    GloveError::Hex(source) => GloveError::BadFrame { index, source },
                    other => other,
                })
            })
            .collect::<Result<Vec<Frame>, GloveError>>()?;
        let pattern = Pattern {
            source,
            bin_ms,
            levels,
            map,
            frames,
        };
        pattern.validate()?;
        Ok(pattern)
    }
}

fn sub<T: serde::de::DeserializeOwned>(
    obj: &crate::json::Object,
    field: &'static str,
    key: &str,
) -> Result<T, GloveError> {
    let v = obj.get(key).ok_or(GloveError::MissingField(field))?;
    typed(v, field)
}

/// SHA-256 of everything `r` yields, as 64 lower-case hex digits.
pub fn sha256_hex(mut r: impl Read) -> std::io::Result<String> {
    let mut hasher = Sha256::new();
    let mut buf = [0u8; 64 * 1024];
    loop {
        let n = r.read(&mut buf)?;
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
    }
    let digest = hasher.finalize();
    let mut s = String::with_capacity(64);
    for b in digest {
        use std::fmt::Write as _;
        let _ = write!(s, "{b:02x}");
    }
    Ok(s)
}

/// SHA-256 of a file's bytes, as 64 lower-case hex digits.
pub fn sha256_file(path: impl AsRef<Path>) -> std::io::Result<String> {
    sha256_hex(std::fs::File::open(path)?)
}

crate::json::json_file_readers!(Pattern);
