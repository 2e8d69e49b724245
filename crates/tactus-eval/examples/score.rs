//! Scores a features file against a corpus truth and prints the Markdown report.
//!
//! ```sh
//! cargo run -p tactus-eval --example score -- corpus/fixtures/bwv66-6_96bpm/truth.json FEAT.json
//! cargo run -p tactus-eval --example score -- corpus/fixtures/bwv66-6_96bpm/truth.json
//! ```
//! Without a features file it scores "oracle features" built from the truth itself
//! (pitch = truth f0, levels = truth discretized into 8 levels, onsets = truth): the
//! floor of the paper's MAE / DTW that discretization alone causes.
use tactus_dsp::{Band, Stem};
use tactus_eval::levels::{bin_pitch, discretize};
use tactus_eval::{evaluate, FeaturesLike, Truth};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(truth_path) = args.first() else {
        eprintln!("usage: score TRUTH.json [FEATURES.json]");
        std::process::exit(2);
    };
    let truth = Truth::from_json_str(&std::fs::read_to_string(truth_path)?)?;
    let features = match args.get(1) {
        Some(p) => FeaturesLike::from_json_str(&std::fs::read_to_string(p)?)?,
        None => {
            let mut f = FeaturesLike {
                hop_s: truth.hop_s,
                bin_s: 0.1,
                ..Default::default()
            };
            for stem in Stem::MELODIC {
                if let Some(f0) = truth.f0(stem) {
                    let levels = discretize(&bin_pitch(f0, truth.hop_s, 0.1)?, 8)?;
                    f.pitch_hz.insert(stem.name().into(), f0.to_vec());
                    f.levels.insert(stem.name().into(), levels);
                }
            }
            for band in Band::ALL {
                f.onsets_s
                    .insert(band.name().into(), truth.onset_times(band));
            }
            f
        }
    };
    print!("{}", evaluate(&features, &truth).to_markdown());
    Ok(())
}
