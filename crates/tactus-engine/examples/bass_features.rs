//! Dumps the learned bass salience's input features (`tactus_dsp::bassnet`) of a song's
//! separated bass stem, computed by the code the render runs, for `models/bassnet/train.py`.
//!
//! ```text
//! cargo run --release -p tactus-engine --example bass_features -- MIX OUT.f32 [--stem] [--lead BANDS LOW_HZ [--harmonic]]
//! ```
//! MIX goes through the default spectral separator (with `--stem`, MIX is taken as the bass
//! stem itself), then the bass chain's front end: the denoiser (30 Hz high-pass + 3-sample
//! median), the decimator to the pitch rate, 10 ms hops of the harmonic sum's frame. OUT
//! gets, per hop, `tactus_dsp::bassnet::BANDS` little-endian f32 values. With `--lead`, the
//! vocals stem and the vocals chain's front end (60 Hz high-pass, the melody frame) with
//! BANDS bands from LOW_HZ (the lead model's). With `--lead … --harmonic`, the separator's
//! harmonic sum (vocals + bass + other, the harmonic-view lead models' input) instead of
//! the vocals stem. With `--live`, the live profile's separator
//! (`tactus_engine::profile::separator`) instead of the default one (with `--harmonic`:
//! its harmonic sum). `--frame N` sets the frame at the pitch rate (default: the
//! harmonic sum's; the FFT length stays the preset's).
use std::io::Write;
use std::path::Path;

use tactus_dsp::bassnet::{BassFront, BANDS};
use tactus_dsp::framer::Framer;
use tactus_dsp::shs::ShsConfig;
use tactus_dsp::Stem;
use tactus_engine::source::decode_all;
use tactus_engine::track::{Decimator, Denoise};
use tactus_separate::spectral::{SpectralConfig, SpectralSeparator};
use tactus_separate::{Separator, StemOutput, StemSet};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        return Err("usage: bass_features MIX OUT.f32 [--stem]".into());
    }
    let d = decode_all(Path::new(&args[1]))?;
    let rate = d.info.sample_rate;
    let lead = args.iter().position(|a| a == "--lead");
    let (stem, hp, bands, low_hz) = match lead {
        Some(i) => (
            Stem::Vocals,
            60.0,
            args.get(i + 1)
                .ok_or("--lead BANDS LOW_HZ")?
                .parse::<usize>()?,
            args.get(i + 2)
                .ok_or("--lead BANDS LOW_HZ")?
                .parse::<f32>()?,
        ),
        None => (Stem::Bass, 30.0, BANDS, tactus_dsp::bassnet::LOW_HZ),
    };
    let mut bass: Vec<f32> = if args[3..].iter().any(|a| a == "--stem") {
        d.left
            .iter()
            .zip(&d.right)
            .map(|(l, r)| 0.5 * (l + r))
            .collect()
    } else {
        let live = args[3..].iter().any(|a| a == "--live");
        let sep_cfg = if live {
            tactus_engine::profile::separator()
        } else {
            SpectralConfig::default()
        };
        let mut sep = SpectralSeparator::new(rate, StemSet::all(), sep_cfg)?;
        let mut out = StemOutput::new();
        sep.process(&d.left, &d.right, &mut out);
        sep.finish(&mut out);
        if args[3..].iter().any(|a| a == "--harmonic") {
            // The lead's harmonic view: vocals + bass + other, as the engine sums them.
            let (v, b, o) = (
                out.get(Stem::Vocals),
                out.get(Stem::Bass),
                out.get(Stem::Other),
            );
            v.iter()
                .zip(b)
                .zip(o)
                .map(|((v, b), o)| b + v + o)
                .collect()
        } else {
            out.get(stem).to_vec()
        }
    };
    // The stem's chain (tactus_engine::engine::StemChain, track::PitchTrack).
    Denoise::new(hp, rate)?.process_inplace(&mut bass);
    let (fmin, fmax) = stem.pitch_range_hz().ok_or("the stem has a pitch range")?;
    let factor = Decimator::factor_for(rate, fmax);
    let mut dec = Decimator::new(rate, factor)?;
    dec.process(&bass);
    let low = dec.output().to_vec();
    let mut cfg = if lead.is_some() {
        ShsConfig::melody(rate / factor as u32, fmin, fmax)
    } else {
        ShsConfig::new(rate / factor as u32, fmin, fmax)
    };
    if let Some(i) = args.iter().position(|a| a == "--frame") {
        cfg.frame = args.get(i + 1).ok_or("--frame N")?.parse()?;
    }
    let hop = ((rate / factor as u32) as f64 * 0.010).round() as usize;
    let mut framer = Framer::new(cfg.frame, hop)?;
    let mut front =
        BassFront::with_bands(rate / factor as u32, cfg.frame, cfg.n_fft, bands, low_hz)?;
    let mut feat = vec![0.0f32; bands];
    let mut bytes: Vec<u8> = Vec::new();
    let mut emit = |_: usize, fr: &[f32]| {
        front.features(fr, &mut feat);
        for v in &feat {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    };
    framer.push(&low, &mut emit);
    framer.finish(&mut emit);
    let tmp = format!("{}.tmp", args[2]);
    std::fs::File::create(&tmp)?.write_all(&bytes)?;
    std::fs::rename(&tmp, &args[2])?;
    Ok(())
}
