//! `tactus`: turns music into touch. See README.md for the tour.
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::{anyhow, bail, Context, Result};
use clap::{Parser, Subcommand, ValueEnum};

use tactus_dsp::Stem;
use tactus_engine::render::{render, RenderRequest};
use tactus_engine::{EngineConfig, Mode, PitchMethod, SeparatorChoice};
use tactus_glove::{write_atomic, GloveMap};

mod play;
mod plot;

#[derive(Parser)]
#[command(
    name = "tactus",
    version,
    about = "Turns music into touch: songs to haptic glove patterns"
)]
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

/// Settings shared by `render` and `play`: how the song becomes glove frames.
#[derive(clap::Args)]
struct EngineArgs {
    /// Source separator.
    #[arg(long, value_enum, default_value = "spectral")]
    separator: SepArg,
    /// ONNX model for --separator htdemucs|spleeter.
    #[arg(long)]
    model: Option<PathBuf>,
    /// Threads ONNX Runtime may use inside one network call (--separator
    /// htdemucs|spleeter) [default: the available cores].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    threads: Option<u32>,
    /// Supply a stem and skip separating it: NAME=PATH, NAME in drums, bass, vocals, other.
    #[arg(long = "stem", value_name = "NAME=PATH")]
    stems: Vec<String>,
    /// Bin length in milliseconds (default: 100 for render, as in the paper; 25 for play).
    #[arg(long)]
    bin_ms: Option<u32>,
    /// Pitch levels per melodic stem.
    #[arg(long, default_value_t = 8)]
    levels: u8,
    /// Glove map (TOML); the default is the paper's map.
    #[arg(long)]
    map: Option<PathBuf>,
    /// Pitch tracker.
    #[arg(long, value_enum, default_value = "pyin")]
    pitch: PitchArg,
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
        #[command(flatten)]
        engine: EngineArgs,
        /// Statistics: offline (whole track, paper) or streaming (causal, as live).
        #[arg(long, value_enum, default_value = "offline")]
        mode: ModeArg,
        /// Print which stages ran, what each cost, and the latency budget.
        #[arg(short, long)]
        verbose: bool,
    },
    /// Stream a song (rendered frame by frame as it plays) or a pattern file to a glove.
    Play {
        /// A song, or a pattern file (.json) from `tactus render`.
        input: PathBuf,
        /// Where the frames go: serial:PATH[@BAUD] | ble[:NAME|ADDRESS] | file:LOG.jsonl | emulator[:LOG.jsonl] | null
        #[arg(long)]
        glove: String,
        /// Send frames this much earlier (positive) or later (negative), on top of the
        /// 50 ms pin rise and the link latency.
        #[arg(long, default_value_t = 0, allow_hyphen_values = true)]
        offset_ms: i64,
        /// Time frames on the wall clock (this build has no audio output, so this is the only clock).
        #[arg(long)]
        no_audio: bool,
        #[command(flatten)]
        engine: EngineArgs,
    },
    /// Run a virtual glove on a serial port or pty: decode, check, log every actuation.
    Emulate {
        /// The port (e.g. the other end of a socat pty pair).
        #[arg(long)]
        port: PathBuf,
        /// Actuation log (JSON Lines).
        #[arg(long)]
        log: Option<PathBuf>,
        /// Stop after this many seconds (default: until Ctrl-C or the writer goes away).
        #[arg(long)]
        duration: Option<f64>,
    },
    /// List serial ports and BLE devices.
    Devices {
        /// Seconds to scan for BLE devices.
        #[arg(long, default_value_t = 3.0)]
        ble_scan_s: f64,
    },
    /// Score a features file against ground truth (a corpus song folder or truth.json).
    Eval {
        /// Features file from `tactus render --features`.
        features: PathBuf,
        /// Folder with truth.json, or the truth file itself.
        #[arg(long)]
        truth: PathBuf,
        /// Also write the report as JSON.
        #[arg(long)]
        json: Option<PathBuf>,
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
    let stem = Stem::from_name(name).ok_or_else(|| {
        anyhow!("--stem {s:?}: unknown stem {name:?} (drums, bass, vocals, other)")
    })?;
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
        bail!(
            "{}: the directory {} does not exist",
            path.display(),
            dir.display()
        );
    }
    Ok(())
}

fn engine_config(
    e: &EngineArgs,
    mode: Mode,
    default_bin_ms: u32,
) -> Result<(EngineConfig, Vec<(Stem, PathBuf)>)> {
    let model = |name: &str| -> Result<PathBuf> {
        e.model.clone().ok_or_else(|| {
            anyhow!("--separator {name} needs --model PATH (see README, \"ONNX models\")")
        })
    };
    let separator = match e.separator {
        SepArg::Spectral => SeparatorChoice::Spectral,
        SepArg::None => SeparatorChoice::None,
        SepArg::Spleeter => SeparatorChoice::Spleeter(model("spleeter")?),
        SepArg::Htdemucs => SeparatorChoice::HtDemucs(model("htdemucs")?),
    };
    let map = match &e.map {
        Some(p) => GloveMap::from_path(p).with_context(|| format!("--map {}", p.display()))?,
        None => GloveMap::default(),
    };
    if e.levels == 0 {
        bail!("--levels must be at least 1");
    }
    let bin_ms = e.bin_ms.unwrap_or(default_bin_ms);
    if bin_ms == 0 {
        bail!("--bin-ms must be at least 1");
    }
    let stems = e
        .stems
        .iter()
        .map(|s| parse_stem(s))
        .collect::<Result<Vec<_>>>()?;
    let cfg = EngineConfig {
        bin_ms,
        levels: e.levels,
        mode,
        pitch: match e.pitch {
            PitchArg::Yin => PitchMethod::Yin,
            PitchArg::Pyin => PitchMethod::Pyin,
        },
        map,
        separator,
        threads: e.threads.map_or(0, |n| n as usize),
        ..EngineConfig::default()
    };
    Ok((cfg, stems))
}

fn stop_flag() -> Arc<AtomicBool> {
    let stop = Arc::new(AtomicBool::new(false));
    let s = stop.clone();
    // A second handler cannot be installed; then Ctrl-C simply ends the process.
    let _ = ctrlc::set_handler(move || s.store(true, Ordering::SeqCst));
    stop
}

fn run(cli: Cli) -> Result<()> {
    match cli.cmd {
        Cmd::Play {
            input,
            glove,
            offset_ms,
            no_audio,
            engine,
        } => play::run(&input, &glove, offset_ms, no_audio, &engine),
        Cmd::Emulate {
            port,
            log,
            duration,
        } => play::emulate(&port, log.as_deref(), duration),
        Cmd::Devices { ble_scan_s } => {
            print!(
                "{}",
                tactus_transport::devices_report(std::time::Duration::from_secs_f64(
                    ble_scan_s.max(0.0)
                ))
            );
            Ok(())
        }
        Cmd::Eval {
            features,
            truth,
            json,
        } => {
            let truth_path = if truth.is_dir() {
                truth.join("truth.json")
            } else {
                truth
            };
            let t = std::fs::read_to_string(&truth_path)
                .with_context(|| format!("reading {}", truth_path.display()))?;
            let t = tactus_eval::Truth::from_json_str(&t)
                .with_context(|| truth_path.display().to_string())?;
            let f = std::fs::read_to_string(&features)
                .with_context(|| format!("reading {}", features.display()))?;
            let f = tactus_eval::FeaturesLike::from_json_str(&f)
                .with_context(|| features.display().to_string())?;
            let report = tactus_eval::evaluate(&f, &t);
            print!("{}", report.to_markdown());
            if let Some(p) = &json {
                check_writable(p)?;
                let j = report.to_json();
                write_atomic(p, |w| w.write_all(j.as_bytes()))
                    .with_context(|| format!("writing {}", p.display()))?;
            }
            Ok(())
        }
        Cmd::Render {
            input,
            output,
            features,
            plot,
            engine,
            mode,
            verbose,
        } => {
            let mode = match mode {
                ModeArg::Offline => Mode::Offline,
                ModeArg::Streaming => Mode::Streaming,
            };
            let (config, stems) = engine_config(&engine, mode, 100)?;
            for p in [&output, &features, &plot].into_iter().flatten() {
                check_writable(p)?;
            }
            if let Some(p) = &plot {
                plot::check_extension(p)?;
            }
            let req = RenderRequest {
                input: input.clone(),
                stems,
                config,
            };
            let bar = if std::io::stderr().is_terminal() {
                let b = indicatif::ProgressBar::new(1000);
                b.set_style(
                    indicatif::ProgressStyle::with_template(
                        "{spinner} {msg} [{bar:40}] {percent}% {elapsed}",
                    )
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
                write_atomic(p, |w| w.write_all(json.as_bytes()))
                    .with_context(|| format!("writing {}", p.display()))?;
            }
            if let Some(p) = &features {
                let json = out.features.to_json_string()?;
                write_atomic(p, |w| w.write_all(json.as_bytes()))
                    .with_context(|| format!("writing {}", p.display()))?;
            }
            if let Some(p) = &plot {
                let svg = plot::render_svg(&out.pattern, &out.features);
                write_atomic(p, |w| w.write_all(svg.as_bytes()))
                    .with_context(|| format!("writing {}", p.display()))?;
            }
            if verbose {
                eprintln!(
                    "tactus: {} ({:.1} s), separator {}, stems {}",
                    input.display(),
                    out.duration_s,
                    out.separator.unwrap_or("none needed"),
                    out.stems
                        .iter()
                        .map(|s| s.name())
                        .collect::<Vec<_>>()
                        .join(", ")
                );
                let total = out
                    .times
                    .stages
                    .last()
                    .map(|t| t.1.as_secs_f64())
                    .unwrap_or(0.0);
                for (name, t) in &out.times.stages {
                    eprintln!("  {:<36} {:>9.3} s", name, t.as_secs_f64());
                }
                if total > 0.0 {
                    eprintln!("  speed: {:.1}x real time", out.duration_s / total);
                }
                if let Some(st) = &out.segments {
                    eprintln!(
                        "  network segments: {}, per segment mean {:.3} s, min {:.3} s, max {:.3} s",
                        st.segments,
                        st.network_mean().as_secs_f64(),
                        st.network_min.as_secs_f64(),
                        st.network_max.as_secs_f64()
                    );
                    eprintln!(
                        "  outside the network (STFT, iSTFT, overlap-add, masks): {:.3} s = {:.1} % of the network's {:.3} s",
                        st.outside().as_secs_f64(),
                        100.0 * st.outside_share(),
                        st.network.as_secs_f64()
                    );
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
