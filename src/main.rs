//! `tactus`: turns music into touch. See README.md for the tour.
#![forbid(unsafe_code)]
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};

use tactus_glove::write_atomic;

mod args;
mod batch;
mod play;
mod render;

use args::{EngineArgs, ModeArg};

#[derive(Parser)]
#[command(
    name = "tactus",
    version,
    about = "Turns music into touch: songs to haptic glove patterns",
    // `tactus` alone prints the command list; `help` is a command of ours, so that
    // `tactus help --help` works too.
    arg_required_else_help = true,
    disable_help_subcommand = true
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Render a song to a glove pattern (and optionally features and a plot).
    Render(render::RenderArgs),
    /// Stream a song (rendered frame by frame as it plays) or a pattern file to a glove.
    Play(play::PlayArgs),
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
        #[arg(long, value_parser = seconds_parser(0.001, MAX_SECONDS))]
        seconds: Option<f64>,
        /// Draw the glove in the terminal as it plays: five fingers, two cells of eight
        /// dots each, input level, latency, link and counters (stdout must be a terminal).
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
        #[arg(long, value_parser = seconds_parser(0.0, MAX_SECONDS))]
        duration: Option<f64>,
        /// Stop once frames have arrived and then none for 2 s (the player has closed the
        /// link).
        #[arg(long)]
        until_idle: bool,
        /// Also list every received pin frame in the JSON report on stdout (the actuation
        /// log, --log, has them too).
        #[arg(long)]
        json_frames: bool,
    },
    /// List serial ports, BLE devices and audio devices.
    Devices {
        /// Seconds to scan for BLE devices (0..=600).
        #[arg(long, default_value_t = 3.0, value_parser = seconds_parser(0.0, 600.0))]
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
    /// Print this message or the help of the given subcommand(s)
    Help {
        /// The command to explain (default: the list of commands).
        command: Option<String>,
    },
}

/// `tactus help [COMMAND]`: the text of `tactus [COMMAND] --help`.
fn help(command: Option<&str>) -> Result<()> {
    let argv = ["tactus"].into_iter().chain(command).chain(["--help"]);
    match Cli::try_parse_from(argv) {
        Err(e) if !e.use_stderr() => e.exit(),
        Err(e) => bail!("{}", one_line(&e)),
        Ok(_) => Ok(()),
    }
}

/// The longest duration any option accepts: 10⁷ s (116 days).
const MAX_SECONDS: f64 = 1e7;

/// A parser for a duration in seconds: a finite number within `min..=max`.
fn seconds_parser(min: f64, max: f64) -> impl Fn(&str) -> Result<f64, String> + Clone {
    move |s: &str| {
        let v: f64 = s
            .trim()
            .parse()
            .map_err(|_| format!("{s:?} is not a number of seconds"))?;
        if !v.is_finite() || v < min || v > max {
            return Err(format!(
                "must be a finite number of seconds from {min} to {max}"
            ));
        }
        Ok(v)
    }
}

/// clap's error as one line (its usage and help hints dropped), for the one-line rule.
fn one_line(e: &clap::Error) -> String {
    let text = e.render().to_string();
    let mut parts = Vec::new();
    for line in text.lines() {
        let line = line.trim();
        if line.starts_with("Usage:") || line.starts_with("For more information") {
            break;
        }
        if !line.is_empty() {
            parts.push(line.trim_start_matches("error: "));
        }
    }
    parts.join(" ")
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) if !e.use_stderr() => e.exit(), // --help, --version
        // No command: the command list (on stderr, exit status 2).
        Err(e) if e.kind() == clap::error::ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
            e.exit()
        }
        Err(e) => {
            eprintln!("tactus: error: {} (see tactus --help)", one_line(&e));
            return ExitCode::from(2);
        }
    };
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // The causes, each once: a cause whose text the message already holds adds
            // nothing (many errors quote their source).
            let mut msg = String::new();
            for cause in e.chain() {
                let c = cause.to_string().replace('\n', " ");
                if !msg.contains(&c) {
                    if !msg.is_empty() {
                        msg.push_str(": ");
                    }
                    msg.push_str(&c);
                }
            }
            eprintln!("tactus: error: {msg}");
            ExitCode::FAILURE
        }
    }
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
        Cmd::Play(args) => play::run(&args),
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
                bail!("this tactus was built without audio input: rebuild with `--features audio` (needs libasound2-dev; see docs/install.md, \"Live setup\")")
            }
        }
        Cmd::Emulate {
            port,
            log,
            duration,
            until_idle,
            json_frames,
        } => play::emulate(&port, log.as_deref(), duration, until_idle, json_frames),
        Cmd::Devices { ble_scan_s } => {
            print!(
                "{}",
                tactus_transport::devices_report(std::time::Duration::from_secs_f64(
                    ble_scan_s.max(0.0)
                ))
            );
            #[cfg(feature = "audio")]
            print!("{}", tactus_audio::device::devices_report());
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
            if let Some(p) = &json {
                tactus_glove::atomic::check_location("--json", p)?;
            }
            let (text, j) = match (glove_log, pattern, truth, features) {
                (Some(log), Some(pattern), None, f) => {
                    let (text, j, warnings) =
                        tactus_eval::files::eval_glove_log(&log, &pattern, f.as_deref())?;
                    for w in warnings {
                        eprintln!("tactus: warning: {w}");
                    }
                    (text, j)
                }
                (None, None, Some(truth), Some(f)) => tactus_eval::files::eval_truth(&f, &truth)?,
                (None, None, Some(_), None) => bail!("eval --truth needs a FEATURES.json"),
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
        Cmd::Render(args) => render::run(args),
        Cmd::Help { command } => help(command.as_deref()),
    }
}
