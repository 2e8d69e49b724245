//! Tactus over a music library: many songs rendered to pattern files, one song per core.
//!
//! A batch has three steps, each usable alone (the CLI's `render INPUT... --out-dir DIR`
//! runs them all; the Python package's Ray job plans and finishes on the driver and runs
//! [`render_job`] on the workers):
//!
//! 1. [`plan`]: the inputs (files, directories walked for audio by content, globs) become
//!    [`Job`]s, each with the base name of its outputs (`ROOT/a/b.mp3` -> `a/b`);
//! 2. [`render_job`] for each job, on a pool of `jobs` threads ([`run`]): hash the song,
//!    skip it if the manifest's record says its outputs are up to date (same SHA-256, same
//!    [`RenderOptions::key`], every output present), else render it and write
//!    `DIR/a/b.pattern.json` (+ `.features.json`, + the caller's extra outputs such as a
//!    plot) atomically, as one transaction. A song that fails (undecodable, unreadable, a
//!    panic in the engine) gives a failed [`Record`] and the batch goes on;
//! 3. [`manifest::write_final`]: `DIR/manifest.jsonl`, one [`Record`] per input.
//!
//! With file-level parallelism each job runs the engine on its own thread
//! ([`tactus_engine::EngineConfig::parallel`] off) unless `job_threads` says otherwise, so
//! `jobs` songs use `jobs` cores without oversubscribing them.
//!
//! ```no_run
//! use tactus_batch::{plan, run, BatchSpec, RenderOptions};
//! let plan = plan(&["music/".into()], Some("patterns".as_ref())).unwrap();
//! let spec = BatchSpec::new("patterns".into(), RenderOptions::default());
//! let summary = run(&plan, &spec, &mut |r, done, total| {
//!     eprintln!("{done}/{total} {} {:?}", r.path.display(), r.status)
//! })
//! .unwrap();
//! assert_eq!(summary.failed, 0);
//! ```
#![forbid(unsafe_code)]

pub mod discover;
pub mod manifest;
pub mod options;

use std::collections::HashMap;
use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::Instant;

pub use discover::{plan, Job, Plan};
pub use manifest::{Record, Status, MANIFEST};
pub use options::{Command, RenderOptions};
use tactus_engine::render::{render, RenderOutput, RenderRequest};
use tactus_engine::EngineConfig;
use tactus_glove::OutputSet;

/// What can stop a batch before it starts (a failing song never does).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BatchError {
    /// An option is invalid (the CLI's one-line message).
    #[error("{0}")]
    Options(String),
    /// The glove map (`--map`) could not be read.
    #[error("--map: {0}")]
    Map(#[source] tactus_glove::GloveError),
    /// An input could not be expanded.
    #[error("{path}: {why}", path = .path.display())]
    Input {
        /// The input as given.
        path: PathBuf,
        /// Why.
        why: String,
    },
    /// The output directory could not be created or written.
    #[error("--out-dir {path}: {source}", path = .0.display(), source = .1)]
    OutDir(PathBuf, #[source] std::io::Error),
}

/// Makes one extra output's bytes from a render (e.g. the CLI's plot), or a one-line error.
pub type ExtraFn = dyn Fn(&RenderOutput) -> Result<Vec<u8>, String> + Sync;

/// An extra output per song: `DIR/a/b` + `suffix`.
pub struct Extra<'a> {
    /// Appended to the base name, e.g. `.svg`.
    pub suffix: String,
    /// Makes the bytes.
    pub make: &'a ExtraFn,
}

/// How to run a batch.
pub struct BatchSpec<'a> {
    /// The output directory (created if missing).
    pub out_dir: PathBuf,
    /// The render options (`stems` must be empty: a library has no per-song stems).
    pub options: RenderOptions,
    /// Also write `a/b.features.json`.
    pub features: bool,
    /// Further outputs per song.
    pub extras: Vec<Extra<'a>>,
    /// Songs rendered at once (0: the available cores).
    pub jobs: usize,
    /// Threads per song (0: cores / jobs, at least 1). 1 runs each song's engine on its
    /// worker thread alone; more lets the engine start its own threads and gives ONNX
    /// Runtime that many intra-op threads.
    pub job_threads: usize,
}

impl<'a> BatchSpec<'a> {
    /// A spec with the defaults: patterns only, one job per core.
    pub fn new(out_dir: PathBuf, options: RenderOptions) -> Self {
        BatchSpec {
            out_dir,
            options,
            features: false,
            extras: Vec::new(),
            jobs: 0,
            job_threads: 0,
        }
    }

    /// The number of songs rendered at once.
    pub fn jobs(&self) -> usize {
        if self.jobs == 0 {
            cores()
        } else {
            self.jobs
        }
    }

    /// Threads per song.
    pub fn job_threads(&self) -> usize {
        if self.job_threads == 0 {
            (cores() / self.jobs()).max(1)
        } else {
            self.job_threads
        }
    }

    /// The output suffixes, in the order they are written.
    pub fn suffixes(&self) -> Vec<String> {
        let mut v = vec![".pattern.json".to_string()];
        if self.features {
            v.push(".features.json".into());
        }
        v.extend(self.extras.iter().map(|e| e.suffix.clone()));
        v
    }
}

/// The available cores ([`std::thread::available_parallelism`]).
pub fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// How a batch ended.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Summary {
    /// Inputs rendered.
    pub ok: usize,
    /// Inputs up to date from an earlier run.
    pub skipped: usize,
    /// Inputs that failed (planned and rejected ones).
    pub failed: usize,
}

/// `base` + `suffix` as a relative path.
fn with_suffix(base: &Path, suffix: &str) -> PathBuf {
    let mut s = base.as_os_str().to_os_string();
    s.push(suffix);
    PathBuf::from(s)
}

/// The engine configuration and the options key a batch renders with.
pub fn prepare(
    options: &RenderOptions,
    job_threads: usize,
) -> Result<(EngineConfig, serde_json::Value), BatchError> {
    if !options.stems.is_empty() {
        return Err(BatchError::Options(
            "--stem does not go with --out-dir (a library has no per-song stems)".into(),
        ));
    }
    let mut opts = options.clone();
    if job_threads > 0 && opts.threads.is_none() {
        opts.threads = Some(job_threads as u32);
    }
    let (cfg, _) = opts.to_config(job_threads != 1)?;
    Ok((cfg, options.key()?))
}

/// Renders one song of a batch and writes its outputs (see the crate docs); never fails:
/// problems become a failed [`Record`]. `earlier` is the manifest's record of this song
/// from an earlier run, if any. A panic inside the engine is caught and reported.
pub fn render_job(
    job: &Job,
    spec: &BatchSpec,
    config: &EngineConfig,
    key: &serde_json::Value,
    earlier: Option<&Record>,
) -> Record {
    let t = Instant::now();
    let outputs: Vec<PathBuf> = spec
        .suffixes()
        .iter()
        .map(|s| with_suffix(&job.base, s))
        .collect();
    let mut record = Record {
        path: job.source.clone(),
        sha256: None,
        options: key.clone(),
        status: Status::Failed,
        seconds: 0.0,
        error: None,
        outputs: outputs.clone(),
    };
    let result = std::panic::catch_unwind(AssertUnwindSafe(|| {
        let sha = tactus_glove::sha256_file(&job.source)
            .map_err(|e| format!("{}: {e}", job.source.display()))?;
        record.sha256 = Some(sha.clone());
        if earlier.is_some_and(|r| r.is_up_to_date(&spec.out_dir, &sha, key, &outputs)) {
            return Ok(Status::Skipped);
        }
        let sha = render_and_write(job, spec, config, &outputs)?;
        record.sha256 = Some(sha);
        Ok(Status::Ok)
    }));
    match result {
        Ok(Ok(status)) => record.status = status,
        Ok(Err(e)) => {
            record.error = Some(e);
            record.outputs.clear();
        }
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown".into());
            record.error = Some(format!(
                "{}: internal error (please report it): {what}",
                job.source.display()
            ));
            record.outputs.clear();
        }
    }
    record.seconds = t.elapsed().as_secs_f64();
    record
}

/// Renders and writes one song's outputs as one transaction; returns the SHA-256 the
/// pattern records.
fn render_and_write(
    job: &Job,
    spec: &BatchSpec,
    config: &EngineConfig,
    outputs: &[PathBuf],
) -> Result<String, String> {
    let targets: Vec<PathBuf> = outputs.iter().map(|o| spec.out_dir.join(o)).collect();
    if let Some(dir) = targets.first().and_then(|t| t.parent()) {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    let labels: Vec<String> = outputs.iter().map(|o| o.display().to_string()).collect();
    let pairs: Vec<(&str, &Path)> = labels
        .iter()
        .zip(&targets)
        .map(|(l, t)| (l.as_str(), t.as_path()))
        .collect();
    let mut set = OutputSet::prepare(&pairs, &[job.source.as_path()]).map_err(|e| e.to_string())?;
    let req = RenderRequest {
        input: job.source.clone(),
        stems: Vec::new(),
        config: config.clone(),
    };
    let out = render(&req, &mut |_| {}).map_err(|e| e.to_string())?;
    let mut bytes: Vec<Vec<u8>> = vec![out
        .pattern
        .to_json_string()
        .map_err(|e| e.to_string())?
        .into_bytes()];
    if spec.features {
        bytes.push(
            out.features
                .to_json_string()
                .map_err(|e| e.to_string())?
                .into_bytes(),
        );
    }
    for e in &spec.extras {
        let label = &labels[bytes.len()];
        bytes.push((e.make)(&out).map_err(|why| format!("{label}: {why}"))?);
    }
    for (i, b) in bytes.iter().enumerate() {
        set.write(i, b).map_err(|e| e.to_string())?;
    }
    set.commit().map_err(|e| e.to_string())?;
    Ok(out.pattern.source.sha256)
}

/// A failed record for an input that could not be planned.
pub fn rejected_record(path: &Path, why: &str, key: &serde_json::Value) -> Record {
    Record {
        path: std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf()),
        sha256: None,
        options: key.clone(),
        status: Status::Failed,
        seconds: 0.0,
        error: Some(format!("{}: {why}", path.display())),
        outputs: Vec::new(),
    }
}

/// Runs a whole batch: the plan's jobs on `spec.jobs()` threads, each record appended to
/// the manifest as it finishes and handed to `on_record(record, done, total)` (on the
/// calling thread), then the manifest rewritten whole. Fails only before the first song
/// (bad options, an output directory that cannot be made).
pub fn run(
    plan: &Plan,
    spec: &BatchSpec,
    on_record: &mut dyn FnMut(&Record, usize, usize),
) -> Result<Summary, BatchError> {
    let (config, key) = prepare(&spec.options, spec.job_threads())?;
    let dir = &spec.out_dir;
    std::fs::create_dir_all(dir).map_err(|e| BatchError::OutDir(dir.clone(), e))?;
    let (order, earlier) = manifest::read(dir);
    let mut appender =
        manifest::Appender::open(dir).map_err(|e| BatchError::OutDir(dir.clone(), e))?;
    let total = plan.jobs.len() + plan.rejected.len();
    let mut done = 0;
    let mut summary = Summary::default();
    let mut records: Vec<Option<Record>> = vec![None; plan.jobs.len()];
    let mut note = |r: &Record, summary: &mut Summary, done: &mut usize| {
        match r.status {
            Status::Ok => summary.ok += 1,
            Status::Skipped => summary.skipped += 1,
            Status::Failed => summary.failed += 1,
        }
        *done += 1;
        appender.append(r);
        on_record(r, *done, total);
    };
    let rejected: Vec<Record> = plan
        .rejected
        .iter()
        .map(|(p, why)| rejected_record(p, why, &key))
        .collect();
    for r in &rejected {
        note(r, &mut summary, &mut done);
    }
    let next = AtomicUsize::new(0);
    let workers = spec.jobs().min(plan.jobs.len()).max(1);
    let (tx, rx) = mpsc::channel::<(usize, Record)>();
    std::thread::scope(|s| {
        for _ in 0..workers {
            let tx = tx.clone();
            let (next, config, key, earlier) = (&next, &config, &key, &earlier);
            s.spawn(move || loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(job) = plan.jobs.get(i) else { break };
                let r = render_job(job, spec, config, key, earlier.get(&job.source));
                if tx.send((i, r)).is_err() {
                    break;
                }
            });
        }
        drop(tx);
        for (i, r) in rx {
            note(&r, &mut summary, &mut done);
            records[i] = Some(r);
        }
    });
    let mut all: Vec<Record> = records.into_iter().flatten().collect();
    all.extend(rejected);
    manifest::write_final(dir, &all, &order, &earlier)
        .map_err(|e| BatchError::OutDir(dir.join(MANIFEST), e))?;
    Ok(summary)
}

/// Writes the final manifest for records computed elsewhere (the Ray job's workers):
/// `records` in order, then the earlier manifest's records of other inputs whose outputs
/// exist.
pub fn finish(dir: &Path, records: &[Record]) -> std::io::Result<()> {
    let (order, earlier): (Vec<PathBuf>, HashMap<PathBuf, Record>) = manifest::read(dir);
    manifest::write_final(dir, records, &order, &earlier)
}

/// The README's Rust example, compiled as a doctest so that it stays true of the API.
#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
mod readme {}
