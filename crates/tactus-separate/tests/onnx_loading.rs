//! Loading the ONNX backends: a missing or broken runtime, a missing, broken or foreign
//! model all give clear errors, never panics. One test function, because ONNX Runtime
//! can be loaded only once per process: the failing loads must come first.
#![cfg(feature = "onnx")]

#[path = "fixtures/onnx/support.rs"]
mod support;

use std::path::PathBuf;

use tactus_separate::onnx::spleeter::SpleeterSeparator;
use tactus_separate::onnx::{OnnxConfig, OnnxError};
use tactus_separate::{SeparateError, Stem, StemSet};

fn cfg(library: Option<PathBuf>, model: PathBuf) -> OnnxConfig {
    OnnxConfig {
        library,
        model,
        threads: 1,
    }
}

#[test]
fn loading_errors_are_clear() {
    let vocals = StemSet::EMPTY.with(Stem::Vocals);
    let any_model = support::fixture("wrong_names.onnx");

    // 1. Missing library file.
    let missing = PathBuf::from("/nonexistent/libonnxruntime.so");
    let err = SpleeterSeparator::new(
        44_100,
        vocals,
        &cfg(Some(missing.clone()), any_model.clone()),
    )
    .err()
    .expect("missing library must fail");
    assert_eq!(err, OnnxError::RuntimeNotFound(Some(missing)));
    let msg = err.to_string();
    assert!(
        msg.contains("ONNX Runtime not found") && msg.contains("setup_onnxruntime.sh"),
        "{msg}"
    );

    // 2. A file that is not a shared library.
    let not_lib = support::fixture("not_a_model.onnx");
    let err = SpleeterSeparator::new(44_100, vocals, &cfg(Some(not_lib), any_model.clone()))
        .err()
        .expect("a non-library must fail");
    assert!(matches!(err, OnnxError::RuntimeLoad { .. }), "{err}");
    println!("non-library: {err}");

    // 3. Argument errors come before any loading.
    let err = SpleeterSeparator::new(48_000, vocals, &cfg(None, any_model.clone())).err();
    assert_eq!(
        err,
        Some(OnnxError::Separate(SeparateError::SampleRate(48_000)))
    );
    let err = SpleeterSeparator::new(44_100, StemSet::EMPTY, &cfg(None, any_model.clone())).err();
    assert_eq!(err, Some(OnnxError::Separate(SeparateError::NoStems)));

    let Some(lib) = support::runtime_or_skip("loading_errors_are_clear (model part)") else {
        return;
    };
    let lib = Some(lib);

    // 4. Missing model.
    let nowhere = PathBuf::from("/nonexistent/spleeter-2stems.onnx");
    let err = SpleeterSeparator::new(44_100, vocals, &cfg(lib.clone(), nowhere.clone()))
        .err()
        .expect("missing model must fail");
    assert_eq!(err, OnnxError::ModelNotFound(nowhere));
    assert!(err.to_string().contains("setup_models.sh"));

    // 5. Not an ONNX file.
    let err = SpleeterSeparator::new(
        44_100,
        vocals,
        &cfg(lib.clone(), support::fixture("not_a_model.onnx")),
    )
    .err()
    .expect("garbage must fail");
    assert!(matches!(err, OnnxError::ModelLoad { .. }), "{err}");

    // 6. A valid ONNX model with other input names.
    let err = SpleeterSeparator::new(44_100, vocals, &cfg(lib.clone(), any_model))
        .err()
        .expect("foreign model must fail");
    let msg = err.to_string();
    assert!(matches!(err, OnnxError::WrongModel { .. }), "{msg}");
    assert!(
        msg.contains("no input named `mag`") && msg.contains("\"x\""),
        "{msg}"
    );
    println!("foreign model: {msg}");

    // 7. Right names, wrong bin count.
    let err = SpleeterSeparator::new(
        44_100,
        vocals,
        &cfg(lib, support::fixture("wrong_shape.onnx")),
    )
    .err()
    .expect("wrong shape must fail");
    let msg = err.to_string();
    assert!(msg.contains("shape") && msg.contains("1024"), "{msg}");
    println!("wrong shape: {msg}");
}
