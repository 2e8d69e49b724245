//! CSV and AHAP exports: the CSV round-trips every frame of random patterns at several bin
//! lengths; the AHAP document passes a validator written from Apple's documented keys
//! ("Representing haptic patterns in AHAP files", Core Haptics) and holds exactly the
//! events the features call for.

use std::collections::BTreeMap;

use serde_json::Value;
use tactus_glove::export::{csv_header, from_csv, to_ahap, to_csv, AHAP_MAX_CONTINUOUS_S};
use tactus_glove::{Features, Finger, Frame, GloveMap, Pattern, SourceInfo};

fn pattern(frames: Vec<Frame>, bin_ms: u32, map: GloveMap) -> Pattern {
    Pattern {
        source: SourceInfo {
            path: "song.wav".into(),
            sha256: String::new(),
            duration_s: frames.len() as f64 * f64::from(bin_ms) / 1000.0,
            sample_rate: 44100,
        },
        bin_ms,
        levels: 8,
        map,
        frames,
    }
}

/// Seeded xorshift: deterministic random frames.
fn random_frames(n: usize, seed: u64) -> Vec<Frame> {
    let mut x = seed | 1;
    (0..n)
        .map(|_| {
            let mut f = Frame::DOWN;
            for b in &mut f.0 {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                *b = (x >> 24) as u8;
            }
            f
        })
        .collect()
}

#[test]
fn csv_header_names_every_dot_in_cell_byte_order() {
    let h = csv_header();
    assert_eq!(h.len(), 81);
    assert_eq!(h[0], "time_s");
    assert_eq!(h[1], "thumb.c0.d1");
    assert_eq!(h[8], "thumb.c0.d8");
    assert_eq!(h[9], "thumb.c1.d1");
    assert_eq!(h[80], "pinky.c1.d8");
    // One raised dot, index cell 1 dot 4 (byte 3, bit 3): exactly its column is 1.
    let mut f = Frame::DOWN;
    f.0[3] = 1 << 3;
    let csv = to_csv(&pattern(vec![f], 100, GloveMap::default()));
    let rows: Vec<&str> = csv.lines().collect();
    let cols: Vec<&str> = rows[1].split(',').collect();
    let ones: Vec<&str> = (1..81)
        .filter(|&i| cols[i] == "1")
        .map(|i| h[i].as_str())
        .collect();
    assert_eq!(ones, ["index.c1.d4"]);
    assert_eq!(cols[0], "0");
    assert_eq!(f.cell(Finger::Index, 1), 8);
}

#[test]
fn csv_round_trips_random_patterns() {
    for (seed, bin_ms) in [(1u64, 100u32), (2, 25), (3, 7), (4, 33), (5, 1000)] {
        let frames = random_frames(500, seed);
        let p = pattern(frames.clone(), bin_ms, GloveMap::default());
        let rows = from_csv(&to_csv(&p)).unwrap();
        assert_eq!(rows.len(), frames.len());
        for (i, ((t, f), want)) in rows.iter().zip(&frames).enumerate() {
            assert_eq!(f, want, "bin {i}");
            // Exact: the time is written from whole milliseconds.
            assert_eq!(*t, (i as u64 * u64::from(bin_ms)) as f64 / 1000.0);
        }
    }
}

#[test]
fn csv_reader_matches_columns_by_name_and_rejects_bad_values() {
    let frames = random_frames(20, 9);
    let csv = to_csv(&pattern(frames.clone(), 100, GloveMap::default()));
    // Reverse the column order: still the same frames.
    let reversed: String = csv
        .lines()
        .map(|l| {
            let mut v: Vec<&str> = l.split(',').collect();
            v.reverse();
            v.join(",") + "\n"
        })
        .collect();
    let rows = from_csv(&reversed).unwrap();
    assert_eq!(rows.iter().map(|r| r.1).collect::<Vec<_>>(), frames);
    let bad = csv.replacen(",0", ",2", 1);
    assert!(from_csv(&bad)
        .unwrap_err()
        .to_string()
        .contains("not 0 or 1"));
    let missing = csv.replacen("thumb.c0.d1", "thumb.c0.dX", 1);
    assert!(from_csv(&missing)
        .unwrap_err()
        .to_string()
        .contains("thumb.c0.d1"));
}

/// Apple's documented AHAP structure: top-level `Version` (number), optional `Metadata`,
/// `Pattern` (array); each element holds one of `Event`, `Parameter`, `ParameterCurve`; an
/// event has `Time` (>= 0), `EventType` (HapticTransient, HapticContinuous, AudioCustom,
/// AudioContinuous), `EventDuration` for continuous events (> 0, at most 30 s for haptics),
/// and `EventParameters`, each `{ParameterID, ParameterValue}` with a haptic ID and a value
/// in 0..=1 for intensity and sharpness.
fn validate_ahap(doc: &Value) -> Result<(), String> {
    let top = doc.as_object().ok_or("not an object")?;
    for k in top.keys() {
        if !["Version", "Metadata", "Pattern"].contains(&k.as_str()) {
            return Err(format!("unknown top-level key {k}"));
        }
    }
    top.get("Version")
        .and_then(Value::as_f64)
        .ok_or("Version must be a number")?;
    let pattern = top
        .get("Pattern")
        .and_then(Value::as_array)
        .ok_or("Pattern must be an array")?;
    for (i, el) in pattern.iter().enumerate() {
        let el = el
            .as_object()
            .ok_or(format!("Pattern[{i}] not an object"))?;
        if el.len() != 1 {
            return Err(format!("Pattern[{i}] must hold exactly one entry"));
        }
        let Some(ev) = el.get("Event") else {
            if el.contains_key("Parameter") || el.contains_key("ParameterCurve") {
                continue;
            }
            return Err(format!("Pattern[{i}]: unknown entry"));
        };
        let ev = ev.as_object().ok_or("Event not an object")?;
        for k in ev.keys() {
            if ![
                "Time",
                "EventType",
                "EventDuration",
                "EventParameters",
                "EventWaveformPath",
                "EventWaveformUseVolumeEnvelope",
            ]
            .contains(&k.as_str())
            {
                return Err(format!("Pattern[{i}]: unknown Event key {k}"));
            }
        }
        let t = ev.get("Time").and_then(Value::as_f64).ok_or("Time")?;
        if t < 0.0 {
            return Err(format!("Pattern[{i}]: negative Time"));
        }
        let ty = ev
            .get("EventType")
            .and_then(Value::as_str)
            .ok_or("EventType")?;
        match ty {
            "HapticTransient" => {}
            "HapticContinuous" => {
                let d = ev
                    .get("EventDuration")
                    .and_then(Value::as_f64)
                    .ok_or(format!(
                        "Pattern[{i}]: continuous event without EventDuration"
                    ))?;
                if !(d > 0.0 && d <= 30.0) {
                    return Err(format!("Pattern[{i}]: EventDuration {d}"));
                }
            }
            "AudioCustom" | "AudioContinuous" => {}
            other => return Err(format!("Pattern[{i}]: EventType {other}")),
        }
        for p in ev
            .get("EventParameters")
            .and_then(Value::as_array)
            .ok_or("EventParameters")?
        {
            let id = p
                .get("ParameterID")
                .and_then(Value::as_str)
                .ok_or("ParameterID")?;
            let v = p
                .get("ParameterValue")
                .and_then(Value::as_f64)
                .ok_or("ParameterValue")?;
            match id {
                "HapticIntensity" | "HapticSharpness" => {
                    if !(0.0..=1.0).contains(&v) {
                        return Err(format!("Pattern[{i}]: {id} {v} outside 0..1"));
                    }
                }
                "AttackTime" | "DecayTime" | "ReleaseTime" | "Sustained" => {}
                other => return Err(format!("Pattern[{i}]: ParameterID {other}")),
            }
            if p.as_object().map_or(0, |o| o.len()) != 2 {
                return Err(format!("Pattern[{i}]: parameter with extra keys"));
            }
        }
    }
    Ok(())
}

fn events(doc: &Value, ty: &str) -> Vec<(f64, Option<f64>, f64)> {
    doc["Pattern"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| &e["Event"])
        .filter(|e| e["EventType"] == ty)
        .map(|e| {
            let sharp = e["EventParameters"]
                .as_array()
                .unwrap()
                .iter()
                .find(|p| p["ParameterID"] == "HapticSharpness")
                .unwrap()["ParameterValue"]
                .as_f64()
                .unwrap();
            (
                e["Time"].as_f64().unwrap(),
                e["EventDuration"].as_f64(),
                sharp,
            )
        })
        .collect()
}

#[test]
fn ahap_holds_drum_transients_and_bass_sharpness() {
    let mut levels = vec![0u8; 10];
    levels.splice(1..6, [3, 3, 5, 5, 5]);
    levels[8] = 8;
    let features = Features {
        hop_s: 0.01,
        bin_s: 0.1,
        levels: BTreeMap::from([("bass".to_string(), levels)]),
        onsets_s: BTreeMap::from([
            ("kick".to_string(), vec![0.0, 0.5]),
            ("snare".to_string(), vec![0.25]),
            // Not on the default map's glove: no events.
            ("vocals".to_string(), vec![0.3]),
        ]),
        ..Features::default()
    };
    let p = pattern(vec![Frame::DOWN; 10], 100, GloveMap::default());
    let doc: Value = serde_json::from_str(&to_ahap(&p, &features)).unwrap();
    validate_ahap(&doc).unwrap();
    assert_eq!(
        events(&doc, "HapticTransient"),
        [(0.0, None, 0.2), (0.25, None, 0.7), (0.5, None, 0.2)]
    );
    assert_eq!(
        events(&doc, "HapticContinuous"),
        [
            (0.1, Some(0.2), 3.0 / 8.0),
            (0.3, Some(0.3), 5.0 / 8.0),
            (0.8, Some(0.1), 1.0)
        ]
    );
    // Events in time order.
    let times: Vec<f64> = doc["Pattern"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["Event"]["Time"].as_f64().unwrap())
        .collect();
    assert!(times.windows(2).all(|w| w[0] <= w[1]));
}

#[test]
fn ahap_splits_long_bass_notes_and_the_validator_can_fail() {
    // 45 s at one level: two events, 30 s and 15 s.
    let features = Features {
        hop_s: 0.01,
        bin_s: 0.1,
        levels: BTreeMap::from([("bass".to_string(), vec![4u8; 450])]),
        ..Features::default()
    };
    let p = pattern(vec![Frame::DOWN; 450], 100, GloveMap::default());
    let doc: Value = serde_json::from_str(&to_ahap(&p, &features)).unwrap();
    validate_ahap(&doc).unwrap();
    let c = events(&doc, "HapticContinuous");
    assert_eq!(c.len(), 2);
    assert_eq!(c[0].1, Some(AHAP_MAX_CONTINUOUS_S));
    assert_eq!(c[1], (30.0, Some(15.0), 0.5));
    // The validator rejects what Core Haptics would.
    let mut broken = doc.clone();
    broken["Pattern"][0]["Event"]["EventDuration"] = Value::from(31.0);
    assert!(validate_ahap(&broken).is_err());
    let mut broken = doc.clone();
    broken["Pattern"][0]["Event"]["EventParameters"][0]["ParameterID"] = "Intensity".into();
    assert!(validate_ahap(&broken).is_err());
    let mut broken = doc;
    broken["Pattern"][0]["Event"]["Type"] = "HapticTransient".into();
    assert!(validate_ahap(&broken).is_err());
}
