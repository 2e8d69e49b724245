//! The crate's error type: everything that can go wrong reading maps, patterns, features
//! and hex frames. Processing (rendering, encoding, decoding) never fails.

use std::path::PathBuf;

pub use crate::glove::HexError;

/// Errors from parsing or validating glove maps and files.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GloveError {
    /// Reading or writing failed.
    #[error("I/O error: {0}")]
    Io(#[from] std::io::Error),
    /// An error while handling a named file.
    #[error("{}: {source}", path.display())]
    InFile {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        #[source]
        source: Box<GloveError>,
    },
    /// A song is no longer the file its pattern was rendered from.
    #[error("{} changed while it was rendered", .0.display())]
    SongChanged(PathBuf),
    /// The input is empty (or only whitespace).
    #[error("empty input: expected a {what} JSON document")]
    Empty {
        /// "pattern" or "features".
        what: &'static str,
    },
    /// The input is not valid JSON.
    #[error("not valid JSON (line {line}, column {column}): {message}")]
    NotJson {
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// The parser's message.
        message: String,
    },
    /// The `format` key names another kind of file.
    #[error("wrong format {found}: expected \"{expected}\"")]
    WrongFormat {
        /// What this reader accepts.
        expected: &'static str,
        /// What was found (as JSON).
        found: String,
    },
    /// The file is newer (or older) than this reader.
    #[error(
        "{what} version {found} is not supported: this build of tactus reads version \
         {supported}{}",
        upgrade_hint(*.found, *.supported)
    )]
    UnsupportedVersion {
        /// "pattern" or "features".
        what: &'static str,
        /// The version in the file.
        found: u64,
        /// The version this reader understands.
        supported: u64,
    },
    /// A required key is absent.
    #[error("missing field `{0}`")]
    MissingField(&'static str),
    /// A key holds a value of the wrong type or range.
    #[error("invalid `{field}`: {reason}")]
    InvalidField {
        /// Dotted path of the key, e.g. `source.sample_rate` or `levels.bass[3]`.
        field: String,
        /// Why.
        reason: String,
    },
    /// A pattern frame is malformed.
    #[error("frame {index}: {source}")]
    BadFrame {
        /// 0-based frame (bin) index.
        index: usize,
        /// What is wrong with its hex.
        #[source]
        source: HexError,
    },
    /// A hex frame is malformed.
    #[error("bad hex frame: {0}")]
    Hex(#[from] HexError),
    /// A map cell is invalid.
    #[error("map: {finger}.{cell}: {reason}")]
    Map {
        /// Finger name.
        finger: &'static str,
        /// `cell0` or `cell1`.
        cell: &'static str,
        /// Why.
        reason: String,
    },
    /// A map file is not valid TOML or has unknown keys.
    #[error("map: {0}")]
    MapSyntax(String),
    /// `--map NAME`: neither a file nor a built-in map.
    #[error("{name}: no such file, and no built-in map of that name (built-in: {known})")]
    UnknownMap {
        /// What was asked for.
        name: String,
        /// The built-in names, comma-separated.
        known: String,
    },
}

fn upgrade_hint(found: u64, supported: u64) -> &'static str {
    if found > supported {
        "; upgrade tactus to read it"
    } else {
        ""
    }
}

impl GloveError {
    /// Wraps `self` with the file it came from.
    pub fn in_file(self, path: impl Into<PathBuf>) -> GloveError {
        GloveError::InFile {
            path: path.into(),
            source: Box::new(self),
        }
    }

    /// The innermost error (skipping [`GloveError::InFile`] wrappers).
    pub fn root(&self) -> &GloveError {
        match self {
            GloveError::InFile { source, .. } => source.root(),
            e => e,
        }
    }
}

/// `s` with its control characters escaped (`\n`, `\u{1b}`, ...), so that an error that
/// quotes user input (a key, a value) stays on one line.
pub(crate) fn one_line(s: impl Into<String>) -> String {
    let s = s.into();
    if !s.chars().any(char::is_control) {
        return s;
    }
    s.chars()
        .map(|c| {
            if c.is_control() {
                c.escape_debug().to_string()
            } else {
                c.to_string()
            }
        })
        .collect()
}
