//! `tactus`: turns music into touch. See README.md for the tour.
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{anyhow, bail, Context, Result};
use clap::{Parser, Subcommand, ValueEnum};

use tactus_dsp::Stem;
use tactus_engine::render::{render, RenderRequest};
use tactus_engine::{EngineConfig, Mode, PitchMethod, SeparatorChoice};
use tactus_glove::{write_atomic, GloveMap};

mod plot;

#[derive(Parser)]
#[command(name = "tactus", version, about = "Turns music into touch: songs to haptic glove patterns")]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Clone, Copy, ValueEnum)]
enum SepArg {
    Spectral,
    Htdemucs,
    Spleeter,
    None,
}

#[derive(Clone, Copy, ValueEnum)]
enum ModeArg {
    Offline,
    Streaming,
}

#[derive(Clone, Copy, ValueEnum)]
enum PitchArg {
    Yin,
    Pyin,
}

#[derive(Subcommand)]
enum Cmd {
    /// Render a song to a glove pattern (and optionally features and a plot).
    Render {
        /// The song: WAV, FLAC, MP3, OGG/Vorbis, AAC/M4A.
        input: PathBuf,
        /// Pattern file to write ("-" for stdout).
        #[arg(short = 'o', long = "output")]
        output: Option<PathBuf>,
        /// Features file to write (JSON).
        #[arg(long)]
        features: Option<PathBuf>,
        /// Plot to write (.svg).
        #[arg(long)]
        plot: Option<PathBuf>,
        /// Source separator.
        #[arg(long, value_enum, default_value = "spectral")]
        separator: SepArg,
        /// ONNX model for --separator htdemucs|spleeter.
        #[arg(long)]
        model: Option<PathBuf>,
        /// Supply a stem and skip separating it: NAME=PATH, NAME in drums, bass, vocals, other.
        #[arg(long = "stem", value_name = "NAME=PATH")]
        stems: Vec<String>,
        /// Bin length in milliseconds.
        #[arg(long, default_value_t = 100)]
        bin_ms: u32,
        /// Pitch levels per melodic stem.
        #[arg(long, default_value_t = 8)]
        levels: u8,
        /// Glove map (TOML); the default is the paper's map.
        #[arg(long)]
        map: Option<PathBuf>,
        /// Statistics: offline (whole track, paper) or streaming (causal, as live).
        #[arg(long, value_enum, default_value = "offline")]
        mode: ModeArg,
        /// Pitch tracker.
        #[arg(long, value_enum, default_value = "pyin")]
        pitch: PitchArg,
        /// Print which stages ran, what each cost, and the latency budget.
        #[arg(short, long)]
        verbose: bool,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            let msg = format!("{e:#}").replace('\n', " ");
            eprintln!("tactus: error: {msg}");
            ExitCode::FAILURE
        }
    }
}

fn parse_stem(s: &str) -> Result<(Stem, PathBuf)> {
    let (name, path) = s
        .split_once('=')
        .ok_or_else(|| anyhow!("--stem {s:?}: expected NAME=PATH"))?;
    let stem = Stem::from_name(name)
        .ok_or_else(|| anyhow!("--stem {s:?}: unknown stem {name:?} (drums, bass, vocals, other)"))?;
    Ok((stem, PathBuf::from(path)))
}

fn check_writable(path: &Path) -> Result<()> {
    if path == Path::new("-") {
        return Ok(());
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        bail!("{}: the directory {} does not exist", path.display(), dir.display());
    }
    Ok(())
}

fn run(cli: Cli) -> Result<()> {
    match cli.cmd {
        Cmd::Render {
            input,
            output,
            features,
            plot,
            separator,
            model,
            stems,
            bin_ms,
            levels,
            map,
            mode,
            pitch,
            verbose,
        } => {
            let separator = match separator {
                SepArg::Spectral => SeparatorChoice::Spectral,
                SepArg::None => SeparatorChoice::None,
                SepArg::Htdemucs | SepArg::Spleeter => bail!(
                    "the ONNX separators are not part of this build yet; use --separator spectral (default) or none{}",
                    model.map(|m| format!(" (model {} not loaded)", m.display())).unwrap_or_default()
                ),
            };
            let map = match &map {
                Some(p) => GloveMap::from_path(p).with_context(|| format!("--map {}", p.display()))?,
                None => GloveMap::default(),
            };
            if levels == 0 {
                bail!("--levels must be at least 1");
            }
            if bin_ms == 0 {
                bail!("--bin-ms must be at least 1");
            }
            let stems = stems.iter().map(|s| parse_stem(s)).collect::<Result<Vec<_>>>()?;
            for p in [&output, &features, &plot].into_iter().flatten() {
                check_writable(p)?;
            }
            if let Some(p) = &plot {
                plot::check_extension(p)?;
            }
            let req = RenderRequest {
                input: input.clone(),
                stems,
                config: EngineConfig {
                    bin_ms,
                    levels,
                    mode: match mode {
                        ModeArg::Offline => Mode::Offline,
                        ModeArg::Streaming => Mode::Streaming,
                    },
                    pitch: match pitch {
                        PitchArg::Yin => PitchMethod::Yin,
                        PitchArg::Pyin => PitchMethod::Pyin,
                    },
                    map,
                    separator,
                    ..EngineConfig::default()
                },
            };
            let bar = if std::io::stderr().is_terminal() {
                let b = indicatif::ProgressBar::new(1000);
                b.set_style(
                    indicatif::ProgressStyle::with_template("{spinner} {msg} [{bar:40}] {percent}% {elapsed}")
                        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
                );
                b.set_message(input.display().to_string());
                Some(b)
            } else {
                None
            };
            let result = render(&req, &mut |f| {
                if let Some(b) = &bar {
                    b.set_position((f * 1000.0) as u64);
                }
            });
            if let Some(b) = &bar {
                b.finish_and_clear();
            }
            let out = result?;
            for w in &out.warnings {
                eprintln!("tactus: warning: {w}");
            }
            if let Some(p) = &output {
                let json = out.pattern.to_json_string()?;
                write_atomic(p, |w| w.write_all(json.as_bytes())).with_context(|| format!("writing {}", p.display()))?;
            }
            if let Some(p) = &features {
                let json = out.features.to_json_string()?;
                write_atomic(p, |w| w.write_all(json.as_bytes())).with_context(|| format!("writing {}", p.display()))?;
            }
            if let Some(p) = &plot {
                let svg = plot::render_svg(&out.pattern, &out.features);
                write_atomic(p, |w| w.write_all(svg.as_bytes())).with_context(|| format!("writing {}", p.display()))?;
            }
            if verbose {
                eprintln!(
                    "tactus: {} ({:.1} s), separator {}, stems {}",
                    input.display(),
                    out.duration_s,
                    out.separator.unwrap_or("none needed"),
                    out.stems.iter().map(|s| s.name()).collect::<Vec<_>>().join(", ")
                );
                let total = out.times.stages.last().map(|t| t.1.as_secs_f64()).unwrap_or(0.0);
                for (name, t) in &out.times.stages {
                    eprintln!("  {:<36} {:>9.3} s", name, t.as_secs_f64());
                }
                if total > 0.0 {
                    eprintln!("  speed: {:.1}x real time", out.duration_s / total);
                }
                eprintln!("  latency budget (streaming):");
                let mut sum = 0.0;
                for (name, ms) in &out.latency {
                    sum += ms;
                    eprintln!("    {:<44} {:>7.1} ms", name, ms);
                }
                eprintln!("    {:<44} {:>7.1} ms", "total", sum);
            }
            Ok(())
        }
    }
}
