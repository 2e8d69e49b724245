//! Dumps the low-band drum mask's front end (`tactus_separate::lowband`) and its training
//! targets for `models/lowband/train.py`, computed by the very code the separator runs.
//!
//! ```text
//! cargo run --release -p tactus-engine --example lowband_features -- MIX DRUMS OUT.f32 [GAIN]
//! ```
//! MIX and DRUMS (44.1 kHz) are downmixed to mono like the separator's mid channel; with
//! GAIN (default 1) the input is `MIX − DRUMS + GAIN·DRUMS` and its drums `GAIN·DRUMS`
//! (0: the song without its kit, every target 0). For every
//! STFT frame (2048-point periodic Hann, hop 1024, the separator's analysis) OUT gets, as
//! little-endian f32: the frame's features (`per_frame` values), then per output bin the
//! drums' share `|D|² / (|D|² + |M − D|²)`, then per output bin `|M|`.
use std::io::Write;
use std::path::Path;

use tactus_engine::source::decode_all;
use tactus_separate::lowband::LowBand;
use tactus_separate::stft::{StftAnalysis, StftConfig};

fn mono(path: &str) -> Result<Vec<f32>, Box<dyn std::error::Error>> {
    let d = decode_all(Path::new(path))?;
    if d.info.sample_rate != 44_100 {
        return Err(format!("{path}: needs 44.1 kHz").into());
    }
    Ok(d.left
        .iter()
        .zip(&d.right)
        .map(|(l, r)| 0.5 * (l + r))
        .collect())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if !(4..=5).contains(&args.len()) {
        return Err("usage: lowband_features MIX DRUMS OUT.f32 [GAIN]".into());
    }
    let gain: f32 = args.get(4).map_or(Ok(1.0), |g| g.parse())?;
    let mix = mono(&args[1])?;
    let drums = mono(&args[2])?;
    let n = mix.len().min(drums.len());
    let rest: Vec<f32> = mix[..n]
        .iter()
        .zip(&drums[..n])
        .map(|(m, d)| m - d)
        .collect();
    let drums: Vec<f32> = drums[..n].iter().map(|d| gain * d).collect();
    let mix: Vec<f32> = rest.iter().zip(&drums).map(|(r, d)| r + d).collect();
    let cfg = StftConfig {
        n_fft: 2048,
        hop: 1024,
    };
    let mut lb = LowBand::new(44_100, cfg.n_fft, cfg.hop).ok_or("low-band model: bin width")?;
    let per = lb.model().per_frame();
    let k_out = lb.out_bins();
    let mut an = StftAnalysis::new(cfg, 3)?;
    let mut out: Vec<u8> = Vec::new();
    let mut feat = vec![0.0f32; per];
    let mut emit = |_: usize, sp: &[Vec<realfft::num_complex::Complex<f32>>]| {
        lb.frame_features(&sp[0], &mut feat);
        let mut row: Vec<f32> = feat.clone();
        for (d, r) in sp[1][..k_out].iter().zip(&sp[2][..k_out]) {
            let (d, r) = (d.norm_sqr(), r.norm_sqr());
            row.push(if d + r > 1e-30 { d / (d + r) } else { 0.0 });
        }
        row.extend(sp[0][..k_out].iter().map(|x| x.norm_sqr().sqrt()));
        for v in row {
            out.extend_from_slice(&v.to_le_bytes());
        }
    };
    an.push(&[&mix[..n], &drums[..n], &rest], &mut emit);
    an.finish(&mut emit);
    let tmp = format!("{}.tmp", args[3]);
    std::fs::File::create(&tmp)?.write_all(&out)?;
    std::fs::rename(&tmp, &args[3])?;
    Ok(())
}
