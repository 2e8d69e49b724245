//! Dumps the drum transcriber's front end (log mel frames, `tactus_dsp::melbank`) for the
//! training script `models/drums/train.py`, computed by the very code the engine runs.
//!
//! ```text
//! cargo run --release -p tactus-engine --example drum_features -- INPUT OUT.f32 [iso|sep|mix] [MODEL]
//! ```
//! * `iso`: INPUT is a drum stem; it is downmixed to mono.
//! * `sep`: INPUT is a mix; the embedded spectral separator's drum stem is used (what the
//!   default render feeds the transcriber).
//! * `mix`: INPUT is a mix, downmixed to mono (the transcriber on the mix itself).
//! * `back`: INPUT is a mix; the separator's other stems (bass + vocals + other), the
//!   backing beside its drum stem.
//! * `iso-short`, `sep-short`, `mix-short`: the same signals through the short view's front
//!   end (`MelConfig::drums_short`: a 1024-point frame ending where the 2048-point one does),
//!   the second view of a model with input feature set 3.
//!
//! Every input then goes through the engine's drum denoiser (30 Hz high-pass + 3-sample
//! median). OUT is little-endian f32, one row of `bands` values per 10 ms hop; with MODEL (a
//! drum model file), one row of the transcriber's 4 activations per hop instead, so a
//! training script can check that the engine runs its network as it does.
use std::io::Write;
use std::path::Path;

use tactus_dsp::drums::{DrumModel, DrumTranscriber};
use tactus_dsp::melbank::{MelBank, MelConfig};
use tactus_dsp::{HopStage, Stem};
use tactus_engine::source::decode_all;
use tactus_engine::track::Denoise;
use tactus_separate::spectral::{SpectralConfig, SpectralSeparator};
use tactus_separate::{Separator, StemOutput, StemSet};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        return Err("usage: drum_features INPUT OUT.f32 [iso|sep|mix]".into());
    }
    let mode = args.get(3).map(String::as_str).unwrap_or("iso");
    let (mode, short) = match mode.strip_suffix("-short") {
        Some(m) => (m, true),
        None => (mode, false),
    };
    let d = decode_all(Path::new(&args[1]))?;
    let sr = d.info.sample_rate;
    if sr != 44_100 {
        return Err(format!("{}: needs 44.1 kHz, got {sr}", args[1]).into());
    }
    let mut x: Vec<f32> = match mode {
        "iso" | "mix" => d
            .left
            .iter()
            .zip(&d.right)
            .map(|(l, r)| 0.5 * (l + r))
            .collect(),
        "sep" => {
            let stems = StemSet::default().with(Stem::Drums);
            let mut sep = SpectralSeparator::new(sr, stems, SpectralConfig::default())?;
            let mut out = StemOutput::with_capacity(stems, d.left.len());
            for (l, r) in d.left.chunks(88_200).zip(d.right.chunks(88_200)) {
                sep.process(l, r, &mut out);
            }
            sep.finish(&mut out);
            out.take(Stem::Drums)
        }
        "back" => backing(&d.left, &d.right, sr)?,
        m => return Err(format!("unknown mode {m}").into()),
    };
    let mut den = Denoise::new(30.0, sr)?;
    den.process_inplace(&mut x);
    let mut rows: Vec<f32> = Vec::new();
    if let Some(model) = args.get(4) {
        let model = DrumModel::from_bytes(&std::fs::read(model)?)?;
        let mut t = DrumTranscriber::with_model(sr, model)?;
        if t.wants_backing() && mode == "sep" {
            // The render's input: the separated drum stem with the backing beside it.
            let mut back = backing(&d.left, &d.right, sr)?;
            Denoise::new(30.0, sr)?.process_inplace(&mut back);
            for (c, b) in x.chunks(88_200).zip(back.chunks(88_200)) {
                t.process_with(c, Some(b), &mut |_, f| {
                    rows.extend_from_slice(&f.activation)
                });
            }
        } else {
            for c in x.chunks(88_200) {
                t.process(c, &mut |_, f| rows.extend_from_slice(&f.activation));
            }
        }
        t.finish(&mut |_, f| rows.extend_from_slice(&f.activation));
    } else {
        let cfg = if short {
            MelConfig::drums_short(sr)
        } else {
            MelConfig::drums(sr)
        };
        let mut mel = MelBank::new(cfg)?;
        for c in x.chunks(88_200) {
            mel.process_bands(c, &mut |_, b| rows.extend_from_slice(b));
        }
        mel.finish_bands(&mut |_, b| rows.extend_from_slice(b));
    }
    let mut f = std::io::BufWriter::new(std::fs::File::create(&args[2])?);
    for v in rows {
        f.write_all(&v.to_le_bytes())?;
    }
    f.flush()?;
    Ok(())
}

/// The backing the spectral separator leaves beside its drum stem: bass + vocals + other,
/// summed (what the engine feeds a transcriber with the backing view).
fn backing(left: &[f32], right: &[f32], sr: u32) -> Result<Vec<f32>, Box<dyn std::error::Error>> {
    let stems = StemSet::default()
        .with(Stem::Bass)
        .with(Stem::Vocals)
        .with(Stem::Other);
    let mut sep = SpectralSeparator::new(sr, stems, SpectralConfig::default())?;
    let mut out = StemOutput::with_capacity(stems, left.len());
    for (l, r) in left.chunks(88_200).zip(right.chunks(88_200)) {
        sep.process(l, r, &mut out);
    }
    sep.finish(&mut out);
    let (b, v, o) = (
        out.take(Stem::Bass),
        out.take(Stem::Vocals),
        out.take(Stem::Other),
    );
    Ok(b.iter()
        .zip(&v)
        .zip(&o)
        .map(|((b, v), o)| b + v + o)
        .collect())
}
