//! The per-instrument drum transcriber on held-out audio, through the binary: two 8 s
//! excerpts from kit families that no model was trained or tuned on
//! (`crates/tactus-engine/tests/fixtures/drums/`, made by `models/drums/make_fixtures.py`),
//! scored by `tactus eval` against their exact per-hit truth (±50 ms).
//!
//! Floors sit about 0.1 under the measured F (docs/results.md, "Drums"), so a regression of the
//! embedded model, its front end or the engine wiring fails here; the band method is
//! checked to stay far below them (the comparison the issue asks to keep reproducible).
use std::path::{Path, PathBuf};

mod common;

const CLASSES: [&str; 4] = ["kick", "snare", "toms", "cymbals"];

fn fixtures() -> Vec<PathBuf> {
    let root =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("crates/tactus-engine/tests/fixtures/drums");
    let mut v: Vec<PathBuf> = std::fs::read_dir(&root)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("truth.json").exists())
        .collect();
    v.sort();
    assert_eq!(v.len(), 2, "fixtures in {}", root.display());
    v
}

/// Renders one fixture and returns (tp, est, truth) per class from `tactus eval --json`.
fn score(song: &Path, isolated: bool, args: &[&str]) -> Vec<(f64, f64, f64)> {
    let dir = tempfile::tempdir().unwrap();
    let feat = dir.path().join("f.json");
    let ev = dir.path().join("e.json");
    let mut render: Vec<std::ffi::OsString> = vec![
        "render".into(),
        song.join("mix.flac").into(),
        "--features".into(),
        feat.clone().into(),
    ];
    if isolated {
        let map =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("crates/tactus-glove/maps/drums-only.toml");
        render.push("--stem".into());
        render.push(format!("drums={}", song.join("drums.flac").display()).into());
        render.push("--map".into());
        render.push(map.into());
    }
    render.extend(args.iter().map(|a| a.into()));
    common::tactus_ok(&render);
    let e = common::eval(&feat, song, &ev);
    CLASSES
        .iter()
        .map(|c| {
            let b = e["bands"]
                .as_array()
                .unwrap()
                .iter()
                .find(|b| b["band"] == *c)
                .unwrap_or_else(|| panic!("{c} missing"));
            let (truth, est) = (
                b["truth_onsets"].as_f64().unwrap(),
                b["est_onsets"].as_f64().unwrap(),
            );
            let tp = (b["recall"].as_f64().unwrap() * truth).round();
            (tp, est, truth)
        })
        .collect()
}

/// Pooled (P, R, F) per class over both fixtures.
fn pooled(isolated: bool, args: &[&str]) -> Vec<(f64, f64, f64)> {
    let mut sum = vec![(0.0, 0.0, 0.0); 4];
    for song in fixtures() {
        for (s, x) in sum.iter_mut().zip(score(&song, isolated, args)) {
            s.0 += x.0;
            s.1 += x.1;
            s.2 += x.2;
        }
    }
    sum.into_iter()
        .map(|(tp, est, truth)| {
            let p = if est > 0.0 { tp / est } else { 0.0 };
            let r = if truth > 0.0 { tp / truth } else { 0.0 };
            let f = if p + r > 0.0 {
                2.0 * p * r / (p + r)
            } else {
                0.0
            };
            (p, r, f)
        })
        .collect()
}

fn check(name: &str, got: &[(f64, f64, f64)], floors: [f64; 4]) {
    eprintln!("{name}: {:?}", got);
    for ((c, (p, r, f)), floor) in CLASSES.iter().zip(got).zip(floors) {
        assert!(
            *f >= floor,
            "{name} {c}: F {f:.2} (P {p:.2} R {r:.2}) below {floor}"
        );
    }
}

#[test]
fn held_out_isolated_drums() {
    check(
        "isolated, classes, offline",
        &pooled(true, &[]),
        ISOLATED_FLOORS,
    );
}

#[test]
fn held_out_isolated_drums_live_model() {
    check(
        "isolated, classes-live, offline",
        &pooled(true, &["--drums", "classes-live"]),
        LIVE_ISOLATED_FLOORS,
    );
}

#[test]
fn held_out_full_mix_through_the_default_separator() {
    check("mix, classes, offline", &pooled(false, &[]), MIX_FLOORS);
}

#[test]
fn streaming_is_within_a_few_hits_of_offline() {
    let off = pooled(true, &[]);
    let st = pooled(true, &["--mode", "streaming"]);
    for (c, (a, b)) in CLASSES.iter().zip(off.iter().zip(&st)) {
        assert!(
            (a.2 - b.2).abs() <= 0.05,
            "{c}: offline F {:.3}, streaming F {:.3}",
            a.2,
            b.2
        );
    }
}

#[test]
fn the_band_method_stays_available_and_is_worse() {
    let bands = pooled(true, &["--drums", "bands"]);
    let classes = pooled(true, &[]);
    let mean = |v: &[(f64, f64, f64)]| v.iter().map(|x| x.2).sum::<f64>() / 4.0;
    assert!(
        mean(&bands) + 0.2 < mean(&classes),
        "bands {bands:?} vs classes {classes:?}"
    );
}

/// Measured F on these two excerpts (kick, snare, toms, cymbals) minus about 0.1: isolated
/// 0.92 / 0.54 / 0.77 / 0.84, mix 0.98 / 0.53 / 0.70 / 0.86 (the model trained
/// with retune and stretch augmentation, `models/drums/README.md`). The excerpts are short
/// (12–78 hits per class), so these are regression guards; README's table has the corpus
/// figures. The isolated kick and snare floors stay where the previous model put them (0.88,
/// 0.50: measured 0.98 / 0.60 then); the toms and mix floors rose with this model. The
/// default model rebuilt from its Rebuild command
/// (docs/decisions/0044-default-drum-model-rebuilt.md) measures isolated 0.96 / 0.58 / 0.92 / 0.84
/// and mix 0.95 / 0.47 / 0.92 / 0.82 here (23 snare hits: one hit moves F by about 0.03), same
/// floors.
const ISOLATED_FLOORS: [f64; 4] = [0.88, 0.50, 0.67, 0.75];
const MIX_FLOORS: [f64; 4] = [0.88, 0.43, 0.60, 0.76];
/// The 21.6 ms live model (`--drums classes-live`) on the same excerpts, isolated: measured
/// 0.91 / 0.46 / 0.50 / 0.75, minus about 0.1 (the live model trained on the raw mix too,
/// a later draw: 0.94 / 0.47 / 0.48 / 0.74, same floors). The toms floor was lowered from 0.51 (the
/// previous live model measured 0.61) on purpose: these excerpts hold 12 tom hits (one hit
/// moves F by about 0.05), and on the 24 held-out corpus songs (569 tom hits) the retrained
/// live model's isolated toms F moved 0.61 → 0.58 while its snare rose 0.55 → 0.66 and its
/// kick 0.82 → 0.86 (`benches/drums_eval.py`, README "Drums").
const LIVE_ISOLATED_FLOORS: [f64; 4] = [0.85, 0.36, 0.40, 0.65];

/// `--drums classes --drum-model FILE` runs the transcriber with the file's network: the
/// embedded model's own file gives the default render byte for byte, the live model's file
/// gives `--drums classes-live`'s; a file that is not a model, a missing one, and a model
/// with the band method are clear errors that write nothing.
#[test]
fn a_drum_model_file_replaces_the_embedded_network() {
    use std::ffi::OsString;
    let mix = fixtures()[0].join("mix.flac");
    let weights = Path::new(env!("CARGO_MANIFEST_DIR")).join("crates/tactus-dsp/weights");
    let (embedded, live) = (weights.join("drums.bin"), weights.join("drums_live.bin"));
    let dir = tempfile::tempdir().unwrap();
    let args = |out: &Path, extra: &[&Path]| -> Vec<OsString> {
        let mut v: Vec<OsString> = vec!["render".into(), mix.clone().into(), "-o".into()];
        v.push(out.into());
        v.extend(extra.iter().map(|p| p.as_os_str().to_owned()));
        v
    };
    let features = |name: &str, extra: &[&Path]| -> Vec<u8> {
        let feat = dir.path().join(format!("{name}.json"));
        let mut a = args(&dir.path().join(format!("{name}.pattern.json")), extra);
        a.extend(["--features".into(), feat.clone().into()]);
        common::tactus_ok(&a);
        std::fs::read(&feat).unwrap()
    };
    let p = Path::new;
    let default = features("default", &[]);
    let from_file = features("file", &[p("--drum-model"), &embedded]);
    assert!(
        default == from_file,
        "the embedded model's file changed the render"
    );
    let live_cli = features("live", &[p("--drums"), p("classes-live")]);
    let live_file = features(
        "live-file",
        &[p("--drums"), p("classes-live"), p("--drum-model"), &live],
    );
    assert!(
        live_cli == live_file,
        "the live model's file changed the render"
    );
    assert!(default != live_cli, "the two models gave the same render");
    let readme = p(env!("CARGO_MANIFEST_DIR")).join("README.md");
    let missing = p("/nonexistent/drums.bin");
    for (extra, want) in [
        (vec![p("--drum-model"), &readme], "not a Tactus drum model"),
        (vec![p("--drum-model"), missing], "/nonexistent/drums.bin"),
        (
            vec![p("--drums"), p("bands"), p("--drum-model"), &embedded],
            "not bands",
        ),
    ] {
        let out_path = dir.path().join("bad.json");
        let a = args(&out_path, &extra);
        let out = common::tactus_output(&a);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(want), "{a:?}: {err}");
        assert!(!out_path.exists(), "{a:?} wrote {}", out_path.display());
    }
}

/// A drum model file (format of `models/drums/train.py`, version 2, feature set 2) whose
/// kick sees only the backing view: 48 hidden units, unit `b` = ReLU(backing[current][b] -
/// backing[previous][b]) (a band of the backing rising), kick = Σ units / 4 − 6; the drum
/// view, snare, toms and cymbals are wired to nothing (the three never fire).
fn backing_only_model() -> Vec<u8> {
    let (bands, past, future) = (48usize, 7usize, 4usize);
    let frames = past + 1 + future;
    let n_in = 2 * bands * frames;
    let mut f = b"TACTUSDR".to_vec();
    for v in [2u32, bands as u32, past as u32, future as u32, 4, 2] {
        f.extend(v.to_le_bytes());
    }
    f.extend((-16f32).to_le_bytes());
    f.extend(2u32.to_le_bytes());
    f.extend(6f32.to_le_bytes());
    let push_layer = |f: &mut Vec<u8>, n_in: usize, n_out: usize, w: &[f32], b: &[f32]| {
        f.extend((n_in as u32).to_le_bytes());
        f.extend((n_out as u32).to_le_bytes());
        w.iter().chain(b).for_each(|v| f.extend(v.to_le_bytes()));
    };
    let mut w1 = vec![0f32; bands * n_in];
    let back = bands * frames; // the backing view starts here
    for b in 0..bands {
        w1[b * n_in + back + past * bands + b] = 1.0;
        w1[b * n_in + back + (past - 1) * bands + b] = -1.0;
    }
    push_layer(&mut f, n_in, bands, &w1, &vec![0f32; bands]);
    let mut w2 = vec![0f32; 4 * bands];
    w2[..bands].fill(0.25);
    push_layer(&mut f, bands, 4, &w2, &[-6.0, -30.0, -30.0, -30.0]);
    for t in [0.5f32; 4] {
        f.extend(t.to_le_bytes());
    }
    f
}

#[test]
fn a_backing_model_reads_the_separators_other_stems_in_time() {
    // Staccato organ notes (0.3 s on, 0.3 s off) over steady noise: the spectral separator
    // puts the notes in its tonal stems and the noise in its drum stem. A model that fires
    // a kick where its backing view rises must fire at the notes' starts on the mix, and
    // never when the same audio is supplied as a clean drum stem (no backing: silence, as
    // in training). A separator output that did not reach the transcriber, or reached it
    // shifted by more than the onset tolerance, fails.
    let sr = 44_100usize;
    let mut rng = 0x2545_F491_4F6C_DD1Du64;
    let mut noise = || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
    };
    let starts: Vec<f64> = (0..10).map(|k| 0.5 + 0.6 * k as f64).collect();
    let pitches = [
        110.0, 165.0, 131.0, 196.0, 147.0, 220.0, 123.0, 175.0, 139.0, 247.0,
    ];
    let n = (7.0 * sr as f64) as usize;
    let x: Vec<f32> = (0..n)
        .map(|i| {
            let t = i as f64 / sr as f64;
            let mut v = 0.02 * noise();
            for (&s, &f0) in starts.iter().zip(&pitches) {
                let u = t - s;
                if (0.0..0.3).contains(&u) {
                    let env = (u / 0.005).min(1.0) * ((0.3 - u) / 0.005).min(1.0);
                    for h in 1..8 {
                        let ph = 2.0 * std::f64::consts::PI * f0 * h as f64 * u;
                        v += (0.3 * env * ph.sin() / h as f64) as f32;
                    }
                }
            }
            v
        })
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let wav = dir.path().join("notes.wav");
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: sr as u32,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(&wav, spec).unwrap();
    for &v in &x {
        w.write_sample((v.clamp(-1.0, 1.0) * 32_000.0) as i16)
            .unwrap();
    }
    w.finalize().unwrap();
    let model = dir.path().join("backing.bin");
    std::fs::write(&model, backing_only_model()).unwrap();
    let kicks = |name: &str, extra: &[&std::ffi::OsStr]| -> Vec<f64> {
        let feat = dir.path().join(format!("{name}.json"));
        let mut a: Vec<std::ffi::OsString> = vec![
            "render".into(),
            wav.clone().into(),
            "-o".into(),
            dir.path().join(format!("{name}.pattern.json")).into(),
            "--features".into(),
            feat.clone().into(),
            "--drum-model".into(),
            model.clone().into(),
        ];
        a.extend(extra.iter().map(|s| s.to_os_string()));
        common::tactus_ok(&a);
        let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&feat).unwrap()).unwrap();
        v["onsets_s"]["kick"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| t.as_f64().unwrap())
            .collect()
    };
    for mode in ["offline", "streaming"] {
        // The stream's first hop rises from the silence before it: this model fires there.
        let on_mix: Vec<f64> = kicks(mode, &["--mode".as_ref(), mode.as_ref()])
            .into_iter()
            .filter(|&t| t > 0.1)
            .collect();
        let near = |t: f64| starts.iter().any(|&s| (t - s).abs() <= 0.05);
        let found = starts
            .iter()
            .filter(|&&s| on_mix.iter().any(|&t| (t - s).abs() <= 0.05))
            .count();
        assert!(
            found >= 9,
            "{mode}: {found} of 10 note starts found: {on_mix:?}"
        );
        assert!(
            on_mix.iter().all(|&t| near(t)),
            "{mode}: kicks away from the note starts: {on_mix:?}"
        );
    }
    let stem = format!("drums={}", wav.display());
    let clean = kicks("clean", &["--stem".as_ref(), stem.as_ref()]);
    assert!(
        clean.is_empty(),
        "a supplied drum stem has no backing: {clean:?}"
    );
}
