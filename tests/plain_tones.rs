//! Plain tones through the default render (`tactus render`, the spectral separator and the
//! learned trackers): sines, squares, saws and 808-style notes (a sine with a little second
//! harmonic), held and gliding, 41 Hz to 2 kHz, in WAV files at 8 to 192 kHz. Each must be
//! tracked by the finger its stem goes to (the bass below the separator's 250 Hz crossover,
//! the lead above it) within 50 cents in at least 95 % of the hops; DC and silence stay
//! unvoiced and fire no drum. A learned tracker that does not know a plain tone falls back to
//! YIN (docs/decisions/0051-plain-guard.md), and the kit mask leaves a held sub-bass tone in
//! the bass (docs/decisions/0052-kit-mask-spares-held-tones.md).

use std::path::Path;
use std::process::Command;

#[derive(Clone, Copy, Debug)]
enum Wave {
    Sine,
    Square,
    Saw,
    Eight08,
}

/// Seconds of every test signal.
const SECONDS: f32 = 3.0;
/// Scored hops: from 0.3 s (a new low tone's first 200 ms read like a kick body to the kit
/// mask) to 0.3 s before the end.
const SCORED_S: (f32, f32) = (0.3, SECONDS - 0.3);

/// The true f0 at `t`: `f0`, or with `glide` semitones reached linearly between 1 and 2 s.
fn f0_at(f0: f32, glide: f32, t: f32) -> f32 {
    f0 * 2f32.powf((t - 1.0).clamp(0.0, 1.0) * glide / 12.0)
}

/// The signal, amplitude 0.5 (before the format's own scaling).
fn synth(wave: Wave, f0: f32, glide: f32, rate: u32) -> Vec<f32> {
    let n = (SECONDS * rate as f32) as usize;
    let mut phase = 0.0f64;
    (0..n)
        .map(|j| {
            let t = j as f32 / rate as f32;
            phase += f64::from(f0_at(f0, glide, t)) / f64::from(rate);
            let p = (phase.fract() * std::f64::consts::TAU) as f32;
            0.5 * match wave {
                Wave::Sine => p.sin(),
                Wave::Square => 0.6 * p.sin().signum(),
                Wave::Saw => 0.6 * (p / std::f32::consts::PI - 1.0),
                Wave::Eight08 => 0.9 * (p.sin() + 0.15 * (2.0 * p).sin()),
            }
        })
        .collect()
}

/// How the samples are stored.
#[derive(Clone, Copy, Debug)]
enum Format {
    Int(u16),
    /// 32-bit float, scaled by this gain (above 1: over full scale, as a float file may be).
    Float(f32),
}

fn write_wav(path: &Path, rate: u32, channels: u16, format: Format, x: &[f32]) {
    let (bits, sample_format) = match format {
        Format::Int(b) => (b, hound::SampleFormat::Int),
        Format::Float(_) => (32, hound::SampleFormat::Float),
    };
    let spec = hound::WavSpec {
        channels,
        sample_rate: rate,
        bits_per_sample: bits,
        sample_format,
    };
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    for &v in x {
        for _ in 0..channels {
            match format {
                Format::Float(g) => w.write_sample(v * g).unwrap(),
                Format::Int(b) => {
                    let full = ((1i64 << (b - 1)) - 1) as f32;
                    w.write_sample((v.clamp(-1.0, 1.0) * full).round() as i32)
                        .unwrap()
                }
            }
        }
    }
    w.finalize().unwrap();
}

/// Renders `wav` with the defaults; returns the features file.
fn render(wav: &Path) -> serde_json::Value {
    render_with(wav, &[])
}

/// Renders `wav` with the defaults and `extra` options; returns the features file.
fn render_with(wav: &Path, extra: &[&str]) -> serde_json::Value {
    let dir = wav.parent().unwrap();
    let features = dir.join(format!(
        "{}.features.json",
        wav.file_stem().unwrap().to_string_lossy()
    ));
    let out = Command::new(env!("CARGO_BIN_EXE_tactus"))
        .arg("render")
        .arg(wav)
        .arg("-o")
        .arg(dir.join("pattern.json"))
        .arg("--features")
        .arg(&features)
        .args(extra)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "render {} failed: {}",
        wav.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(&std::fs::read_to_string(&features).unwrap()).unwrap()
}

/// Share of the scored hops of `stem` within 50 cents of the truth.
fn rpa(features: &serde_json::Value, stem: &str, f0: f32, glide: f32) -> f64 {
    let hop_s = features["hop_s"].as_f64().unwrap() as f32;
    let track = features["pitch_hz"][stem].as_array().unwrap();
    let (mut n, mut ok) = (0usize, 0usize);
    for (i, v) in track.iter().enumerate() {
        let t = i as f32 * hop_s;
        if t < SCORED_S.0 || t > SCORED_S.1 {
            continue;
        }
        n += 1;
        let got = v.as_f64().unwrap_or(0.0) as f32;
        if got > 0.0 && (1200.0 * (got / f0_at(f0, glide, t)).log2()).abs() < 50.0 {
            ok += 1;
        }
    }
    ok as f64 / n.max(1) as f64
}

/// The finger a centred tone's stem drives: the spectral separator's bass below its
/// crossover (250 Hz), the lead (vocals) above.
fn home(f0: f32) -> &'static str {
    if f0 < 250.0 {
        "bass"
    } else {
        "vocals"
    }
}

/// Drum onsets at or after `from_s`.
fn drum_onsets(features: &serde_json::Value, from_s: f64) -> usize {
    ["kick", "snare", "toms", "cymbals"]
        .iter()
        .flat_map(|c| {
            features["onsets_s"][c]
                .as_array()
                .cloned()
                .unwrap_or_default()
        })
        .filter(|t| t.as_f64().is_some_and(|t| t >= from_s))
        .count()
}

/// Renders every case and collects the failures, so that one run reports all of them.
fn check_tones(cases: &[(Wave, f32, f32, u32, u16, Format)]) {
    check_tones_with(cases, &[]);
}

/// [`check_tones`] with `extra` render options.
fn check_tones_with(cases: &[(Wave, f32, f32, u32, u16, Format)], extra: &[&str]) {
    let d = tempfile::tempdir().unwrap();
    let mut failures = Vec::new();
    for (k, &(wave, f0, glide, rate, channels, format)) in cases.iter().enumerate() {
        let wav = d.path().join(format!("t{k}.wav"));
        write_wav(&wav, rate, channels, format, &synth(wave, f0, glide, rate));
        let f = render_with(&wav, extra);
        let stem = home(f0.max(f0_at(f0, glide, SECONDS)));
        let r = rpa(&f, stem, f0, glide);
        let case = format!(
            "{wave:?} {f0} Hz glide {glide} st, {rate} Hz {channels} ch {format:?} {extra:?}"
        );
        eprintln!("{case}: {stem} RPA {r:.3}");
        if r < 0.95 {
            failures.push(format!("{case}: {stem} RPA {r:.3} < 0.95"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

const PCM16: Format = Format::Int(16);

#[test]
fn held_and_gliding_tones_from_41_hz_to_2_khz_are_tracked_by_their_finger() {
    let mut cases = Vec::new();
    for wave in [Wave::Sine, Wave::Square, Wave::Saw, Wave::Eight08] {
        for f0 in [41.2, 55.0, 110.0, 220.0, 440.0, 1000.0, 2000.0] {
            if matches!(wave, Wave::Eight08) && f0 > 220.0 {
                continue;
            }
            // Glides up two semitones, the top note down (the lead's guard ends at 2 kHz).
            for glide in [0.0, if f0 >= 2000.0 { -2.0 } else { 2.0 }] {
                cases.push((wave, f0, glide, 44_100, 1, PCM16));
            }
        }
    }
    check_tones(&cases);
}

#[test]
fn the_live_profile_tracks_plain_tones_on_their_finger() {
    // The live profile's learned trackers (docs/decisions/0057-learned-live-pitch.md), backed
    // by YIN (docs/decisions/0051-plain-guard.md): held and gliding tones from 41 Hz to 2 kHz,
    // streamed as `tactus live` computes them, must reach the offline render's 0.95.
    let mut cases = Vec::new();
    for wave in [Wave::Sine, Wave::Saw, Wave::Eight08] {
        for f0 in [41.2, 55.0, 110.0, 220.0, 440.0, 1000.0, 2000.0] {
            if matches!(wave, Wave::Eight08) && f0 > 220.0 {
                continue;
            }
            for glide in [0.0, if f0 >= 2000.0 { -2.0 } else { 2.0 }] {
                cases.push((wave, f0, glide, 44_100, 1, PCM16));
            }
        }
    }
    check_tones_with(&cases, &["--mode", "streaming", "--profile", "live"]);
}

#[test]
fn a_supplied_bass_stem_of_plain_low_tones_is_tracked_on_the_thumb() {
    // A clean bass stem (supplied, or an ONNX separator's) goes to the harmonic sum, whose
    // lowest candidates share FFT bins: a 41 Hz sine came out 65 cents flat. YIN backs it
    // (docs/decisions/0061-plain-guard-beside-the-clean-bass.md).
    let d = tempfile::tempdir().unwrap();
    let mut failures = Vec::new();
    for wave in [Wave::Sine, Wave::Square, Wave::Saw, Wave::Eight08] {
        for f0 in [41.2, 55.0, 110.0, 220.0] {
            for glide in [0.0, 2.0] {
                let wav = d.path().join(format!("{wave:?}{f0}{glide}.wav"));
                write_wav(&wav, 44_100, 1, PCM16, &synth(wave, f0, glide, 44_100));
                let stem = format!("bass={}", wav.display());
                let r = rpa(&render_with(&wav, &["--stem", &stem]), "bass", f0, glide);
                eprintln!("{wave:?} {f0} Hz glide {glide} st, supplied bass stem: RPA {r:.3}");
                if r < 0.95 {
                    failures.push(format!("{wave:?} {f0} Hz glide {glide}: RPA {r:.3} < 0.95"));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn tones_are_tracked_at_every_rate_and_sample_format() {
    check_tones(&[
        (Wave::Sine, 220.0, 0.0, 8_000, 1, Format::Int(8)),
        (Wave::Sine, 220.0, 0.0, 22_050, 1, Format::Int(8)),
        (Wave::Sine, 1000.0, 0.0, 8_000, 1, PCM16),
        (Wave::Sine, 220.0, 0.0, 48_000, 2, Format::Int(24)),
        (Wave::Sine, 220.0, 0.0, 96_000, 2, PCM16),
        (Wave::Sine, 220.0, 0.0, 192_000, 2, PCM16),
        (Wave::Sine, 41.2, 0.0, 192_000, 2, PCM16),
        (Wave::Saw, 2000.0, 0.0, 192_000, 1, PCM16),
        // +18 dBFS in a float file: 0.5 × 15.9.
        (Wave::Sine, 220.0, 0.0, 44_100, 1, Format::Float(15.9)),
        (Wave::Eight08, 55.0, 2.0, 16_000, 1, PCM16),
    ]);
}

#[test]
fn dc_and_silence_stay_unvoiced_and_fire_no_drum() {
    let d = tempfile::tempdir().unwrap();
    let rate = 44_100;
    let n = (SECONDS * rate as f32) as usize;
    let quiet_sine = synth(Wave::Sine, 220.0, 0.0, rate);
    // (name, signal, whether it must stay unvoiced, from when no drum may fire)
    let cases: [(&str, Vec<f32>, bool, f64); 4] = [
        ("silence", vec![0.0; n], true, 0.0),
        ("DC offset", vec![0.3; n], true, 0.0),
        ("negative DC offset", vec![-0.6; n], true, 0.0),
        // A quiet tone on an offset: pitched, and no drum while it holds. The tone's own
        // start (at 0 s, from nothing) may read as one hit.
        (
            "DC offset with a quiet sine",
            quiet_sine.iter().map(|v| 0.5 + 0.02 * v).collect(),
            false,
            0.1,
        ),
    ];
    for (name, x, unvoiced, from_s) in cases {
        let wav = d.path().join("dc.wav");
        write_wav(&wav, rate, 1, PCM16, &x);
        let f = render(&wav);
        assert_eq!(
            drum_onsets(&f, from_s),
            0,
            "{name}: drum onsets {}",
            f["onsets_s"]
        );
        if unvoiced {
            for (stem, track) in f["pitch_hz"].as_object().unwrap() {
                let voiced = track
                    .as_array()
                    .unwrap()
                    .iter()
                    .filter(|v| v.as_f64().unwrap_or(0.0) > 0.0)
                    .count();
                assert_eq!(voiced, 0, "{name}: {stem} voiced in {voiced} hops");
            }
        }
    }
}
