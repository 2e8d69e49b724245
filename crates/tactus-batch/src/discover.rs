//! Which files a batch renders, and where each one's outputs go.
//!
//! An input is a file (always rendered, whatever it holds: a broken one is reported), a
//! directory (walked recursively; a file is taken when its first bytes are those of an
//! audio container, or when its extension is an audio one, so that a broken `.mp3` is
//! reported rather than silently left out) or a glob (`*`, `?`, `[...]`, `**`; every
//! matching file is taken, as for a file). The outputs of `ROOT/a/b.mp3` are named
//! `a/b` + suffix, where `ROOT` is the directory given, the directory of a file given, or
//! the part of a glob before its first wildcard.

use std::collections::HashMap;
use std::fs::File;
use std::io::Read;
use std::path::{Component, Path, PathBuf};

use crate::BatchError;

/// One song of the batch.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Job {
    /// The song, as an absolute path (the pattern's `source.path`).
    pub source: PathBuf,
    /// The outputs' base name relative to the output directory: `a/b` for `ROOT/a/b.mp3`.
    pub base: PathBuf,
}

/// A batch plan: the jobs in a stable order (inputs in the order given, each expanded in
/// sorted order), and the inputs that could not be planned (a missing path, an output name
/// taken by an earlier input), each with its one-line reason.
#[derive(Debug, Clone, Default)]
pub struct Plan {
    /// What to render.
    pub jobs: Vec<Job>,
    /// (path, reason) for inputs that will be reported as failed without rendering.
    pub rejected: Vec<(PathBuf, String)>,
}

/// File extensions taken as audio even when the content is not recognised.
const AUDIO_EXTENSIONS: &[&str] = &[
    "wav", "wave", "flac", "mp3", "mp2", "mp1", "ogg", "oga", "opus", "m4a", "mp4", "aac", "aif",
    "aiff", "aifc", "caf", "mka", "webm", "wv", "alac",
];

/// Whether `head` (a file's first bytes) starts like an audio container or stream that the
/// decoder knows: RIFF/WAVE, FLAC, ID3-tagged or bare MPEG audio, Ogg, MP4/M4A, AIFF, CAF,
/// Matroska/WebM, ADTS AAC.
pub fn looks_like_audio(head: &[u8]) -> bool {
    let starts = |m: &[u8]| head.len() >= m.len() && &head[..m.len()] == m;
    if starts(b"RIFF") && head.len() >= 12 && (&head[8..12] == b"WAVE" || &head[8..12] == b"RF64") {
        return true;
    }
    if starts(b"RF64") || starts(b"fLaC") || starts(b"ID3") || starts(b"OggS") || starts(b"caff") {
        return true;
    }
    if starts(b"FORM") && head.len() >= 12 && (&head[8..12] == b"AIFF" || &head[8..12] == b"AIFC") {
        return true;
    }
    if head.len() >= 12 && &head[4..8] == b"ftyp" {
        return true;
    }
    if starts(&[0x1A, 0x45, 0xDF, 0xA3]) {
        return true;
    }
    // An MPEG audio frame header (11 sync bits, a valid layer and bit-rate index) or ADTS.
    if head.len() >= 3 && head[0] == 0xFF && head[1] & 0xE0 == 0xE0 {
        let layer = (head[1] >> 1) & 0x3;
        let version = (head[1] >> 3) & 0x3;
        if layer == 0 {
            // ADTS (AAC): layer bits are always 0, the version bit 0 or 1.
            return head[1] & 0xF6 == 0xF0;
        }
        let bitrate = head[2] >> 4;
        return version != 1 && bitrate != 0xF && (head[2] >> 2) & 0x3 != 0x3;
    }
    false
}

fn has_audio_extension(p: &Path) -> bool {
    p.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| AUDIO_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// Whether a file found in a directory is taken: audio by content, or by extension.
fn is_audio_file(p: &Path) -> bool {
    if has_audio_extension(p) {
        return true;
    }
    let mut head = [0u8; 16];
    let Ok(mut f) = File::open(p) else {
        return false;
    };
    let mut n = 0;
    while n < head.len() {
        match f.read(&mut head[n..]) {
            Ok(0) | Err(_) => break,
            Ok(k) => n += k,
        }
    }
    looks_like_audio(&head[..n])
}

fn has_glob_chars(s: &str) -> bool {
    s.contains(['*', '?', '['])
}

/// The base name for `path` under `root`: the relative path without its extension.
fn base_of(path: &Path, root: &Path) -> PathBuf {
    let rel = path.strip_prefix(root).unwrap_or(path);
    let rel: PathBuf = rel
        .components()
        .filter(|c| matches!(c, Component::Normal(_)))
        .collect();
    match rel.file_stem() {
        Some(stem) => rel.with_file_name(stem),
        None => rel,
    }
}

fn absolute(p: &Path) -> PathBuf {
    std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf())
}

/// Every file under `dir`, sorted, recursively (symbolic links to files followed, to
/// directories not, so a link cycle cannot trap the walk).
fn walk(dir: &Path, out: &mut Vec<PathBuf>) -> std::io::Result<()> {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    entries.sort();
    for p in entries {
        let meta = std::fs::symlink_metadata(&p)?;
        if meta.is_dir() {
            walk(&p, out)?;
        } else if p.is_file() {
            out.push(p);
        }
    }
    Ok(())
}

/// Expands the inputs into jobs (see the module docs). `skip` is a directory whose files
/// are never inputs (the output directory, when it lies inside an input directory).
pub fn plan(inputs: &[PathBuf], skip: Option<&Path>) -> Result<Plan, BatchError> {
    let skip = skip.map(absolute);
    let mut plan = Plan::default();
    // (source, base) in order; then collisions are resolved.
    let mut found: Vec<(PathBuf, PathBuf)> = Vec::new();
    for input in inputs {
        let text = input.to_string_lossy();
        if input.is_dir() {
            let mut files = Vec::new();
            walk(input, &mut files).map_err(|e| BatchError::Input {
                path: input.clone(),
                why: e.to_string(),
            })?;
            for f in files {
                let abs = absolute(&f);
                if skip.as_ref().is_some_and(|s| abs.starts_with(s)) {
                    continue;
                }
                if is_audio_file(&f) {
                    let base = base_of(&f, input);
                    found.push((abs, base));
                }
            }
        } else if input.exists() {
            let root = input.parent().unwrap_or(Path::new(""));
            found.push((absolute(input), base_of(input, root)));
        } else if has_glob_chars(&text) {
            let root: PathBuf = input
                .components()
                .take_while(|c| !has_glob_chars(&c.as_os_str().to_string_lossy()))
                .collect();
            let paths = glob::glob(&text).map_err(|e| BatchError::Input {
                path: input.clone(),
                why: format!("bad pattern: {e}"),
            })?;
            let mut n = 0;
            let mut matched: Vec<PathBuf> = paths.filter_map(Result::ok).collect();
            matched.sort();
            for f in matched {
                if f.is_file() {
                    n += 1;
                    found.push((absolute(&f), base_of(&f, &root)));
                }
            }
            if n == 0 {
                plan.rejected
                    .push((input.clone(), "the pattern matches no file".into()));
            }
        } else {
            plan.rejected
                .push((input.clone(), "no such file or directory".into()));
        }
    }
    let mut taken: HashMap<PathBuf, PathBuf> = HashMap::new();
    let mut seen = std::collections::HashSet::new();
    for (source, base) in found {
        if !seen.insert(source.clone()) {
            continue; // the same file through two inputs
        }
        if let Some(first) = taken.get(&base) {
            plan.rejected.push((
                source,
                format!(
                    "its outputs {} would overwrite those of {}",
                    base.display(),
                    first.display()
                ),
            ));
            continue;
        }
        taken.insert(base.clone(), source.clone());
        plan.jobs.push(Job { source, base });
    }
    Ok(plan)
}
