//! Input discovery: audio found by content, the output base names, collisions, the output
//! directory left out, and the options key.

use std::fs;
use std::path::{Path, PathBuf};

use tactus_batch::discover::looks_like_audio;
use tactus_batch::{plan, RenderOptions};

fn wav(path: &Path) {
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: 8000,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    for i in 0..800 {
        w.write_sample((i % 100) as i16).unwrap();
    }
    w.finalize().unwrap();
}

#[test]
fn container_signatures() {
    let demo = fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/demo.ogg"
    ))
    .unwrap();
    assert!(looks_like_audio(&demo[..16]));
    for yes in [
        &b"RIFF\x24\x00\x00\x00WAVEfmt "[..],
        b"fLaC\x00\x00\x00\x22",
        b"ID3\x04\x00\x00\x00\x00",
        b"\x00\x00\x00\x20ftypM4A \x00\x00",
        b"FORM\x00\x00\x00\x00AIFF",
        b"\xFF\xFB\x90\x64",         // MPEG-1 layer III, 128 kbit/s, 44.1 kHz
        b"\xFF\xF1\x50\x80",         // ADTS AAC
        b"\x1A\x45\xDF\xA3\x01\x00", // Matroska / WebM
    ] {
        assert!(looks_like_audio(yes), "{yes:?}");
    }
    for no in [
        &b"liner notes\n"[..],
        b"\x89PNG\r\n\x1a\n",
        b"%PDF-1.7",
        b"RIFF\x24\x00\x00\x00AVI ",
        b"\xFF\xFF\xFF\xFF", // no valid MPEG header (bit-rate index 15)
        b"",
    ] {
        assert!(!looks_like_audio(no), "{no:?}");
    }
}

#[test]
fn a_directory_is_walked_for_audio_by_content() {
    let tmp = tempfile::tempdir().unwrap();
    let lib = tmp.path().join("lib");
    fs::create_dir_all(lib.join("a/b")).unwrap();
    wav(&lib.join("x.wav"));
    wav(&lib.join("a/noext"));
    wav(&lib.join("a/b/y.WAV"));
    fs::write(lib.join("a/readme.md"), "# hi").unwrap();
    fs::write(lib.join("a/broken.flac"), "not flac").unwrap();
    // The output directory inside the library is never an input.
    fs::create_dir_all(lib.join("out")).unwrap();
    wav(&lib.join("out/old.wav"));
    let p = plan(std::slice::from_ref(&lib), Some(&lib.join("out"))).unwrap();
    let bases: Vec<PathBuf> = p.jobs.iter().map(|j| j.base.clone()).collect();
    assert_eq!(
        bases,
        ["a/b/y", "a/broken", "a/noext", "x"]
            .map(PathBuf::from)
            .to_vec()
    );
    assert!(p.jobs.iter().all(|j| j.source.is_absolute()));
    assert!(p.rejected.is_empty());
}

#[test]
fn outputs_that_collide_are_refused_and_missing_inputs_reported() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    wav(&d.join("song.wav"));
    wav(&d.join("song.mp3")); // same base name "song"
    let p = plan(
        &[
            d.to_path_buf(),
            d.join("song.wav"),
            d.join("nope.wav"),
            d.join("*.zzz"),
        ],
        None,
    )
    .unwrap();
    assert_eq!(p.jobs.len(), 1, "{p:?}");
    let why: Vec<&str> = p.rejected.iter().map(|(_, w)| w.as_str()).collect();
    assert_eq!(p.rejected.len(), 3, "{why:?}");
    assert!(why.iter().any(|w| w.contains("would overwrite")), "{why:?}");
    assert!(why.contains(&"no such file or directory"), "{why:?}");
    assert!(why.contains(&"the pattern matches no file"), "{why:?}");
}

#[test]
fn options_key_fills_defaults_and_rejects_bad_values() {
    let a = RenderOptions::default().key().unwrap();
    let b = RenderOptions {
        separator: Some("spectral".into()),
        levels: Some(8),
        bin_ms: Some(100),
        threads: Some(3), // speed only
        ..RenderOptions::default()
    }
    .key()
    .unwrap();
    assert_eq!(a, b);
    let c = RenderOptions {
        levels: Some(4),
        ..RenderOptions::default()
    }
    .key()
    .unwrap();
    assert_ne!(a, c);
    for bad in [
        RenderOptions {
            levels: Some(9),
            ..RenderOptions::default()
        },
        RenderOptions {
            pitch: Some("crepe".into()),
            ..RenderOptions::default()
        },
        RenderOptions {
            separator: Some("htdemucs".into()),
            ..RenderOptions::default()
        },
    ] {
        let e = bad.key().unwrap_err().to_string();
        assert_eq!(e.lines().count(), 1, "{e}");
    }
}
