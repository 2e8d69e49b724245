//! Pattern and features files: hand-written golden fixtures, round trips, and every bad
//! case giving the expected error.

use tactus_glove::{Features, Finger, Frame, GloveError, GloveMap, HexError, Pattern, SourceInfo};

const FIXTURE_PATTERN: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/fixtures/pattern-v1.json"
);
const FIXTURE_FEATURES: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/fixtures/features-v1.json"
);

fn fixture_text() -> String {
    std::fs::read_to_string(FIXTURE_PATTERN).unwrap()
}

#[test]
fn golden_pattern_parses_to_known_values() {
    let p = Pattern::from_path(FIXTURE_PATTERN).unwrap();
    assert_eq!(p.source.path, "songs/demo.wav");
    assert_eq!(
        p.source.sha256,
        "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"
    );
    assert_eq!(p.source.duration_s, 0.3);
    assert_eq!(p.source.sample_rate, 44100);
    assert_eq!((p.bin_ms, p.levels), (100, 8));
    assert_eq!(p.map, GloveMap::default());
    assert_eq!(p.frames.len(), 3);
    assert_eq!(p.frames[0], Frame::DOWN);
    // Frame 1: bass level 1 (dot 7 = 0x40), bass onset, kick.
    assert_eq!(p.frames[1].cell(Finger::Thumb, 0), 0x40);
    assert_eq!(p.frames[1].cell(Finger::Thumb, 1), 0xFF);
    assert_eq!(p.frames[1].cell(Finger::Index, 0), 0xFF);
    assert_eq!(p.frames[1].raised_dots(), 17);
    // Frame 2 (upper-case hex accepted): bass level 8 (dot 4), cymbals, other level 8.
    assert_eq!(p.frames[2].0, [0x08, 0, 0, 0, 0, 0xFF, 0, 0, 0x08, 0]);
    assert!((p.frame_time_s(2) - 0.2).abs() < 1e-12);
}

#[test]
fn pattern_round_trip() {
    let p = Pattern::from_path(FIXTURE_PATTERN).unwrap();
    let mut buf = Vec::new();
    p.write_to(&mut buf).unwrap();
    let again = Pattern::read_from(&buf[..]).unwrap();
    assert_eq!(again, p);
    let text = String::from_utf8(buf).unwrap();
    assert!(text.contains("\"format\": \"tactus-pattern\""));
    assert!(
        text.contains("\"0800000000ff00000800\""),
        "written lower-case"
    );

    // Through a file, with a non-default map and odd values.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.json");
    let q = Pattern {
        source: SourceInfo {
            path: "a \"quoted\" ü.wav".into(),
            sha256: String::new(),
            duration_s: 1.0 / 3.0,
            sample_rate: 48000,
        },
        bin_ms: 25,
        levels: 12,
        map: GloveMap::from_toml_str(tactus_glove::map::DRUMS_ONLY_MAP_TOML).unwrap(),
        frames: (0..=255u8).map(|i| Frame([i; 10])).collect(),
    };
    q.write_to_path(&path).unwrap();
    assert_eq!(Pattern::from_path(&path).unwrap(), q);
}

/// The fixture with one top-level key replaced (or removed with `None`).
fn with_key(key: &str, value: Option<serde_json::Value>) -> String {
    let mut v: serde_json::Value = serde_json::from_str(&fixture_text()).unwrap();
    let o = v.as_object_mut().unwrap();
    match value {
        Some(x) => {
            o.insert(key.into(), x);
        }
        None => {
            o.remove(key);
        }
    }
    v.to_string()
}

fn pattern_err(text: &str) -> GloveError {
    match Pattern::from_json_str(text) {
        Ok(_) => panic!("accepted: {text}"),
        Err(e) => e,
    }
}

#[test]
fn pattern_bad_cases() {
    use serde_json::json;

    let e = pattern_err(&with_key("format", Some(json!("tactus-features"))));
    assert!(
        matches!(
            e,
            GloveError::WrongFormat {
                expected: "tactus-pattern",
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("\"tactus-features\""));

    let e = pattern_err(&with_key("version", Some(json!(2))));
    assert!(
        matches!(
            e,
            GloveError::UnsupportedVersion {
                found: 2,
                supported: 1,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("upgrade tactus"), "{e}");
    let e = pattern_err(&with_key("version", Some(json!(0))));
    assert!(
        matches!(e, GloveError::UnsupportedVersion { found: 0, .. }),
        "{e}"
    );
    assert!(!e.to_string().contains("upgrade"), "{e}");
    let e = pattern_err(&with_key("version", Some(json!("1"))));
    assert!(
        matches!(&e, GloveError::InvalidField { field, .. } if field == "version"),
        "{e}"
    );

    let frames = |f: serde_json::Value| with_key("frames", Some(f));
    let e = pattern_err(&frames(json!(["00000000000000000000", "000"])));
    assert!(
        matches!(
            e,
            GloveError::BadFrame {
                index: 1,
                source: HexError::OddLength { chars: 3 }
            }
        ),
        "{e}"
    );
    let e = pattern_err(&frames(json!(["0000000000000000000x"])));
    assert!(
        matches!(
            e,
            GloveError::BadFrame {
                index: 0,
                source: HexError::NotHex {
                    position: 19,
                    character: 'x'
                }
            }
        ),
        "{e}"
    );
    assert_eq!(
        e.to_string(),
        "frame 0: character 'x' at position 19 is not a hex digit"
    );
    let e = pattern_err(&frames(json!([
        "00000000000000000000",
        "00000000000000000000",
        "000000000000000000"
    ])));
    assert!(
        matches!(
            e,
            GloveError::BadFrame {
                index: 2,
                source: HexError::WrongLength { bytes: 9 }
            }
        ),
        "{e}"
    );
    let e = pattern_err(&frames(json!([17])));
    assert!(
        matches!(&e, GloveError::InvalidField { field, .. } if field == "frames"),
        "{e}"
    );

    for key in [
        "format", "version", "source", "bin_ms", "levels", "map", "frames",
    ] {
        let e = pattern_err(&with_key(key, None));
        assert!(
            matches!(e, GloveError::MissingField(k) if k == key),
            "{key}: {e}"
        );
    }
    let mut v: serde_json::Value = serde_json::from_str(&fixture_text()).unwrap();
    v["source"].as_object_mut().unwrap().remove("sample_rate");
    let e = pattern_err(&v.to_string());
    assert!(
        matches!(e, GloveError::MissingField("source.sample_rate")),
        "{e}"
    );

    let e = pattern_err(&with_key("bin_ms", Some(json!(0))));
    assert!(
        matches!(&e, GloveError::InvalidField { field, .. } if field == "bin_ms"),
        "{e}"
    );
    let e = pattern_err(&with_key("levels", Some(json!(0))));
    assert!(
        matches!(&e, GloveError::InvalidField { field, .. } if field == "levels"),
        "{e}"
    );
    let e = pattern_err(&with_key("levels", Some(json!(300))));
    assert!(
        matches!(&e, GloveError::InvalidField { field, .. } if field == "levels"),
        "{e}"
    );
    let e = pattern_err(&with_key(
        "map",
        Some(json!({"thumb": {"cell0": {"pitch": "tuba"}}})),
    ));
    assert!(
        e.to_string().contains("thumb.cell0") && e.to_string().contains("tuba"),
        "{e}"
    );

    assert!(matches!(
        pattern_err("{\"format\": \"tactus-pattern\","),
        GloveError::NotJson { .. }
    ));
    assert!(matches!(
        pattern_err("hello"),
        GloveError::NotJson { line: 1, .. }
    ));
    assert!(matches!(
        pattern_err(""),
        GloveError::Empty { what: "pattern" }
    ));
    assert!(matches!(pattern_err("  \n"), GloveError::Empty { .. }));
    assert!(matches!(
        pattern_err("[1, 2]"),
        GloveError::InvalidField { .. }
    ));

    // from_path names the file.
    let e = Pattern::from_path("/no/such/pattern.json").unwrap_err();
    assert!(
        e.to_string()
            .starts_with("/no/such/pattern.json: I/O error"),
        "{e}"
    );
    assert!(matches!(e.root(), GloveError::Io(_)));
}

#[test]
fn writing_an_invalid_pattern_fails() {
    let mut p = Pattern::from_path(FIXTURE_PATTERN).unwrap();
    p.source.duration_s = f64::NAN;
    assert!(p.to_json_string().is_err());
    p.source.duration_s = 1.0;
    p.bin_ms = 0;
    assert!(p.to_json_string().is_err());
}

#[test]
fn golden_features_parse_to_known_values() {
    let f = Features::from_path(FIXTURE_FEATURES).unwrap();
    assert_eq!((f.hop_s, f.bin_s), (0.01, 0.1));
    assert_eq!(f.pitch_hz["bass"], vec![0.0, 55.0, 55.5, 0.0]);
    assert_eq!(f.pitch_hz["vocals"], vec![220.0, 0.0, 0.0, 440.25]);
    assert!(
        !f.pitch_hz.contains_key("other"),
        "only computed stems appear"
    );
    assert_eq!(f.levels["bass"], vec![0, 5, 8]);
    assert_eq!(f.onsets_s["kick"], vec![0.0, 0.5, 1.25]);
    assert!(f.onsets_s["snare"].is_empty());
    assert_eq!(f.beats["kick"], vec![1, 0, 1]);
    assert_eq!(f.beats.len(), 2);
}

#[test]
fn features_round_trip_with_header() {
    let f = Features::from_path(FIXTURE_FEATURES).unwrap();
    let text = f.to_json_string().unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(v["format"], "tactus-features");
    assert_eq!(v["version"], 1);
    assert_eq!(Features::from_json_str(&text).unwrap(), f);

    let mut g = Features {
        hop_s: 512.0 / 44100.0,
        bin_s: 0.025,
        ..Features::default()
    };
    g.pitch_hz
        .insert("other".into(), vec![0.0, 123.456_79, f32::MAX]);
    g.onsets_s.insert("bass".into(), vec![0.1, 0.1, 0.2]);
    g.beats.insert("cymbals".into(), vec![]);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("f.json");
    g.write_to_path(&path).unwrap();
    assert_eq!(Features::from_path(&path).unwrap(), g);
    // Minimal file: only hop_s and bin_s.
    let m = Features::from_json_str(r#"{"hop_s": 0.01, "bin_s": 0.1}"#).unwrap();
    assert_eq!(
        m,
        Features {
            hop_s: 0.01,
            bin_s: 0.1,
            ..Features::default()
        }
    );
}

fn features_err(text: &str) -> GloveError {
    match Features::from_json_str(text) {
        Ok(f) => panic!("accepted {text}: {f:?}"),
        Err(e) => e,
    }
}

#[test]
fn features_bad_cases() {
    let field = |e: &GloveError| match e {
        GloveError::InvalidField { field, .. } => field.clone(),
        other => panic!("expected InvalidField, got {other:?}"),
    };
    let base = r#""hop_s": 0.01, "bin_s": 0.1"#;
    assert_eq!(
        field(&features_err(&format!(
            r#"{{{base}, "pitch_hz": {{"tuba": [1]}}}}"#
        ))),
        "pitch_hz.tuba"
    );
    assert_eq!(
        field(&features_err(&format!(
            r#"{{{base}, "pitch_hz": {{"drums": [1]}}}}"#
        ))),
        "pitch_hz.drums"
    );
    assert_eq!(
        field(&features_err(&format!(
            r#"{{{base}, "pitch_hz": {{"bass": [1, -2]}}}}"#
        ))),
        "pitch_hz.bass[1]"
    );
    assert_eq!(
        field(&features_err(&format!(
            r#"{{{base}, "pitch_hz": {{"bass": [null]}}}}"#
        ))),
        "pitch_hz"
    );
    assert_eq!(
        field(&features_err(&format!(
            r#"{{{base}, "levels": {{"kick": [1]}}}}"#
        ))),
        "levels.kick"
    );
    assert_eq!(
        field(&features_err(&format!(
            r#"{{{base}, "levels": {{"bass": [256]}}}}"#
        ))),
        "levels"
    );
    assert_eq!(
        field(&features_err(&format!(
            r#"{{{base}, "onsets_s": {{"kik": []}}}}"#
        ))),
        "onsets_s.kik"
    );
    assert_eq!(
        field(&features_err(&format!(
            r#"{{{base}, "onsets_s": {{"kick": [0.5, 0.2]}}}}"#
        ))),
        "onsets_s.kick[1]"
    );
    assert_eq!(
        field(&features_err(&format!(
            r#"{{{base}, "beats": {{"kick": [0, 2]}}}}"#
        ))),
        "beats.kick[1]"
    );
    assert_eq!(
        field(&features_err(r#"{"hop_s": 0, "bin_s": 0.1}"#)),
        "hop_s"
    );
    assert!(matches!(
        features_err(r#"{"hop_s": 0.01}"#),
        GloveError::MissingField("bin_s")
    ));
    assert!(matches!(
        features_err(&format!(r#"{{"format": "tactus-pattern", {base}}}"#)),
        GloveError::WrongFormat {
            expected: "tactus-features",
            ..
        }
    ));
    assert!(matches!(
        features_err(&format!(r#"{{"version": 2, {base}}}"#)),
        GloveError::UnsupportedVersion {
            what: "features",
            found: 2,
            supported: 1
        }
    ));
    assert!(matches!(
        features_err(""),
        GloveError::Empty { what: "features" }
    ));
    assert!(matches!(features_err("{"), GloveError::NotJson { .. }));

    let mut f = Features {
        hop_s: 0.01,
        bin_s: 0.1,
        ..Features::default()
    };
    f.pitch_hz.insert("bass".into(), vec![f32::NAN]);
    assert!(f.to_json_string().is_err(), "NaN would be written as null");
}

#[test]
fn sha256_known_value() {
    // SHA-256 of the empty string and of "abc" (FIPS 180-2 test vectors).
    assert_eq!(
        tactus_glove::sha256_hex(&b""[..]).unwrap(),
        "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"
    );
    assert_eq!(
        tactus_glove::sha256_hex(&b"abc"[..]).unwrap(),
        "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
    );
}

/// The one SHA-256 helper of the project (pattern files, `play`'s song check, the
/// renderer): FIPS 180-2 vectors, and a file longer than one read block.
#[test]
fn sha256_matches_reference_values() {
    let dir = tempfile::tempdir().unwrap();
    // FIPS 180-2 test vectors: "" and "abc".
    let write_temp = |_: &tempfile::TempDir, name: &str, bytes: &[u8]| {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };
    let p = write_temp(&dir, "empty", b"");
    assert_eq!(
        tactus_glove::sha256_file(&p).unwrap(),
        "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"
    );
    let p = write_temp(&dir, "abc", b"abc");
    assert_eq!(
        tactus_glove::sha256_file(&p).unwrap(),
        "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
    );
    // More than one 64 KiB read: 200 000 x 'a' hashed in one go by the reference
    // implementation must equal the streamed hash.
    let big = vec![b'a'; 200_000];
    let p = write_temp(&dir, "big", &big);
    use sha2::Digest;
    let want: String = sha2::Sha256::digest(&big)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    assert_eq!(tactus_glove::sha256_file(&p).unwrap(), want);
    assert!(tactus_glove::sha256_file(dir.path().join("missing")).is_err());
}
