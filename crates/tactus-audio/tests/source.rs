//! Decoding and resampling against signals whose every sample is known.
//!
//! The fixtures in `tests/fixtures/` were made by `make_fixtures.sh` from the formulas below
//! (ffmpeg's aevalsrc, double precision, t = n / rate). Lossless files must match the formula
//! within their quantisation step; lossy ones must carry the right tones at the right levels.

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use proptest::prelude::*;
use tactus_audio::resample::{resample_all, ResampleError, StreamResampler};
use tactus_audio::source::{decode_all, AudioSource, Decoded, SourceError};

// ---------------------------------------------------------------------------------------------
// Reference signals and measurements

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

/// MAIN in make_fixtures.sh: mono, and the left channel of stereo fixtures.
fn main_sig(t: f64) -> f64 {
    0.5 * (2.0 * PI * 440.0 * t).sin() + 0.25 * (2.0 * PI * 880.0 * t).sin()
}

/// RIGHT in make_fixtures.sh.
fn right_sig(t: f64) -> f64 {
    0.6 * main_sig(t)
}

/// Channel `k` of the 5.1 fixture.
fn six_sig(k: usize, t: f64) -> f64 {
    0.15 * (2.0 * PI * 220.0 * (k + 1) as f64 * t).sin()
}

/// Amplitude of the sinusoid at `f` Hz in `x`: Hann-windowed single-bin DFT, scaled so that
/// a pure sine of amplitude A reads A (2 |X| / sum(w)). Over windows of >= 0.1 s the Hann
/// leakage of a tone 440 Hz away is below -100 dB, so 440 and 880 Hz do not disturb each other.
fn tone_amp(x: &[f32], rate: f64, f: f64) -> f64 {
    let n = x.len();
    let (mut re, mut im, mut wsum) = (0.0f64, 0.0f64, 0.0f64);
    for (i, &v) in x.iter().enumerate() {
        let w = 0.5 - 0.5 * (2.0 * PI * i as f64 / n as f64).cos();
        let ph = 2.0 * PI * f * i as f64 / rate;
        re += w * v as f64 * ph.cos();
        im -= w * v as f64 * ph.sin();
        wsum += w;
    }
    2.0 * (re * re + im * im).sqrt() / wsum
}

fn rms(x: &[f32]) -> f64 {
    (x.iter().map(|&v| (v as f64).powi(2)).sum::<f64>() / x.len() as f64).sqrt()
}

fn db(ratio: f64) -> f64 {
    20.0 * ratio.log10()
}

/// Largest tone amplitude away from `keep` (Hz, ±60 Hz), on a 25 Hz grid from 50 Hz to
/// 0.45 × rate: the "everything else" against which the expected tones must dominate.
fn strongest_other(x: &[f32], rate: f64, keep: &[f64]) -> f64 {
    let mut worst = 0.0f64;
    let mut f = 50.0;
    while f < 0.45 * rate {
        if keep.iter().all(|k| (f - k).abs() > 60.0) {
            worst = worst.max(tone_amp(x, rate, f));
        }
        f += 25.0;
    }
    worst
}

fn decode(name: &str) -> Decoded {
    decode_all(&fixture(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

// ---------------------------------------------------------------------------------------------
// Lossless fixtures: every sample against the formula

/// One LSB of a b-bit signed integer format scaled to [-1, 1).
fn lsb(bits: i32) -> f64 {
    2f64.powi(-(bits - 1))
}

#[test]
fn lossless_fixtures_are_sample_exact() {
    // (file, rate, channels, codec, tolerance). Tolerances: ffmpeg rounds the double formula
    // to the nearest integer (0.5 LSB); for 24-bit it rounds to 32 bits and truncates the low
    // byte (< 1 LSB); the f32 result adds at most half an f32 ulp at 0.75 (3e-8). s32 and f32
    // are limited by f32 itself.
    let cases: [(&str, u32, usize, &str, f64); 6] = [
        ("wav_s16_44100_stereo.wav", 44100, 2, "pcm_s16le", lsb(16)),
        (
            "wav_s24_48000_mono.wav",
            48000,
            1,
            "pcm_s24le",
            lsb(24) + 1e-7,
        ),
        ("wav_s32_22050_stereo.wav", 22050, 2, "pcm_s32le", 1e-7),
        ("wav_f32_96000_mono.wav", 96000, 1, "pcm_f32le", 1e-7),
        (
            "flac_s24_96000_stereo.flac",
            96000,
            2,
            "flac",
            lsb(24) + 1e-7,
        ),
        ("flac_s16_22050_6ch.flac", 22050, 6, "flac", 0.0), // checked in its own test
    ];
    for (name, rate, channels, codec, tol) in cases {
        let d = decode(name);
        // 0.25 s: aevalsrc emits round(0.25 * rate) frames (5512.5 -> 5513).
        let frames = (0.25 * rate as f64).round() as usize;
        assert_eq!(d.info.sample_rate, rate, "{name}");
        assert_eq!(d.info.channels, channels, "{name}");
        assert_eq!(d.info.codec, codec, "{name}");
        assert_eq!(d.info.frames, Some(frames as u64), "{name}");
        let dur = d.info.duration_s.unwrap();
        assert!((dur - frames as f64 / rate as f64).abs() < 1e-12, "{name}");
        assert_eq!(d.left.len(), frames, "{name}");
        assert_eq!(d.right.len(), frames, "{name}");
        assert!(
            !d.truncated && d.non_finite == 0 && d.skipped_packets == 0,
            "{name}"
        );
        if channels == 6 {
            continue;
        }
        let mut worst = 0.0f64;
        for n in 0..frames {
            let t = n as f64 / rate as f64;
            let r = if channels == 2 {
                right_sig(t)
            } else {
                main_sig(t)
            };
            worst = worst.max((d.left[n] as f64 - main_sig(t)).abs());
            worst = worst.max((d.right[n] as f64 - r).abs());
        }
        assert!(worst <= tol, "{name}: max error {worst:e} > {tol:e}");
    }
}

#[test]
fn six_channels_downmix_to_the_documented_stereo() {
    let d = decode("flac_s16_22050_6ch.flac");
    assert_eq!(d.info.channels, 6);
    // FLAC 6 channels = FL FR FC LFE BL BR. Module docs: FL -> L, FR -> R, FC and LFE -> both
    // at 1/sqrt2, BL -> L and BR -> R at 1/sqrt2; each side divided by its sum 1 + 3/sqrt2.
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let norm = 1.0 + 3.0 * h;
    let mut worst = 0.0f64;
    for n in 0..d.left.len() {
        let t = n as f64 / 22050.0;
        let c: Vec<f64> = (0..6).map(|k| six_sig(k, t)).collect();
        let l = (c[0] + h * (c[2] + c[3] + c[4])) / norm;
        let r = (c[1] + h * (c[2] + c[3] + c[5])) / norm;
        worst = worst
            .max((d.left[n] as f64 - l).abs())
            .max((d.right[n] as f64 - r).abs());
    }
    // Each input carries <= 0.5 LSB (16-bit) of rounding; the weights sum to 1.
    assert!(worst <= lsb(16) / 2.0 + 1e-6, "max error {worst:e}");
    // And the mix really is not symmetric: 220 Hz (FL) only on the left, 440 Hz (FR) only right.
    let (l220, r220) = (
        tone_amp(&d.left, 22050.0, 220.0),
        tone_amp(&d.right, 22050.0, 220.0),
    );
    assert!(
        (l220 - 0.15 / norm).abs() < 1e-3 && r220 < 1e-4,
        "{l220} {r220}"
    );
}

// ---------------------------------------------------------------------------------------------
// Lossy fixtures: duration, tones and level

struct Lossy {
    name: &'static str,
    rate: u32,
    channels: usize,
    codec: &'static str,
    /// Decoded frames: exact where the codec's delay and padding are trimmed.
    frames: usize,
    /// Where t = 0 of the formula lies in the decoded signal.
    lag: usize,
    /// Level the encoder delivers relative to the formula (linear).
    gain: f64,
    /// Allowed level error at 440/880 Hz and in RMS, dB, after `gain`.
    level_db: f64,
    /// Allowed RMS of (decoded - formula) relative to the formula's RMS.
    residual: f64,
    /// Minimum margin of the 440 Hz tone over any tone away from 440/880 Hz, dB.
    dominance_db: f64,
}

/// Tolerances. ffmpeg's LAME encoder delivers the tones at 0.95 × their level (-0.446 dB; ffmpeg's
/// own decoder agrees: astats RMS -10.18 dBFS against -9.74 for the WAV), so MP3 expects that
/// gain, then gets 0.1 dB and a 1 % residual. Vorbis q5 and AAC 96–128 kb/s measure within
/// 0.16 dB and 1–4.2 % residual (AAC's pre-echo around its 1024-frame blocks is the largest);
/// they get 0.25 dB and 2 % / 6 %. Every codec keeps any other tone 48 dB or more below 440 Hz:
/// 40 dB is required.
fn lossy_cases() -> Vec<Lossy> {
    // MP3 (LAME tag) and Vorbis (granule positions) carry gapless info, so their length is
    // exact and t = 0 is frame 0. Symphonia's MP4 reader ignores the edit list, so AAC keeps
    // ffmpeg's 1024 priming frames and is padded to whole 1024-frame packets:
    // ceil((n + 1024) / 1024) * 1024 frames, t = 0 at frame 1024.
    let aac_frames = |n: usize| (n + 1024).div_ceil(1024) * 1024;
    vec![
        Lossy {
            name: "mp3_44100_stereo.mp3",
            rate: 44100,
            channels: 2,
            codec: "mp3",
            frames: 22050,
            lag: 0,
            gain: 0.95,
            level_db: 0.1,
            residual: 0.01,
            dominance_db: 40.0,
        },
        Lossy {
            name: "mp3_22050_mono.mp3",
            rate: 22050,
            channels: 1,
            codec: "mp3",
            frames: 11025,
            lag: 0,
            gain: 0.95,
            level_db: 0.1,
            residual: 0.01,
            dominance_db: 40.0,
        },
        Lossy {
            name: "vorbis_48000_stereo.ogg",
            rate: 48000,
            channels: 2,
            codec: "vorbis",
            frames: 24000,
            lag: 0,
            gain: 1.0,
            level_db: 0.25,
            residual: 0.02,
            dominance_db: 40.0,
        },
        Lossy {
            name: "aac_44100_stereo.m4a",
            rate: 44100,
            channels: 2,
            codec: "aac",
            frames: aac_frames(22050),
            lag: 1024,
            gain: 1.0,
            level_db: 0.25,
            residual: 0.06,
            dominance_db: 40.0,
        },
        Lossy {
            name: "aac_48000_mono.m4a",
            rate: 48000,
            channels: 1,
            codec: "aac",
            frames: aac_frames(24000),
            lag: 1024,
            gain: 1.0,
            level_db: 0.25,
            residual: 0.06,
            dominance_db: 40.0,
        },
    ]
}

#[test]
fn lossy_fixtures_carry_the_right_tones() {
    for c in lossy_cases() {
        let d = decode(c.name);
        let name = c.name;
        assert_eq!(d.info.sample_rate, c.rate, "{name}");
        assert_eq!(d.info.channels, c.channels, "{name}");
        assert_eq!(d.info.codec, c.codec, "{name}");
        assert_eq!(d.left.len(), c.frames, "{name}: length");
        assert!(
            !d.truncated && d.non_finite == 0 && d.skipped_packets == 0,
            "{name}"
        );
        // Steady part: 0.1 s to 0.4 s of the formula's time (away from codec edge effects).
        let rate = c.rate as f64;
        let (a, b) = ((0.1 * rate) as usize, (0.4 * rate) as usize);
        for (side, x, gain) in [
            ("L", &d.left, c.gain),
            (
                "R",
                &d.right,
                c.gain * if c.channels == 2 { 0.6 } else { 1.0 },
            ),
        ] {
            let seg = &x[c.lag + a..c.lag + b];
            let want: Vec<f32> = (a..b)
                .map(|n| (gain * main_sig(n as f64 / rate)) as f32)
                .collect();
            let a440 = tone_amp(seg, rate, 440.0);
            let a880 = tone_amp(seg, rate, 880.0);
            let e440 = db(a440 / (0.5 * gain));
            let e880 = db(a880 / (0.25 * gain));
            let erms = db(rms(seg) / rms(&want));
            let diff: Vec<f32> = seg.iter().zip(&want).map(|(x, y)| x - y).collect();
            let resid = rms(&diff) / rms(&want);
            let dom = db(a440 / strongest_other(seg, rate, &[440.0, 880.0]));
            println!(
                "{name} {side}: 440 {e440:+.3} dB, 880 {e880:+.3} dB, rms {erms:+.3} dB, \
                 residual {resid:.4}, dominance {dom:.1} dB"
            );
            assert!(
                e440.abs() <= c.level_db,
                "{name} {side}: 440 Hz off by {e440} dB"
            );
            assert!(
                e880.abs() <= c.level_db,
                "{name} {side}: 880 Hz off by {e880} dB"
            );
            assert!(
                erms.abs() <= c.level_db,
                "{name} {side}: RMS off by {erms} dB"
            );
            assert!(resid <= c.residual, "{name} {side}: residual {resid}");
            assert!(dom >= c.dominance_db, "{name} {side}: dominance {dom} dB");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Streaming

const ALL_FIXTURES: [&str; 11] = [
    "wav_s16_44100_stereo.wav",
    "wav_s24_48000_mono.wav",
    "wav_s32_22050_stereo.wav",
    "wav_f32_96000_mono.wav",
    "flac_s16_22050_6ch.flac",
    "flac_s24_96000_stereo.flac",
    "mp3_44100_stereo.mp3",
    "mp3_22050_mono.mp3",
    "vorbis_48000_stereo.ogg",
    "aac_44100_stereo.m4a",
    "aac_48000_mono.m4a",
];

#[test]
fn read_block_concatenation_equals_decode_all() {
    for name in ALL_FIXTURES {
        let whole = decode(name);
        let mut src = AudioSource::open(&fixture(name)).unwrap();
        assert_eq!(src.info(), &whole.info, "{name}");
        let (mut left, mut right) = (Vec::new(), Vec::new());
        let mut blocks = 0;
        loop {
            // Fresh vectors per call: read_block must append exactly what it returns.
            let (mut l, mut r) = (vec![9.0f32; 3], vec![9.0f32; 3]);
            let n = src.read_block(&mut l, &mut r).unwrap();
            assert_eq!((l.len(), r.len()), (n + 3, n + 3), "{name}");
            assert_eq!(
                &l[..3],
                &[9.0; 3],
                "{name}: read_block overwrote existing data"
            );
            if n == 0 {
                break;
            }
            blocks += 1;
            left.extend_from_slice(&l[3..]);
            right.extend_from_slice(&r[3..]);
        }
        // Stays at the end.
        let (mut l, mut r) = (Vec::new(), Vec::new());
        assert_eq!(src.read_block(&mut l, &mut r).unwrap(), 0, "{name}");
        assert!(blocks > 1, "{name}: should arrive in several packets");
        assert_eq!(src.frames_read(), left.len() as u64);
        assert!(left == whole.left && right == whole.right, "{name}");
    }
}

// ---------------------------------------------------------------------------------------------
// Bad input

fn xorshift_bytes(n: usize, mut s: u64) -> Vec<u8> {
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 24) as u8
        })
        .collect()
}

fn write_temp(dir: &tempfile::TempDir, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.path().join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn open_err(p: &Path) -> SourceError {
    let e = AudioSource::open(p).expect_err("must not open");
    let name = p.file_name().unwrap().to_str().unwrap();
    let msg = e.to_string();
    assert!(msg.contains(name), "message without the file name: {msg}");
    assert!(!msg.contains('\n'), "message spans lines: {msg}");
    e
}

#[test]
fn missing_empty_and_random_files_are_typed_errors() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no_such_song.mp3");
    assert!(matches!(open_err(&missing), SourceError::NotFound(_)));
    assert!(matches!(
        decode_all(&missing),
        Err(SourceError::NotFound(_))
    ));

    let empty = write_temp(&dir, "empty.wav", &[]);
    assert!(matches!(open_err(&empty), SourceError::Empty(_)));

    for seed in 1..=4u64 {
        for ext in ["mp3", "wav", "bin"] {
            let p = write_temp(
                &dir,
                &format!("noise{seed}.{ext}"),
                &xorshift_bytes(8192, seed),
            );
            let e = open_err(&p);
            assert!(
                matches!(e, SourceError::UnsupportedFormat { .. }),
                "{seed}.{ext}: {e:?}"
            );
            assert!(e.to_string().contains("not a recognised audio file"));
        }
    }
}

#[test]
fn truncated_mp3_keeps_what_decodes() {
    let dir = tempfile::tempdir().unwrap();
    let full_bytes = std::fs::read(fixture("mp3_44100_stereo.mp3")).unwrap();
    let full = decode("mp3_44100_stereo.mp3");
    let cut = full_bytes.len() * 6 / 10;
    let p = write_temp(&dir, "cut.mp3", &full_bytes[..cut]);
    let d = decode_all(&p).unwrap();
    assert!(d.truncated, "truncation must be flagged");
    // Roughly 60 % of the audio survives (minus the partial last frame).
    let frac = d.left.len() as f64 / full.left.len() as f64;
    assert!((0.45..0.62).contains(&frac), "kept {frac}");
    // What is delivered is exactly what the intact file gives for the same packets.
    assert_eq!(d.left[..], full.left[..d.left.len()]);
    assert_eq!(d.right[..], full.right[..d.right.len()]);

    // Cut inside the first audio frame: nothing decodes -> an error, not empty audio.
    let p = write_temp(&dir, "stub.mp3", &full_bytes[..600]);
    assert!(matches!(open_err(&p), SourceError::Truncated { .. }));

    // An M4A cut before its index (moov at the end, as ffmpeg writes it): nothing to decode.
    let m4a = std::fs::read(fixture("aac_44100_stereo.m4a")).unwrap();
    let p = write_temp(&dir, "cut.m4a", &m4a[..4000]);
    assert!(matches!(open_err(&p), SourceError::Corrupt { .. }));
}

/// Byte offset of the `data` chunk header in a WAV file.
fn data_chunk(wav: &[u8]) -> usize {
    wav.windows(4).position(|w| w == b"data").unwrap()
}

#[test]
fn wav_header_claiming_too_much_data_keeps_what_is_there() {
    let dir = tempfile::tempdir().unwrap();
    let wav = std::fs::read(fixture("wav_s16_44100_stereo.wav")).unwrap();
    let full = decode("wav_s16_44100_stereo.wav");
    let pos = data_chunk(&wav);
    let size = |b: &[u8], at: usize| u32::from_le_bytes(b[at..at + 4].try_into().unwrap());

    // Data size alone enlarged (now inconsistent with the RIFF size), both enlarged, and the
    // streaming writers' 0xFFFFFFFF.
    let mut only_data = wav.clone();
    let big = size(&wav, pos + 4) + 100_000;
    only_data[pos + 4..pos + 8].copy_from_slice(&big.to_le_bytes());
    let mut both = only_data.clone();
    both[4..8].copy_from_slice(&(size(&wav, 4) + 100_000).to_le_bytes());
    let mut ffff = wav.clone();
    ffff[4..8].copy_from_slice(&u32::MAX.to_le_bytes());
    ffff[pos + 4..pos + 8].copy_from_slice(&u32::MAX.to_le_bytes());
    for (name, bytes) in [
        ("only_data.wav", &only_data),
        ("both.wav", &both),
        ("ffff.wav", &ffff),
    ] {
        let d = decode_all(&write_temp(&dir, name, bytes)).unwrap();
        assert!(d.truncated, "{name}");
        assert!(d.left == full.left && d.right == full.right, "{name}");
    }

    // Cut in the middle of the data: everything before the cut.
    let cut = pos + 8 + 4 * 1000 + 2;
    let d = decode_all(&write_temp(&dir, "cut.wav", &wav[..cut])).unwrap();
    assert!(d.truncated);
    assert!(!d.left.is_empty() && d.left.len() <= 1000);
    assert_eq!(d.left[..], full.left[..d.left.len()]);

    // A header and no data at all.
    let p = write_temp(&dir, "header_only.wav", &wav[..pos + 8]);
    assert!(matches!(open_err(&p), SourceError::Truncated { .. }));
    // A complete file with zero frames.
    let mut zero = wav[..pos + 8].to_vec();
    zero[pos + 4..pos + 8].copy_from_slice(&0u32.to_le_bytes());
    let riff = (zero.len() - 8) as u32;
    zero[4..8].copy_from_slice(&riff.to_le_bytes());
    let p = write_temp(&dir, "no_frames.wav", &zero);
    assert!(matches!(open_err(&p), SourceError::Empty(_)));
}

#[test]
fn non_finite_float_samples_become_zero_and_are_counted() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("nan.wav");
    let spec = hound::WavSpec {
        channels: 2,
        sample_rate: 44100,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let frames = 4410;
    let bad = [
        (10, 0, f32::NAN),
        (20, 1, f32::INFINITY),
        (30, 0, f32::NEG_INFINITY),
        (4000, 1, f32::NAN),
    ];
    let value = |n: usize, ch: usize| -> f32 {
        for &(bn, bc, v) in &bad {
            if bn == n && bc == ch {
                return v;
            }
        }
        main_sig(n as f64 / 44100.0) as f32 * if ch == 1 { 0.6 } else { 1.0 }
    };
    let mut w = hound::WavWriter::create(&p, spec).unwrap();
    for n in 0..frames {
        for ch in 0..2 {
            w.write_sample(value(n, ch)).unwrap();
        }
    }
    w.finalize().unwrap();

    let d = decode_all(&p).unwrap();
    assert_eq!(d.non_finite, bad.len());
    assert_eq!(d.left.len(), frames);
    for n in 0..frames {
        for (ch, x) in [(0, d.left[n]), (1, d.right[n])] {
            let v = value(n, ch);
            let want = if v.is_finite() { v } else { 0.0 };
            assert!(x.is_finite());
            assert_eq!(x, want, "frame {n} channel {ch}");
        }
    }
}

#[test]
fn unsupported_codecs_are_named() {
    // Opus in Ogg: a real codec Symphonia 0.6 has no decoder for.
    let e = open_err(&fixture("opus_48000_mono.opus"));
    assert!(matches!(e, SourceError::UnsupportedCodec { .. }), "{e:?}");

    // A WAV with format tag 0x0031 (GSM 6.10), which Symphonia's WAV reader rejects.
    let dir = tempfile::tempdir().unwrap();
    let mut b = Vec::new();
    let data = vec![0u8; 650];
    b.extend_from_slice(b"RIFF");
    b.extend_from_slice(&((4 + 8 + 20 + 8 + data.len()) as u32).to_le_bytes());
    b.extend_from_slice(b"WAVEfmt ");
    b.extend_from_slice(&20u32.to_le_bytes());
    b.extend_from_slice(&0x0031u16.to_le_bytes()); // format tag: GSM 6.10
    b.extend_from_slice(&1u16.to_le_bytes()); // channels
    b.extend_from_slice(&8000u32.to_le_bytes()); // rate
    b.extend_from_slice(&1625u32.to_le_bytes()); // bytes per second
    b.extend_from_slice(&65u16.to_le_bytes()); // block align
    b.extend_from_slice(&0u16.to_le_bytes()); // bits per sample
    b.extend_from_slice(&2u16.to_le_bytes()); // extra size
    b.extend_from_slice(&320u16.to_le_bytes()); // samples per block
    b.extend_from_slice(b"data");
    b.extend_from_slice(&(data.len() as u32).to_le_bytes());
    b.extend_from_slice(&data);
    let p = write_temp(&dir, "gsm.wav", &b);
    let e = open_err(&p);
    assert!(matches!(e, SourceError::UnsupportedCodec { .. }), "{e:?}");
}

// ---------------------------------------------------------------------------------------------
// Resampling

const PAIRS: [(u32, u32); 4] = [
    (44100, 48000),
    (48000, 44100),
    (22050, 44100),
    (96000, 44100),
];

fn sine(rate: u32, f: f64, amp: f64, n: usize) -> Vec<f32> {
    (0..n)
        .map(|i| (amp * (2.0 * PI * f * i as f64 / rate as f64).sin()) as f32)
        .collect()
}

#[test]
fn resampled_length_is_exact() {
    for (a, b) in PAIRS {
        for n in [0usize, 1, 7, 1000, 44100, 44100 + 37, 96001] {
            let x = sine(a, 440.0, 0.5, n);
            let y = resample_all(&[&x, &x], a, b).unwrap();
            let want = ((n as u128 * b as u128 + a as u128 / 2) / a as u128) as usize;
            assert_eq!(y[0].len(), want, "{a}->{b}, n={n}");
            assert_eq!(y[1].len(), want, "{a}->{b}, n={n}");
        }
    }
}

#[test]
fn resampled_sines_keep_frequency_phase_and_level() {
    for (a, b) in PAIRS {
        // Test tones up to 40 % of the lower rate: inside the anti-aliasing passband.
        let top = 0.4 * a.min(b) as f64;
        for f in [100.0, 440.0, 1000.0, 5000.0, top] {
            let x = sine(a, f, 0.5, a as usize); // 1 s
            let y = resample_all(&[&x], a, b).unwrap().remove(0);
            // Middle 0.2..0.8 s, away from the start-up and end transients.
            let (lo, hi) = ((0.2 * b as f64) as usize, (0.8 * b as f64) as usize);
            let want = sine(b, f, 0.5, hi);
            let seg = &y[lo..hi];
            let level = db(tone_amp(seg, b as f64, f) / 0.5);
            assert!(level.abs() <= 0.1, "{a}->{b} {f} Hz: {level} dB");
            // Sample by sample against the ideal output sine: checks frequency, level and the
            // alignment (phase) at once. 1e-4 = -74 dB below the tone (measured: < 1e-6 up to
            // 5 kHz); a half-frame misalignment would already give 3.6e-3 at 100 Hz.
            let worst = seg
                .iter()
                .zip(&want[lo..hi])
                .map(|(p, q)| (p - q).abs())
                .fold(0.0f32, f32::max);
            assert!(worst < 1e-4, "{a}->{b} {f} Hz: max error {worst}");
        }
    }
}

#[test]
fn downsampling_rejects_aliases() {
    // 30 kHz at 96 kHz would alias to 14.1 kHz at 44.1 kHz.
    let x = sine(96000, 30000.0, 0.5, 96000);
    let y = resample_all(&[&x], 96000, 44100).unwrap().remove(0);
    let seg = &y[8820..35280];
    let alias = tone_amp(seg, 44100.0, 14100.0);
    assert!(db(alias / 0.5) < -90.0, "alias at {} dB", db(alias / 0.5));
    assert!(rms(seg) < 1e-4, "residual rms {}", rms(seg));
}

#[test]
fn a_click_lands_where_its_time_says() {
    for (a, b) in PAIRS {
        let n = a as usize; // 1 s
                            // Clicks at input frames whose output position is an integer, and at frames whose
                            // position is not (there the peak must be within 1 frame of the exact time).
        let g = {
            let (mut x, mut y) = (a, b);
            while y != 0 {
                (x, y) = (y, x % y);
            }
            x as usize
        };
        let step = a as usize / g;
        for k in [step * 3, step * 101, 12345, n / 2 + 7] {
            let mut x = vec![0.0f32; n];
            x[k] = 1.0;
            let y = resample_all(&[&x], a, b).unwrap().remove(0);
            let peak = y
                .iter()
                .enumerate()
                .max_by(|p, q| p.1.abs().total_cmp(&q.1.abs()))
                .unwrap()
                .0;
            let exact = k as f64 * b as f64 / a as f64;
            if exact.fract() == 0.0 {
                assert_eq!(peak as f64, exact, "{a}->{b}: click at {k}");
            }
            assert!(
                (peak as f64 - exact).abs() <= 1.0,
                "{a}->{b}: click at {k} -> {peak}, expected {exact}"
            );
        }
    }
}

#[test]
fn identity_is_a_pass_through() {
    let x = sine(44100, 440.0, 0.5, 5000);
    let mut r = StreamResampler::new(44100, 44100, 1).unwrap();
    assert_eq!(r.latency_samples(), 0);
    let mut out = vec![Vec::new()];
    r.process(&[&x[..123]], &mut out);
    r.process(&[&x[123..]], &mut out);
    r.finish(&mut out);
    assert_eq!(out[0], x);
}

#[test]
fn bad_resampler_settings_are_errors() {
    assert!(matches!(
        StreamResampler::new(0, 44100, 2),
        Err(ResampleError::InvalidRate { .. })
    ));
    assert!(matches!(
        StreamResampler::new(44100, 0, 2),
        Err(ResampleError::InvalidRate { .. })
    ));
    assert!(matches!(
        StreamResampler::new(44100, 48000, 0),
        Err(ResampleError::InvalidChannels(_))
    ));
    let (x, y) = (vec![0.0f32; 10], vec![0.0f32; 11]);
    assert!(matches!(
        resample_all(&[&x, &y], 44100, 48000),
        Err(ResampleError::InvalidChannels(_))
    ));
}

#[test]
fn latency_bounds_what_is_held_back() {
    for (a, b) in PAIRS {
        let mut r = StreamResampler::new(a, b, 1).unwrap();
        let x = sine(a, 440.0, 0.5, 3 * a as usize / 2);
        let mut out = vec![Vec::new()];
        let mut fed = 0usize;
        for chunk in x.chunks(100) {
            r.process(&[chunk], &mut out);
            fed += chunk.len();
            let due = r.output_len(fed as u64) as usize;
            assert!(due - out[0].len() <= r.latency_samples(), "{a}->{b}");
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 8, ..ProptestConfig::default() })]

    #[test]
    fn chunked_resampling_equals_one_block(
        pair in 0usize..4,
        sizes in proptest::collection::vec(0usize..3000, 1..40),
    ) {
        let (a, b) = PAIRS[pair];
        let n = 20_000;
        let l = sine(a, 440.0, 0.5, n);
        let r = sine(a, 1234.5, 0.25, n);
        let whole = resample_all(&[&l, &r], a, b).unwrap();

        let mut rs = StreamResampler::new(a, b, 2).unwrap();
        let mut out = vec![Vec::new(), Vec::new()];
        let mut pos = 0;
        for s in sizes.iter().cycle() {
            if pos >= n {
                break;
            }
            let end = (pos + s).min(n);
            rs.process(&[&l[pos..end], &r[pos..end]], &mut out);
            pos = end;
            if *s == 0 {
                pos += 1; // make progress even on a run of zero-sized chunks
                rs.process(&[&l[pos - 1..pos], &r[pos - 1..pos]], &mut out);
            }
        }
        rs.finish(&mut out);
        prop_assert_eq!(&out, &whole);

        // finish() resets: a second stream through the same resampler gives the same output.
        let mut again = vec![Vec::new(), Vec::new()];
        rs.process(&[&l, &r], &mut again);
        rs.finish(&mut again);
        prop_assert_eq!(&again, &whole);
    }
}
