//! A separator whose network fails at run time reports it through the trait
//! ([`Separator::take_error`]) instead of returning silence: a deliberately broken Spleeter
//! stand-in (models/make_broken_spleeter.py) passes the loader's port checks but returns a
//! `vocals` output of the wrong shape on every call. Own file: ONNX Runtime loads once per
//! process.
#![cfg(feature = "onnx")]

#[path = "fixtures/onnx/support.rs"]
mod support;

use tactus_separate::onnx::spleeter::SpleeterSeparator;
use tactus_separate::onnx::OnnxConfig;
use tactus_separate::{SeparateError, Separator, Stem, StemOutput, StemSet};

#[test]
fn wrong_output_shape_is_reported_through_the_trait() {
    let Some(lib) = support::runtime_or_skip("wrong_output_shape_is_reported_through_the_trait")
    else {
        return;
    };
    let cfg = OnnxConfig {
        library: Some(lib),
        model: support::fixture("spleeter_wrong_output.onnx"),
        threads: 1,
    };
    let stems = StemSet::EMPTY.with(Stem::Vocals).with(Stem::Drums);
    let mut sep: Box<dyn Separator> =
        Box::new(SpleeterSeparator::new(44_100, stems, &cfg).expect("the ports look right"));
    assert!(sep.take_error().is_none(), "nothing has run yet");
    // 3 s of a tone: at least one network call (segments of 11.9 s run at finish).
    let x: Vec<f32> = (0..3 * 44_100)
        .map(|i| 0.3 * (i as f32 * 440.0 * std::f32::consts::TAU / 44_100.0).sin())
        .collect();
    let mut out = StemOutput::new();
    let mut error = None;
    for block in x.chunks(4096) {
        sep.process(block, block, &mut out);
        error = error.or_else(|| sep.take_error());
    }
    sep.finish(&mut out);
    error = error.or_else(|| sep.take_error());
    // The stream lengths still hold (the contract), but the error is reported once.
    assert_eq!(out.get(Stem::Vocals).len(), x.len());
    let e = error.expect("the wrong output shape must be reported");
    let msg = e.to_string();
    assert!(
        matches!(
            e,
            SeparateError::Failed {
                backend: "spleeter",
                ..
            }
        ),
        "{msg}"
    );
    assert!(msg.contains("vocals") && msg.contains("values"), "{msg}");
    assert!(!msg.contains('\n'), "one line: {msg}");
    assert!(sep.take_error().is_none(), "taken");
    println!("{msg}");
}
