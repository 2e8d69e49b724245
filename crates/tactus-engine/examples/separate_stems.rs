//! Writes the spectral separator's four stems of a song as 32-bit float WAV files, for
//! looking at what a stage downstream hears (diagnosis; not part of the render).
//!
//! ```text
//! cargo run --release -p tactus-engine --example separate_stems -- SONG OUT_PREFIX [--kit-mask off]
//! ```
//! writes `OUT_PREFIX.{drums,bass,vocals,other}.wav` (mono: the separator's mid channel).
use std::io::Write;
use std::path::Path;

use tactus_dsp::Stem;
use tactus_engine::source::decode_all;
use tactus_separate::spectral::{SpectralConfig, SpectralSeparator};
use tactus_separate::{Separator, StemOutput, StemSet};

fn write_wav(path: &str, rate: u32, x: &[f32]) -> std::io::Result<()> {
    let data = 4 * x.len() as u32;
    let mut b = Vec::with_capacity(44 + data as usize);
    b.extend_from_slice(b"RIFF");
    b.extend_from_slice(&(36 + data).to_le_bytes());
    b.extend_from_slice(b"WAVEfmt ");
    b.extend_from_slice(&16u32.to_le_bytes());
    b.extend_from_slice(&3u16.to_le_bytes()); // IEEE float
    b.extend_from_slice(&1u16.to_le_bytes());
    b.extend_from_slice(&rate.to_le_bytes());
    b.extend_from_slice(&(rate * 4).to_le_bytes());
    b.extend_from_slice(&4u16.to_le_bytes());
    b.extend_from_slice(&32u16.to_le_bytes());
    b.extend_from_slice(b"data");
    b.extend_from_slice(&data.to_le_bytes());
    for v in x {
        b.extend_from_slice(&v.to_le_bytes());
    }
    let tmp = format!("{path}.tmp");
    std::fs::File::create(&tmp)?.write_all(&b)?;
    std::fs::rename(&tmp, path)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        return Err("usage: separate_stems SONG OUT_PREFIX [--kit-mask off]".into());
    }
    let d = decode_all(Path::new(&args[1]))?;
    let cfg = SpectralConfig {
        low_band_drums: !args[3..].iter().any(|a| a == "off"),
        ..SpectralConfig::default()
    };
    let mut sep = SpectralSeparator::new(d.info.sample_rate, StemSet::all(), cfg)?;
    let mut out = StemOutput::new();
    sep.process(&d.left, &d.right, &mut out);
    sep.finish(&mut out);
    for s in Stem::ALL {
        write_wav(
            &format!("{}.{}.wav", args[2], s.name()),
            d.info.sample_rate,
            out.get(s),
        )?;
    }
    Ok(())
}
