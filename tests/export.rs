//! `render --export FILE.csv|FILE.ahap` through the binary: the CSV holds the pattern file's
//! frames, the AHAP the features' drum onsets and bass levels; an unknown extension is
//! refused before anything is rendered or written.

use std::path::Path;
use std::process::Command;

use tactus_glove::export::from_csv;
use tactus_glove::{Features, Pattern};

#[test]
fn exports_match_the_pattern_and_features() {
    let d = tempfile::tempdir().unwrap();
    let song = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/demo.ogg");
    let (pat, feat, csv, ahap) = (
        d.path().join("p.json"),
        d.path().join("f.json"),
        d.path().join("p.csv"),
        d.path().join("p.AHAP"),
    );
    let o = Command::new(env!("CARGO_BIN_EXE_tactus"))
        .arg("render")
        .arg(&song)
        .arg("-o")
        .arg(&pat)
        .arg("--features")
        .arg(&feat)
        .arg("--export")
        .arg(&csv)
        .arg("--export")
        .arg(&ahap)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let p = Pattern::from_path(&pat).unwrap();
    let f = Features::from_path(&feat).unwrap();
    let rows = from_csv(&std::fs::read_to_string(&csv).unwrap()).unwrap();
    assert_eq!(rows.len(), p.frames.len());
    for (i, (t, frame)) in rows.iter().enumerate() {
        assert_eq!(*frame, p.frames[i], "bin {i}");
        assert!((t - p.frame_time_s(i)).abs() < 1e-9);
    }
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&ahap).unwrap()).unwrap();
    let events = doc["Pattern"].as_array().unwrap();
    let count = |ty: &str| {
        events
            .iter()
            .filter(|e| e["Event"]["EventType"] == ty)
            .count()
    };
    let onsets: usize = ["kick", "snare", "toms", "cymbals"]
        .iter()
        .map(|b| f.onsets_s.get(*b).map_or(0, Vec::len))
        .sum();
    assert!(onsets > 0);
    assert_eq!(count("HapticTransient"), onsets);
    // One continuous event per run of equal non-zero bass levels.
    let levels = &f.levels["bass"];
    let runs = (0..levels.len())
        .filter(|&i| levels[i] > 0 && (i == 0 || levels[i - 1] != levels[i]))
        .count();
    assert!(runs > 0);
    assert_eq!(count("HapticContinuous"), runs);
    assert_eq!(doc["Version"], 1.0);
}

#[test]
fn unknown_export_extension_is_refused_before_rendering() {
    let d = tempfile::tempdir().unwrap();
    let song = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/demo.ogg");
    let pat = d.path().join("p.json");
    let o = Command::new(env!("CARGO_BIN_EXE_tactus"))
        .arg("render")
        .arg(&song)
        .arg("-o")
        .arg(&pat)
        .arg("--export")
        .arg(d.path().join("p.xlsx"))
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("unknown format"), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(!pat.exists());
}
