//! `tactus`: turns music into touch. See README.md for the tour.
#![forbid(unsafe_code)]
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::{anyhow, bail, Context, Result};
use clap::{Parser, Subcommand, ValueEnum};

use tactus_dsp::Stem;
use tactus_engine::render::{render, RenderRequest};
use tactus_engine::{EngineConfig, LevelRule, Mode, PitchMethod, SeparatorChoice};
use tactus_glove::{write_atomic, GloveMap};

#[cfg(feature = "audio")]
mod audio;
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
    /// pYIN, and harmonic-sum salience for the bass.
    Auto,
    Yin,
    Pyin,
    /// Harmonic-sum salience + Viterbi (made for a bass line in a mix) on every stem.
    Shs,
}

#[derive(Clone, Copy, ValueEnum)]
enum LevelRuleArg {
    Follow,
    Paper,
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
    #[arg(long, value_enum, default_value = "auto")]
    pitch: PitchArg,
    /// How pitch becomes levels: follow (floored Tukey IQR, a streaming range prior) or the
    /// paper's rule.
    #[arg(long, value_enum, default_value = "follow")]
    levels_rule: LevelRuleArg,
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
        /// Plot to write (.svg, or .png rasterised with the system's fonts).
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
        /// Play no sound and time frames on the wall clock. Without it, a build with the
        /// `audio` feature plays the song on the default output device and times frames on
        /// the audio clock.
        #[arg(long)]
        no_audio: bool,
        #[command(flatten)]
        engine: EngineArgs,
    },
    /// Turn live audio (a microphone, a sound server's monitor) into touch, as it plays
    /// (needs the `audio` feature).
    Live {
        /// Input device name (see `tactus devices`; default: the system's default input).
        #[arg(long)]
        input: Option<String>,
        /// Where the frames go: serial:PATH[@BAUD] | ble[:NAME|ADDRESS] | file:LOG.jsonl | emulator[:LOG.jsonl] | null
        #[arg(long)]
        glove: String,
        /// Stop after this many seconds of captured audio (default: until Ctrl-C).
        #[arg(long)]
        seconds: Option<f64>,
        /// Show a one-line status: time, frames, dropped, overruns, link, input level.
        #[arg(long)]
        tui: bool,
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
    /// List serial ports, BLE devices and audio devices.
    Devices {
        /// Seconds to scan for BLE devices.
        #[arg(long, default_value_t = 3.0)]
        ble_scan_s: f64,
    },
    /// Score a features file against ground truth (a corpus song folder or truth.json), or
    /// a virtual glove's actuation log against the pattern it played (the paper's Table 3).
    #[command(
        after_help = "Forms:\n  tactus eval FEATURES.json --truth SONG_DIR|truth.json [--json OUT]\n  tactus eval --glove-log LOG.jsonl --pattern PATTERN.json [FEATURES.json] [--json OUT]"
    )]
    Eval {
        /// Features file from `tactus render --features` (with --glove-log: the features
        /// rendered with the pattern, for the scores against the audio).
        features: Option<PathBuf>,
        /// Folder with truth.json, or the truth file itself.
        #[arg(long, conflicts_with_all = ["glove_log", "pattern"])]
        truth: Option<PathBuf>,
        /// Actuation log from `tactus emulate --log` (JSON Lines).
        #[arg(long, requires = "pattern")]
        glove_log: Option<PathBuf>,
        /// The pattern file that was played (with --glove-log).
        #[arg(long, requires = "glove_log")]
        pattern: Option<PathBuf>,
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
            PitchArg::Shs => PitchMethod::Shs,
            PitchArg::Auto => PitchMethod::Auto,
        },
        level_rule: match e.levels_rule {
            LevelRuleArg::Follow => LevelRule::Follow,
            LevelRuleArg::Paper => LevelRule::Paper,
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
        Cmd::Live {
            input,
            glove,
            seconds,
            tui,
            engine,
        } => {
            #[cfg(feature = "audio")]
            {
                play::live(input.as_deref(), &glove, seconds, tui, &engine)
            }
            #[cfg(not(feature = "audio"))]
            {
                let _ = (input, glove, seconds, tui, engine);
                bail!("this tactus was built without audio input: rebuild with `--features audio` (needs libasound2-dev)")
            }
        }
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
            #[cfg(feature = "audio")]
            print!("{}", audio::devices_report());
            #[cfg(not(feature = "audio"))]
            println!("Audio devices:\n  (unavailable: built without the `audio` feature; rebuild with --features audio)");
            Ok(())
        }
        Cmd::Eval {
            features,
            truth,
            glove_log,
            pattern,
            json,
        } => {
            let read_features = |p: &Path| -> Result<tactus_eval::FeaturesLike> {
                let f = std::fs::read_to_string(p)
                    .with_context(|| format!("reading {}", p.display()))?;
                tactus_eval::FeaturesLike::from_json_str(&f)
                    .with_context(|| p.display().to_string())
            };
            if let Some(p) = &json {
                check_writable(p)?;
            }
            let (text, j) = match (glove_log, pattern, truth) {
                (Some(log), Some(pattern), None) => {
                    let pat = tactus_glove::Pattern::from_path(&pattern)
                        .with_context(|| pattern.display().to_string())?;
                    let l = std::fs::read_to_string(&log)
                        .with_context(|| format!("reading {}", log.display()))?;
                    let l = tactus_eval::glove_log::parse_actuation_log(&l)
                        .with_context(|| log.display().to_string())?;
                    let f = features.as_deref().map(read_features).transpose()?;
                    let r = tactus_eval::glove_log::glove_fidelity(
                        &l,
                        &pat,
                        f.as_ref(),
                        tactus_eval::glove_log::PAPER_BIN_S,
                    )
                    .context("scoring the glove log")?;
                    (r.to_markdown(), r.to_json())
                }
                (None, None, Some(truth)) => {
                    let features = features
                        .ok_or_else(|| anyhow!("eval --truth needs a FEATURES.json"))?;
                    let truth_path = if truth.is_dir() {
                        truth.join("truth.json")
                    } else {
                        truth
                    };
                    let t = std::fs::read_to_string(&truth_path)
                        .with_context(|| format!("reading {}", truth_path.display()))?;
                    let t = tactus_eval::Truth::from_json_str(&t)
                        .with_context(|| truth_path.display().to_string())?;
                    let f = read_features(&features)?;
                    let report = tactus_eval::evaluate(&f, &t);
                    (report.to_markdown(), report.to_json())
                }
                _ => bail!(
                    "eval needs FEATURES.json --truth DIR, or --glove-log LOG.jsonl --pattern PATTERN.json"
                ),
            };
            print!("{text}");
            if let Some(p) = &json {
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
            let plot_format = plot.as_deref().map(plot::format_of).transpose()?;
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
            // Everything is drawn before anything is written, so a failure leaves no output.
            let plot_bytes = match (&plot, plot_format) {
                (Some(p), Some(format)) => {
                    let svg = plot::render_svg(&out.pattern, &out.features);
                    Some(match format {
                        plot::PlotFormat::Svg => svg.into_bytes(),
                        plot::PlotFormat::Png => {
                            let png = plot::render_png(&svg)
                                .with_context(|| format!("--plot {}", p.display()))?;
                            if !png.fonts {
                                eprintln!(
                                    "tactus: warning: --plot {}: no system font found, so the PNG \
                                     has no text (install e.g. fonts-dejavu-core, or use .svg)",
                                    p.display()
                                );
                            }
                            png.bytes
                        }
                    })
                }
                _ => None,
            };
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
            if let (Some(p), Some(bytes)) = (&plot, &plot_bytes) {
                write_atomic(p, |w| w.write_all(bytes))
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
