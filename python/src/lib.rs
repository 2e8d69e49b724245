//! `tactus._native`: the Rust side of the `tactus` Python package. The Python modules
//! (`tactus/__init__.py`, `tactus/eval.py`, `tactus/ray.py`) wrap these functions into
//! NumPy arrays and keyword arguments; the functions here exchange options and records as
//! JSON and arrays as little-endian bytes, so that no NumPy C API is needed (one abi3
//! wheel for every Python from 3.9).
//!
//! Every render releases the GIL ([`Python::detach`]); errors raise `tactus.TactusError`
//! with the CLI's one-line message, except that options are named as keyword arguments
//! (`levels`, `bin_ms=`), not as flags (`--levels <LEVELS>`): see [`keyword_names`].

use std::path::PathBuf;
use std::time::{Duration, Instant};

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use tactus_batch::{BatchSpec, Job, Record, RenderOptions};
use tactus_engine::render::{render as render_file, RenderOutput, RenderRequest};
use tactus_engine::resample::StreamResampler;
use tactus_engine::{Engine, ENGINE_RATE};
use tactus_glove::SourceInfo;

create_exception!(
    _native,
    TactusError,
    PyException,
    "A render or batch failed; the message is the CLI's one-line error."
);

fn fail(e: impl std::fmt::Display) -> PyErr {
    TactusError::new_err(e.to_string().replace('\n', " "))
}

/// The options from `tactus/__init__.py`'s JSON; a value of the wrong type names its
/// keyword argument (serde's own message names only a column of the JSON).
fn options(json: &str) -> PyResult<RenderOptions> {
    serde_json::from_str(json).map_err(|e| {
        let all: serde_json::Map<String, serde_json::Value> =
            serde_json::from_str(json).unwrap_or_default();
        all.into_iter()
            .find_map(|(k, v)| {
                let one = serde_json::Value::Object([(k.clone(), v)].into_iter().collect());
                let e = serde_json::from_value::<RenderOptions>(one).err()?;
                Some(fail(format!(
                    "invalid value for keyword argument '{k}': {e}"
                )))
            })
            .unwrap_or_else(|| fail(format!("options: {e}")))
    })
}

/// The Python keyword argument of each CLI flag that tactus-batch's option messages name.
const KEYWORDS: &[(&str, &str)] = &[
    ("bin-ms", "bin_ms"),
    ("drum-model", "drum_model"),
    ("drums", "drums"),
    ("kit-mask", "kit_mask"),
    ("levels", "levels"),
    ("levels-rule", "levels_rule"),
    ("map", "map"),
    ("mode", "mode"),
    ("model", "model"),
    ("note-onsets", "note_onsets"),
    ("out-dir", "out_dir"),
    ("pitch", "pitch"),
    ("profile", "profile"),
    ("separator", "separator"),
    ("stem", "stems"),
    ("threads", "threads"),
];

/// An option error in Python's words. tactus-batch words its messages for the CLI (one
/// parser for both); here clap's `'--levels <LEVELS>'` becomes `keyword argument 'levels'`,
/// `--separator htdemucs needs --model PATH` becomes `separator=htdemucs needs model=PATH`,
/// and a flag followed by a verb (`--stem does not go with ...`) becomes its bare keyword.
/// Only the flags of [`KEYWORDS`], at the start of a word, are rewritten.
fn keyword_names(msg: &str) -> String {
    let mut out = String::with_capacity(msg.len());
    let mut rest = msg;
    while let Some(i) = rest.find("--") {
        out.push_str(&rest[..i]);
        let tail = &rest[i + 2..];
        let len = tail
            .find(|c: char| !(c.is_ascii_lowercase() || c == '-'))
            .unwrap_or(tail.len());
        let at_word = out
            .chars()
            .last()
            .is_none_or(|c| c.is_whitespace() || c == '\'' || c == '(');
        let keyword = KEYWORDS
            .iter()
            .find(|(flag, _)| at_word && *flag == &tail[..len])
            .map(|(_, kw)| *kw);
        let after = &tail[len..];
        let placeholder = after
            .strip_prefix(" <")
            .and_then(|s| s.find(">'").map(|j| &s[j + 1..]));
        match (keyword, placeholder) {
            (Some(kw), Some(closing_quote)) if out.ends_with('\'') => {
                out.pop();
                out.push_str("keyword argument '");
                out.push_str(kw);
                rest = closing_quote;
            }
            (Some(kw), _) => {
                out.push_str(kw);
                let verb = ["is ", "does ", "needs "];
                rest = match after.strip_prefix(' ') {
                    Some(value) if !verb.iter().any(|v| value.starts_with(v)) => {
                        out.push('=');
                        value
                    }
                    _ => after,
                };
            }
            (None, _) => {
                out.push_str("--");
                rest = tail;
            }
        }
    }
    out.push_str(rest);
    out
}

/// [`fail`] for an option error: the message names keyword arguments.
fn option_error(e: impl std::fmt::Display) -> PyErr {
    fail(keyword_names(&e.to_string()))
}

fn le_f32(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn le_f64(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// `d[name] = {key: bytes(values)}` for one per-stem or per-band group of the features.
fn set_group<V>(
    d: &Bound<'_, PyDict>,
    name: &str,
    m: &std::collections::BTreeMap<String, V>,
    bytes: impl Fn(&V) -> Vec<u8>,
) -> PyResult<()> {
    let g = PyDict::new(d.py());
    for (k, v) in m {
        g.set_item(k, PyBytes::new(d.py(), &bytes(v)))?;
    }
    d.set_item(name, g)
}

/// The result dictionary that `tactus.Result` is built from.
fn result_dict<'py>(py: Python<'py>, out: &RenderOutput) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let frames: Vec<u8> = out.pattern.frames.iter().flat_map(|f| f.0).collect();
    d.set_item("frames", PyBytes::new(py, &frames))?;
    d.set_item("bin_s", out.features.bin_s)?;
    d.set_item("hop_s", out.features.hop_s)?;
    d.set_item("duration_s", out.duration_s)?;
    let f = &out.features;
    set_group(&d, "pitch_hz", &f.pitch_hz, |v| le_f32(v))?;
    set_group(&d, "levels", &f.levels, |v| v.clone())?;
    set_group(&d, "onsets_s", &f.onsets_s, |v| le_f64(v))?;
    set_group(&d, "beats", &f.beats, |v| v.clone())?;
    d.set_item("latency_ms", out.latency.clone())?;
    let stages: Vec<(String, f64)> = out
        .times
        .stages
        .iter()
        .map(|(n, t)| (n.clone(), t.as_secs_f64()))
        .collect();
    d.set_item("stages_s", stages)?;
    d.set_item("warnings", out.warnings.clone())?;
    d.set_item("report", out.report_text())?;
    d.set_item("separator", out.separator)?;
    d.set_item(
        "stems",
        out.stems.iter().map(|s| s.name()).collect::<Vec<_>>(),
    )?;
    d.set_item("pattern_json", out.pattern.to_json_string().map_err(fail)?)?;
    d.set_item(
        "features_json",
        out.features.to_json_string().map_err(fail)?,
    )?;
    Ok(d)
}

/// Renders a song file: `options_json` is a JSON object of CLI-named options.
#[pyfunction]
fn render<'py>(py: Python<'py>, path: PathBuf, options_json: &str) -> PyResult<Bound<'py, PyDict>> {
    let opts = options(options_json)?;
    let (config, stems) = opts.to_config(true).map_err(option_error)?;
    let req = RenderRequest {
        input: path,
        stems,
        config,
    };
    let out = py.detach(|| render_file(&req, &mut |_| {})).map_err(fail)?;
    result_dict(py, &out)
}

/// Samples per block fed to the engine, as the file driver does (1 s at 88.2 kHz).
const BLOCK: usize = 88_200;

/// Renders interleaved f32 samples held in memory (no file): the same engine, resampler
/// and block sizes as a file render, so the same samples give the same frames.
fn render_samples(
    samples: &[f32],
    channels: usize,
    rate: u32,
    opts: &RenderOptions,
) -> Result<RenderOutput, Box<dyn std::error::Error + Send + Sync>> {
    let t_all = Instant::now();
    let (mut config, stems) = opts
        .to_config(true)
        .map_err(|e| keyword_names(&e.to_string()))?;
    if !stems.is_empty() {
        return Err("stems are not supported by render_array (use render with a file)".into());
    }
    if channels == 0 || channels > 64 {
        return Err(format!("{channels} channels: expected 1..=64").into());
    }
    if rate == 0 {
        return Err("sample rate must be at least 1 Hz".into());
    }
    config.pipeline = true;
    let mut engine = Engine::new(config)?;
    let frames_n = samples.len() / channels;
    let mut non_finite = 0usize;
    let mut clean = |x: f32| {
        if x.is_finite() {
            x
        } else {
            non_finite += 1;
            0.0
        }
    };
    // Planar left/right: the first two channels (a mono signal feeds both).
    let mut left = Vec::with_capacity(frames_n);
    let mut right = Vec::with_capacity(frames_n);
    for fr in samples.chunks_exact(channels) {
        let l = clean(fr[0]);
        left.push(l);
        right.push(if channels > 1 { clean(fr[1]) } else { l });
    }
    let mut resampler = if rate != ENGINE_RATE {
        Some(StreamResampler::new(rate, ENGINE_RATE, 2)?)
    } else {
        None
    };
    let mut out = vec![Vec::new(), Vec::new()];
    let mut t_resample = Duration::ZERO;
    let n_blocks = frames_n.div_ceil(BLOCK).max(1);
    for b in 0..n_blocks {
        let (lo, hi) = (b * BLOCK, ((b + 1) * BLOCK).min(frames_n));
        let last = b + 1 == n_blocks;
        let t = Instant::now();
        match &mut resampler {
            Some(rs) => {
                rs.process(&[&left[lo..hi], &right[lo..hi]], &mut out);
                if last {
                    rs.finish(&mut out);
                }
            }
            None => {
                out[0].extend_from_slice(&left[lo..hi]);
                out[1].extend_from_slice(&right[lo..hi]);
            }
        }
        t_resample += t.elapsed();
        let len = out[0].len().min(out[1].len());
        engine.process(&out[0][..len], &out[1][..len], &[]);
        out[0].clear();
        out[1].clear();
        if let Some(e) = engine.take_separator_error() {
            return Err(e.into());
        }
    }
    engine.finish();
    if let Some(e) = engine.take_separator_error() {
        return Err(e.into());
    }
    let mut warnings = Vec::new();
    if non_finite > 0 {
        warnings.push(format!(
            "samples: {non_finite} NaN/Inf samples replaced by 0"
        ));
    }
    let bytes: Vec<u8> = le_f32(samples);
    let duration_s = engine.samples_in() as f64 / ENGINE_RATE as f64;
    let source = SourceInfo {
        path: "<array>".into(),
        sha256: tactus_glove::sha256_hex(&bytes[..])?,
        duration_s,
        sample_rate: rate,
    };
    Ok(RenderOutput::from_engine(
        &engine,
        source,
        engine.frames(),
        &[("resample", t_resample)],
        t_all,
        warnings,
    ))
}

/// Renders interleaved little-endian f32 samples (`channels` per frame, `sample_rate` Hz).
#[pyfunction]
fn render_array<'py>(
    py: Python<'py>,
    samples: &[u8],
    channels: usize,
    sample_rate: u32,
    options_json: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let opts = options(options_json)?;
    let x: Vec<f32> = samples
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    let out = py
        .detach(|| render_samples(&x, channels, sample_rate, &opts))
        .map_err(fail)?;
    result_dict(py, &out)
}

/// The batch plan: `([(source, base), ...], [(input, reason), ...])`. `skip`: the output
/// directory (never an input).
#[pyfunction]
#[pyo3(signature = (inputs, skip=None))]
#[allow(clippy::type_complexity)]
fn batch_plan(
    inputs: Vec<PathBuf>,
    skip: Option<PathBuf>,
) -> PyResult<(Vec<(PathBuf, PathBuf)>, Vec<(PathBuf, String)>)> {
    let plan = tactus_batch::plan(&inputs, skip.as_deref()).map_err(fail)?;
    Ok((
        plan.jobs.into_iter().map(|j| (j.source, j.base)).collect(),
        plan.rejected,
    ))
}

/// The options key records carry (JSON), checking the options.
#[pyfunction]
fn batch_key(options_json: &str) -> PyResult<String> {
    let opts = options(options_json)?;
    let (_, key) = tactus_batch::prepare(&opts, 1).map_err(option_error)?;
    Ok(key.to_string())
}

/// The failed record (JSON) of an input the plan rejected.
#[pyfunction]
fn batch_rejected(path: PathBuf, why: &str, options_json: &str) -> PyResult<String> {
    let key: serde_json::Value = serde_json::from_str(&batch_key(options_json)?).map_err(fail)?;
    serde_json::to_string(&tactus_batch::rejected_record(&path, why, &key)).map_err(fail)
}

/// Renders one job of a batch into `out_dir` exactly as `tactus render --out-dir` does and
/// returns its manifest record (JSON). `earlier_json`: the manifest's record of this song.
#[pyfunction]
#[pyo3(signature = (source, base, out_dir, options_json, features=false, job_threads=1, earlier_json=None))]
#[allow(clippy::too_many_arguments)]
fn batch_job(
    py: Python<'_>,
    source: PathBuf,
    base: PathBuf,
    out_dir: PathBuf,
    options_json: &str,
    features: bool,
    job_threads: usize,
    earlier_json: Option<&str>,
) -> PyResult<String> {
    let opts = options(options_json)?;
    let (config, key) = tactus_batch::prepare(&opts, job_threads.max(1)).map_err(option_error)?;
    let earlier: Option<Record> = earlier_json.and_then(|j| serde_json::from_str(j).ok());
    let mut spec = BatchSpec::new(out_dir, opts);
    spec.features = features;
    spec.jobs = 1;
    spec.job_threads = job_threads.max(1);
    let job = Job { source, base };
    let record =
        py.detach(|| tactus_batch::render_job(&job, &spec, &config, &key, earlier.as_ref()));
    serde_json::to_string(&record).map_err(fail)
}

/// The manifest's records, by path (JSON strings), from `out_dir/manifest.jsonl`.
#[pyfunction]
fn batch_read_manifest(out_dir: PathBuf) -> PyResult<Vec<(PathBuf, String)>> {
    let (order, map) = tactus_batch::manifest::read(&out_dir);
    order
        .into_iter()
        .filter_map(|p| map.get(&p).map(|r| (p.clone(), r)))
        .map(|(p, r)| Ok((p, serde_json::to_string(r).map_err(fail)?)))
        .collect()
}

/// Writes the final manifest from the records (JSON strings), as the CLI batch does.
#[pyfunction]
fn batch_finish(out_dir: PathBuf, records_json: Vec<String>) -> PyResult<()> {
    let records = records_json
        .iter()
        .map(|j| serde_json::from_str::<Record>(j).map_err(fail))
        .collect::<PyResult<Vec<_>>>()?;
    std::fs::create_dir_all(&out_dir).map_err(fail)?;
    tactus_batch::finish(&out_dir, &records).map_err(fail)
}

/// Scores a features file (JSON text) against a truth file (JSON text): the report as JSON,
/// as `tactus eval FEATURES --truth TRUTH --json`.
#[pyfunction]
fn eval_report(features_json: &str, truth_json: &str) -> PyResult<String> {
    let f = tactus_eval::FeaturesLike::from_json_str(features_json).map_err(fail)?;
    let t = tactus_eval::Truth::from_json_str(truth_json).map_err(fail)?;
    Ok(tactus_eval::evaluate(&f, &t).to_json())
}

/// Onset precision, recall, F-measure and matches (mir_eval's `onset.f_measure`).
#[pyfunction]
#[pyo3(signature = (reference, estimate, window_s=0.05))]
fn onset_scores(reference: Vec<f64>, estimate: Vec<f64>, window_s: f64) -> PyResult<String> {
    let s = tactus_eval::onset::onset_scores(&reference, &estimate, window_s).map_err(fail)?;
    serde_json::to_string(&s).map_err(fail)
}

/// Raw pitch and chroma accuracy, voicing recall and false alarm (mir_eval's melody).
#[pyfunction]
#[pyo3(signature = (ref_hz, est_hz, cent_tolerance=50.0))]
fn melody_scores(ref_hz: Vec<f64>, est_hz: Vec<f64>, cent_tolerance: f64) -> PyResult<String> {
    let s = tactus_eval::melody::melody_scores(&ref_hz, &est_hz, cent_tolerance).map_err(fail)?;
    serde_json::to_string(&s).map_err(fail)
}

/// Level accuracy: (exact, within one level).
#[pyfunction]
fn level_accuracy(truth: Vec<u8>, estimate: Vec<u8>) -> PyResult<(f64, f64)> {
    tactus_eval::levels::level_accuracy(&truth, &estimate).map_err(fail)
}

/// Signal-to-distortion ratio in dB.
#[pyfunction]
fn sdr_db(reference: Vec<f32>, estimate: Vec<f32>) -> PyResult<f64> {
    tactus_eval::sdr::sdr_db(&reference, &estimate).map_err(fail)
}

/// `m.add_function(wrap_pyfunction!(f, m)?)?` for each `f`.
macro_rules! add_functions {
    ($m:ident; $($f:ident),+ $(,)?) => {
        $($m.add_function(wrap_pyfunction!($f, $m)?)?;)+
    };
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("TactusError", m.py().get_type::<TactusError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("ENGINE_RATE", ENGINE_RATE)?;
    add_functions![
        m; render, render_array, batch_plan, batch_key, batch_rejected, batch_job,
        batch_read_manifest, batch_finish, eval_report, onset_scores, melody_scores,
        level_accuracy, sdr_db
    ];
    Ok(())
}
