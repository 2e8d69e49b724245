//! `tactus eval` from files: read a features file, a truth file (or a corpus song's
//! folder), an actuation log and the pattern it played, and score them. Every error names
//! the file and keeps its cause.

use std::path::{Path, PathBuf};

use crate::glove_log::{glove_fidelity, log_mismatch, parse_actuation_log, PAPER_BIN_S};
use crate::{evaluate, EvalError, FeaturesLike, Truth};

/// Why a file could not be scored.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FileError {
    /// The file could not be read.
    #[error("reading {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The file's contents are not what they must be.
    #[error("{}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        #[source]
        source: EvalError,
    },
    /// The pattern file could not be read.
    #[error("{}", path.display())]
    Pattern {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        #[source]
        source: tactus_glove::GloveError,
    },
    /// The scores could not be computed.
    #[error("scoring the glove log")]
    Score(#[source] EvalError),
}

fn read(path: &Path) -> Result<String, FileError> {
    std::fs::read_to_string(path).map_err(|source| FileError::Read {
        path: path.to_path_buf(),
        source,
    })
}

fn parse<T>(path: &Path, r: Result<T, EvalError>) -> Result<T, FileError> {
    r.map_err(|source| FileError::Parse {
        path: path.to_path_buf(),
        source,
    })
}

/// A features file (`render --features`).
pub fn read_features(path: &Path) -> Result<FeaturesLike, FileError> {
    parse(path, FeaturesLike::from_json_str(&read(path)?))
}

/// Scores a features file against ground truth: `truth` is a `truth.json` or a corpus
/// song's folder holding one. Returns (Markdown, JSON).
pub fn eval_truth(features: &Path, truth: &Path) -> Result<(String, String), FileError> {
    let truth = if truth.is_dir() {
        truth.join("truth.json")
    } else {
        truth.to_path_buf()
    };
    let t = parse(&truth, Truth::from_json_str(&read(&truth)?))?;
    let report = evaluate(&read_features(features)?, &t);
    Ok((report.to_markdown(), report.to_json()))
}

/// Scores a virtual glove's actuation log against the pattern it played (and, given the
/// features rendered with it, against the audio). Returns (Markdown, JSON, warnings).
pub fn eval_glove_log(
    log: &Path,
    pattern: &Path,
    features: Option<&Path>,
) -> Result<(String, String, Vec<String>), FileError> {
    let pat = tactus_glove::Pattern::from_path(pattern).map_err(|source| FileError::Pattern {
        path: pattern.to_path_buf(),
        source,
    })?;
    let l = parse(log, parse_actuation_log(&read(log)?))?;
    let mut warnings: Vec<String> = log_mismatch(&l, pat.frames.len(), pat.bin_ms)
        .into_iter()
        .map(|w| format!("{}: {w}", log.display()))
        .collect();
    let f = features.map(read_features).transpose()?;
    let r = glove_fidelity(&l, &pat, f.as_ref(), PAPER_BIN_S).map_err(FileError::Score)?;
    if r.frames > 0 && r.frames_matching * 2 < r.frames {
        warnings.push(format!(
            "only {} of the pattern's {} frames appear in the log as they are in the pattern: \
             was this pattern the one played?",
            r.frames_matching, r.frames
        ));
    }
    Ok((r.to_markdown(), r.to_json(), warnings))
}
