//! tactus-eval's melody and onset metrics against mir_eval 0.8.2's values for the same
//! inputs (fixtures written by `mir_eval_oracle.py`). Tolerance 1e-6: both sides compute
//! ratios of small integer counts, so any real disagreement (one frame or one onset out of
//! at most 200) is at least 5e-3; 1e-6 only absorbs the JSON float round trip.
use serde_json::Value;
use tactus_eval::melody::{melody_scores, CENT_TOLERANCE};
use tactus_eval::onset::{onset_scores, WINDOW_S};

const TOL: f64 = 1e-6;

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_f64().expect("number"))
        .collect()
}

fn load() -> (Value, Value) {
    let cases: Value =
        serde_json::from_str(include_str!("fixtures/mir_eval_cases.json")).expect("cases parse");
    let expected: Value = serde_json::from_str(include_str!("fixtures/mir_eval_expected.json"))
        .expect("expected parse");
    (cases, expected)
}

#[test]
fn melody_matches_mir_eval() {
    let (cases, expected) = load();
    let cases = cases["melody"].as_array().unwrap();
    let expected = expected["melody"].as_array().unwrap();
    assert_eq!(cases.len(), expected.len());
    assert!(cases.len() >= 5);
    for (c, e) in cases.iter().zip(expected) {
        let s = melody_scores(&floats(&c["ref_hz"]), &floats(&c["est_hz"]), CENT_TOLERANCE)
            .expect("scores");
        let name = c["name"].as_str().unwrap();
        for (key, got) in [
            ("raw_pitch_accuracy", s.raw_pitch_accuracy),
            ("raw_chroma_accuracy", s.raw_chroma_accuracy),
            ("voicing_recall", s.voicing_recall),
            ("voicing_false_alarm", s.voicing_false_alarm),
        ] {
            let want = e[key].as_f64().unwrap();
            assert!(
                (got - want).abs() <= TOL,
                "{name}/{key}: tactus {got} vs mir_eval {want}"
            );
        }
    }
}

#[test]
fn onsets_match_mir_eval() {
    let (cases, expected) = load();
    let cases = cases["onsets"].as_array().unwrap();
    let expected = expected["onsets"].as_array().unwrap();
    assert_eq!(cases.len(), expected.len());
    assert!(cases.len() >= 5);
    for (c, e) in cases.iter().zip(expected) {
        let s = onset_scores(&floats(&c["ref"]), &floats(&c["est"]), WINDOW_S).expect("scores");
        let name = c["name"].as_str().unwrap();
        for (key, got) in [
            ("precision", s.precision),
            ("recall", s.recall),
            ("f_measure", s.f_measure),
        ] {
            let want = e[key].as_f64().unwrap();
            assert!(
                (got - want).abs() <= TOL,
                "{name}/{key}: tactus {got} vs mir_eval {want}"
            );
        }
    }
}
