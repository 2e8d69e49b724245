//! `DIR/manifest.jsonl`: one JSON record per input.
//!
//! While a batch runs, each finished input's record is appended as one line (so a batch
//! that is killed keeps what it finished); at the end the file is rewritten atomically with
//! one record per input, this run's in plan order, then the earlier records of inputs not in
//! this run whose outputs still exist. Readers take the last record of a path and skip
//! lines they cannot parse (a line cut short by a crash).

use std::collections::HashMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// The manifest's file name inside the output directory.
pub const MANIFEST: &str = "manifest.jsonl";

/// How an input ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// Rendered in this run; its outputs are written.
    Ok,
    /// Up to date from an earlier run (same source hash, options and outputs): not rendered.
    Skipped,
    /// Not rendered; `error` says why. Earlier outputs, if any, are left as they were.
    Failed,
}

/// One input's line in the manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Record {
    /// The song (absolute path).
    pub path: PathBuf,
    /// SHA-256 of the song's bytes (`null` when it could not be read).
    pub sha256: Option<String>,
    /// [`crate::RenderOptions::key`]: what the outputs were rendered with.
    pub options: serde_json::Value,
    /// How it ended.
    pub status: Status,
    /// Wall time spent on this input in this run (rendering, or checking it is up to date).
    pub seconds: f64,
    /// The one-line error when `status` is `failed`.
    pub error: Option<String>,
    /// The outputs, relative to the output directory (`a/b.pattern.json`, ...).
    #[serde(default)]
    pub outputs: Vec<PathBuf>,
}

impl Record {
    /// Whether this record's outputs can stand for a render of `sha256` with `options`
    /// that needs `outputs` (all of them recorded and present under `dir`).
    pub fn is_up_to_date(
        &self,
        dir: &Path,
        sha256: &str,
        options: &serde_json::Value,
        outputs: &[PathBuf],
    ) -> bool {
        matches!(self.status, Status::Ok | Status::Skipped)
            && self.sha256.as_deref() == Some(sha256)
            && &self.options == options
            && outputs
                .iter()
                .all(|o| self.outputs.contains(o) && dir.join(o).is_file())
    }

    /// The record as one JSON line (with its newline).
    pub fn to_line(&self) -> String {
        let mut s = serde_json::to_string(self).unwrap_or_default();
        s.push('\n');
        s
    }
}

/// The records of an existing manifest, the last one per path (an empty map when there is
/// none), in the order of their first appearance.
pub fn read(dir: &Path) -> (Vec<PathBuf>, HashMap<PathBuf, Record>) {
    let mut order = Vec::new();
    let mut map = HashMap::new();
    let Ok(text) = std::fs::read_to_string(dir.join(MANIFEST)) else {
        return (order, map);
    };
    for line in text.lines() {
        if let Ok(r) = serde_json::from_str::<Record>(line) {
            if !map.contains_key(&r.path) {
                order.push(r.path.clone());
            }
            map.insert(r.path.clone(), r);
        }
    }
    (order, map)
}

/// Appends records to the manifest as they finish.
pub struct Appender {
    file: Option<std::fs::File>,
}

impl Appender {
    /// Opens `dir/manifest.jsonl` for appending (created if missing).
    pub fn open(dir: &Path) -> std::io::Result<Appender> {
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(dir.join(MANIFEST))?;
        Ok(Appender { file: Some(file) })
    }

    /// Appends one record as one write (best effort: the final rewrite has every record).
    pub fn append(&mut self, r: &Record) {
        if let Some(f) = &mut self.file {
            if f.write_all(r.to_line().as_bytes()).is_err() {
                self.file = None;
            }
        }
    }
}

/// Rewrites the manifest atomically: `records` first, then the `earlier` records (in
/// `order`) of paths not among them whose outputs all exist.
pub fn write_final(
    dir: &Path,
    records: &[Record],
    order: &[PathBuf],
    earlier: &HashMap<PathBuf, Record>,
) -> std::io::Result<()> {
    let mut text = String::new();
    let here: std::collections::HashSet<&PathBuf> = records.iter().map(|r| &r.path).collect();
    for r in records {
        text.push_str(&r.to_line());
    }
    for p in order {
        if here.contains(p) {
            continue;
        }
        if let Some(r) = earlier.get(p) {
            if r.status != Status::Failed && r.outputs.iter().all(|o| dir.join(o).is_file()) {
                text.push_str(&r.to_line());
            }
        }
    }
    tactus_glove::write_atomic(&dir.join(MANIFEST), |w| w.write_all(text.as_bytes()))
}
