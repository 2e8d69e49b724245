//! The default bass tracker on a mix (the learned bass salience times the harmonic sum on the
//! spectral separator's bass stem) through the binary, scored by `tactus eval` against the
//! committed chorale fixtures' exact f0 (`corpus/fixtures/`, excerpts of two tuning songs
//! that the bass model was never trained on).
//!
//! Floors sit about 0.05 under the measured raw pitch accuracy (0.947 on `bwv347`, 0.968 on
//! `bwv66-6`), so a regression of the model, its front end or the engine wiring
//! fails here; `--pitch auto-shs` (the previous default) must give another bass track.
use std::path::{Path, PathBuf};

mod common;

fn fixtures() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("corpus/fixtures");
    let mut v: Vec<PathBuf> = std::fs::read_dir(&root)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("truth.json").exists() && p.join("mix.flac").exists())
        .collect();
    v.sort();
    assert_eq!(v.len(), 2, "fixtures in {}", root.display());
    v
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Renders `song`'s mix with `args`; returns the bass pitch track and its RPA from `tactus eval`.
fn bass(song: &Path, args: &[&str]) -> (Vec<serde_json::Value>, f64) {
    let dir = tempfile::tempdir().unwrap();
    let (pat, feat, ev) = (
        dir.path().join("p.json"),
        dir.path().join("f.json"),
        dir.path().join("e.json"),
    );
    let mix = song.join("mix.flac");
    let mut render: Vec<&std::ffi::OsStr> = vec![
        "render".as_ref(),
        mix.as_os_str(),
        "-o".as_ref(),
        pat.as_os_str(),
        "--features".as_ref(),
        feat.as_os_str(),
    ];
    render.extend(args.iter().map(std::ffi::OsStr::new));
    common::tactus_ok(&render);
    let rpa = common::eval(&feat, song, &ev)["stems"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["stem"] == "bass")
        .expect("bass row")["rpa"]
        .as_f64()
        .unwrap();
    (
        json(&feat)["pitch_hz"]["bass"].as_array().unwrap().clone(),
        rpa,
    )
}

#[test]
fn the_default_bass_on_a_mix_meets_its_floor() {
    for (song, floor) in fixtures().iter().zip([0.90, 0.92]) {
        let (track, rpa) = bass(song, &[]);
        assert!(
            rpa >= floor,
            "{}: bass RPA {rpa:.3} < {floor}",
            song.display()
        );
        let (old, old_rpa) = bass(song, &["--pitch", "auto-shs"]);
        assert_eq!(track.len(), old.len());
        assert_ne!(
            track,
            old,
            "{}: auto-shs gave the default's track",
            song.display()
        );
        assert!(
            old_rpa > 0.5,
            "{}: auto-shs bass RPA {old_rpa:.3}",
            song.display()
        );
    }
}
