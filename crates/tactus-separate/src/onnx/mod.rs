//! Learned separators run with ONNX Runtime (cargo feature `onnx`).
//!
//! | backend | model | stems | latency at 44.1 kHz |
//! |---|---|---|---|
//! | [`spleeter::SpleeterSeparator`] | Deezer Spleeter 2stems U-Nets (MIT), `models/spleeter-2stems.onnx` | vocals from the network; drums, bass, other split from the accompaniment by [`crate::spectral`] | one 512-frame segment + STFT ≈ 12.0 s |
//! | [`htdemucs::HtDemucsSeparator`] | Demucs v4 `htdemucs` (MIT) exported by `models/export_htdemucs.py` | all four from the network | one 7.8 s segment |
//!
//! Besides the separators, [`adtlib::AdtLib`] transcribes kick, snare and hi-hat onsets
//! with ADTLib's networks (`models/adtlib.onnx`, built by `models/setup_adtlib.sh`).
//!
//! **Runtime.** ONNX Runtime is loaded at run time (`ort`'s `load-dynamic`), never at
//! build time, from the path in [`OnnxConfig::library`] or else from the environment
//! variable `ORT_DYLIB_PATH`. `models/setup_onnxruntime.sh` installs the exact version
//! `ort 2.0.0-rc.15` needs (1.31.1) into `vendor/`. ONNX Runtime allows one library and
//! one environment per process: the first successful load wins and later paths are
//! ignored (see [`runtime`]). A missing library or model, or a model whose inputs and
//! outputs do not match the backend's contract, is an [`OnnxError`], never a panic.
//!
//! **Allocation.** The separators allocate their own buffers at construction only, but
//! ONNX Runtime allocates its output tensors inside every network call (once per
//! segment, i.e. every several seconds of audio), which is outside our control.
//!
//! **Panics**: none. Buffer sizes are fixed at construction and every index is derived
//! from them; the library path is made absolute before `ort` sees it (`ort` would panic
//! resolving a relative path if the executable's path were unknown).
//!
//! **Threads and memory.** [`OnnxConfig::threads`] sets ONNX Runtime's intra-op threads
//! (the CLI's `--threads`, default the available cores). ONNX Runtime's memory pattern is
//! off: for htdemucs it pre-planned a block that raised the peak RSS of one segment from
//! 1.78 GB to 3.16 GB.
//!
//! **Instrumentation.** Both backends keep a [`crate::SegmentStats`] (network calls, time
//! per call, time outside the network, inverse FFTs), read through
//! [`crate::Separator::segment_stats`]; it costs a few `Instant` reads per call.
//!
//! **Blocking.** A network call runs inside `process` / `finish` on the caller's thread
//! (seconds on 2 cores): run these separators off the real-time thread.

pub mod adtlib;
pub mod htdemucs;
pub mod spleeter;

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use ort::environment::Environment;
use ort::session::builder::GraphOptimizationLevel;
use ort::session::Session;
use ort::value::{TensorElementType, ValueType};

use crate::SeparateError;

/// Environment variable that names the ONNX Runtime shared library.
pub const ORT_DYLIB_ENV: &str = "ORT_DYLIB_PATH";

/// Errors raised when an ONNX separator is constructed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum OnnxError {
    /// No library path was given and `ORT_DYLIB_PATH` is unset, or the file is missing.
    #[error(
        "ONNX Runtime not found{}: run models/setup_onnxruntime.sh and set ORT_DYLIB_PATH",
        .0.as_ref().map(|p| format!(" at {}", p.display())).unwrap_or_default()
    )]
    RuntimeNotFound(Option<PathBuf>),
    /// The library exists but could not be loaded (not a shared library, wrong version).
    #[error("ONNX Runtime at {path} could not be loaded: {reason}")]
    RuntimeLoad {
        /// The library path.
        path: PathBuf,
        /// ONNX Runtime's or the loader's message.
        reason: String,
    },
    /// The model file does not exist.
    #[error("model not found at {0}: run models/setup_models.sh (or the export script named in models/README.md)")]
    ModelNotFound(PathBuf),
    /// ONNX Runtime rejected the model file.
    #[error("model {path} could not be loaded: {reason}")]
    ModelLoad {
        /// The model path.
        path: PathBuf,
        /// ONNX Runtime's message.
        reason: String,
    },
    /// The model loads but its inputs / outputs are not what the backend expects.
    #[error("model {path} is not a {backend} model: {reason}")]
    WrongModel {
        /// The model path.
        path: PathBuf,
        /// The backend that rejected it.
        backend: &'static str,
        /// What differs from the contract.
        reason: String,
    },
    /// A configuration error shared with the other backends.
    #[error(transparent)]
    Separate(#[from] SeparateError),
}

/// Where the runtime and the model are, and how many threads ONNX Runtime may use.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct OnnxConfig {
    /// The ONNX Runtime shared library; `None` reads `ORT_DYLIB_PATH`.
    pub library: Option<PathBuf>,
    /// The `.onnx` model file.
    pub model: PathBuf,
    /// Intra-op threads for ONNX Runtime (the threads one network call may use); 0 lets
    /// ONNX Runtime choose (its default: the physical cores). The CLI's `--threads`.
    pub threads: usize,
}

impl OnnxConfig {
    /// A configuration for `model` with the library from `ORT_DYLIB_PATH`.
    pub fn new(model: impl Into<PathBuf>) -> Self {
        OnnxConfig {
            library: None,
            model: model.into(),
            threads: 0,
        }
    }
}

static ENVIRONMENT: Mutex<Option<Environment>> = Mutex::new(None);

/// The library path to load: `library`, else `ORT_DYLIB_PATH`; checked to exist.
pub fn library_path(library: Option<&Path>) -> Result<PathBuf, OnnxError> {
    let path = match library {
        Some(p) => p.to_path_buf(),
        None => match std::env::var_os(ORT_DYLIB_ENV) {
            Some(p) if !p.is_empty() => PathBuf::from(p),
            _ => return Err(OnnxError::RuntimeNotFound(None)),
        },
    };
    if !path.is_file() {
        return Err(OnnxError::RuntimeNotFound(Some(path)));
    }
    // `ort` resolves relative paths against the executable's directory; make it absolute.
    Ok(std::path::absolute(&path).unwrap_or(path))
}

/// Loads ONNX Runtime (once per process) and returns the process-wide environment.
///
/// The first call that succeeds fixes the library for the whole process; later calls
/// return the same environment whatever `library` says (ONNX Runtime cannot be loaded
/// twice). A failed call leaves nothing behind, so a later call may name another path.
pub fn runtime(library: Option<&Path>) -> Result<Environment, OnnxError> {
    let mut env = ENVIRONMENT.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(e) = env.as_ref() {
        return Ok(e.clone());
    }
    let path = library_path(library)?;
    let load_err = |reason: String| OnnxError::RuntimeLoad {
        path: path.clone(),
        reason,
    };
    let builder = ort::init_from(&path).map_err(|e| load_err(e.to_string()))?;
    let built = builder
        .with_name("tactus")
        .build()
        .map_err(|e| load_err(e.to_string()))?;
    *env = Some(built.clone());
    Ok(built)
}

/// What a backend expects of one model input or output: name and shape (`None` = any).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Port {
    pub name: &'static str,
    pub shape: &'static [Option<i64>],
}

/// Loads ONNX Runtime and `cfg.model`, and checks the model's inputs and outputs against
/// the backend's contract (float32 tensors with these names, ranks and fixed sizes).
pub(crate) fn open_session(
    cfg: &OnnxConfig,
    backend: &'static str,
    inputs: &[Port],
    outputs: &[Port],
) -> Result<Session, OnnxError> {
    let env = runtime(cfg.library.as_deref())?;
    if !cfg.model.is_file() {
        return Err(OnnxError::ModelNotFound(cfg.model.clone()));
    }
    let model_err = |reason: String| OnnxError::ModelLoad {
        path: cfg.model.clone(),
        reason,
    };
    let mut builder = Session::builder(&env)
        .map_err(|e| model_err(e.to_string()))?
        .with_optimization_level(GraphOptimizationLevel::All)
        .map_err(|e| model_err(e.to_string()))?
        // ONNX Runtime's memory pattern pre-plans one block for all intermediate tensors
        // of a run; with htdemucs it raised the peak from 1.78 GB to 3.16 GB (measured
        // with /usr/bin/time, one segment). The arena still reuses freed blocks.
        .with_memory_pattern(false)
        .map_err(|e| model_err(e.to_string()))?;
    if cfg.threads > 0 {
        builder = builder
            .with_intra_threads(cfg.threads)
            .map_err(|e| model_err(e.to_string()))?;
    }
    let session = builder
        .commit_from_file(&cfg.model)
        .map_err(|e| model_err(e.to_string()))?;
    let wrong = |reason: String| OnnxError::WrongModel {
        path: cfg.model.clone(),
        backend,
        reason,
    };
    check_ports("input", session.inputs(), inputs).map_err(wrong)?;
    check_ports("output", session.outputs(), outputs).map_err(wrong)?;
    Ok(session)
}

fn check_ports(kind: &str, have: &[ort::value::Outlet], want: &[Port]) -> Result<(), String> {
    let names: Vec<&str> = have.iter().map(|o| o.name()).collect();
    for port in want {
        let Some(outlet) = have.iter().find(|o| o.name() == port.name) else {
            return Err(format!(
                "no {kind} named `{}` (the model's {kind}s are {names:?})",
                port.name
            ));
        };
        let ValueType::Tensor { ty, shape, .. } = outlet.dtype() else {
            return Err(format!("{kind} `{}` is not a tensor", port.name));
        };
        if *ty != TensorElementType::Float32 {
            return Err(format!("{kind} `{}` is {ty:?}, not float32", port.name));
        }
        let ok = shape.len() == port.shape.len()
            && shape
                .iter()
                .zip(port.shape)
                .all(|(&d, w)| w.is_none_or(|w| d < 0 || d == w));
        if !ok {
            let want: Vec<String> = port
                .shape
                .iter()
                .map(|d| d.map_or("?".into(), |d| d.to_string()))
                .collect();
            return Err(format!(
                "{kind} `{}` has shape {:?}, expected [{}]",
                port.name,
                &shape[..],
                want.join(", ")
            ));
        }
    }
    Ok(())
}
