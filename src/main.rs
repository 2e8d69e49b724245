//! `tactus`: turns music into touch. See README.md for the tour.
#![forbid(unsafe_code)]
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::{anyhow, bail, Context, Result};
use clap::{Parser, Subcommand, ValueEnum};

use tactus_batch::{Command, RenderOptions};
use tactus_engine::render::{render, RenderRequest};
use tactus_glove::export::ExportFormat;
use tactus_glove::png::{plot_bytes, PlotFormat};
use tactus_glove::{write_atomic, OutputSet};

mod batch;
mod play;

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

#[derive(Clone, Copy, Debug, ValueEnum)]
enum DrumsArg {
    /// Per-instrument transcriber embedded in Tactus (default).
    Classes,
    /// The same with its low-latency model (21.6 ms instead of 61.6 ms), for live input.
    ClassesLive,
    /// The paper's four Butterworth bands with spectral-flux onsets.
    Bands,
    /// ADTLib's networks through ONNX (kick, snare, hi-hat; needs --drum-model).
    Adtlib,
}

#[derive(Clone, Copy, ValueEnum)]
enum PitchArg {
    /// The learned salience on the spectral separator's stems (models/bassnet/README.md): for
    /// the bass times the harmonic sum; for the lead (vocals) the harmonic sum decides
    /// whether and the learned lead model which pitch. The harmonic sum for other basses and
    /// leads, pYIN for the rest.
    Auto,
    /// The default before the learned salience: the harmonic sum for every bass and the
    /// lead, pYIN for the rest.
    AutoShs,
    Yin,
    Pyin,
    /// Harmonic-sum salience + Viterbi (made for a bass line or a lead in a mix) on every stem.
    Shs,
}

/// Latency profile (issue 13; `tactus_engine::profile`).
#[derive(Clone, Copy, ValueEnum)]
enum ProfileArg {
    /// Quality first: every stage as documented (render and play).
    Full,
    /// Milliseconds first: drums on the mix, short frames, no look-ahead, 10 ms bins with
    /// 50 ms pin pulses (the default for live).
    Live,
}

#[derive(Clone, Copy, ValueEnum)]
enum NoteOnsetsArg {
    Attack,
    Legato,
    Pitch,
}

#[derive(Clone, Copy, ValueEnum)]
enum KitMaskArg {
    On,
    Off,
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
    /// Bin length in milliseconds (default: 100 for render, as in the paper; 25 for play;
    /// 10 with the live profile).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    bin_ms: Option<u32>,
    /// Pitch levels per melodic stem (1..=8: a level raises one of a cell's 8 dots).
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u8).range(1..=8))]
    levels: u8,
    /// Glove map (TOML); the default is the paper's map.
    #[arg(long)]
    map: Option<PathBuf>,
    /// Pitch tracker.
    /// [default: auto (the live profile: YIN on short frames); pyin for live --profile full]
    #[arg(long, value_enum)]
    pitch: Option<PitchArg>,
    /// Drum transcription: classes (embedded per-instrument transcriber; the default for
    /// render and play), classes-live (the same with its 21.6 ms model; the default for live), bands (the paper's band-pass) or adtlib
    /// (ONNX, --drum-model models/adtlib.onnx).
    #[arg(long, value_enum)]
    drums: Option<DrumsArg>,
    /// Drum model file: for --drums adtlib the ONNX file of models/setup_adtlib.sh; for
    /// classes or classes-live a Tactus drum model (models/drums/train.py, train_cnn.py)
    /// in place of the embedded one.
    #[arg(long)]
    drum_model: Option<PathBuf>,
    /// How pitch becomes levels: follow (floored Tukey IQR, a streaming range prior) or the
    /// paper's rule.
    #[arg(long, value_enum, default_value = "follow")]
    levels_rule: LevelRuleArg,
    /// Note onsets of bass, vocals and other: attack (the pitch track and the stem's level:
    /// re-attacks of a held note, onsets at the attack; on a mix the bass changes note only
    /// with an attack), legato (the same, without that bass rule: legato bass lines) or
    /// pitch (the pitch track alone).
    #[arg(long, value_enum, default_value = "attack")]
    note_onsets: NoteOnsetsArg,
    /// The spectral separator's learned kit mask: on (kick and tom bodies leave the bass
    /// stem for the drums) or off (the median filter alone, as before 2026-11-24).
    #[arg(long, value_enum, default_value = "on")]
    kit_mask: KitMaskArg,
    /// Latency profile: full (quality first) or live (under 40 ms to the rhythm pins;
    /// 10 ms bins). [default: live for live, full for render and play]
    #[arg(long, value_enum)]
    profile: Option<ProfileArg>,
}

impl EngineArgs {
    /// The engine options given with other than their default values.
    fn given(&self) -> Vec<&'static str> {
        let mut v = Vec::new();
        let mut add = |on: bool, name| {
            if on {
                v.push(name);
            }
        };
        add(!matches!(self.separator, SepArg::Spectral), "--separator");
        add(self.model.is_some(), "--model");
        add(self.threads.is_some(), "--threads");
        add(!self.stems.is_empty(), "--stem");
        add(self.bin_ms.is_some(), "--bin-ms");
        add(self.levels != 8, "--levels");
        add(self.map.is_some(), "--map");
        add(self.pitch.is_some(), "--pitch");
        add(
            !matches!(self.levels_rule, LevelRuleArg::Follow),
            "--levels-rule",
        );
        add(
            !matches!(self.note_onsets, NoteOnsetsArg::Attack),
            "--note-onsets",
        );
        add(!matches!(self.kit_mask, KitMaskArg::On), "--kit-mask");
        add(self.drums.is_some(), "--drums");
        add(self.drum_model.is_some(), "--drum-model");
        add(self.profile.is_some(), "--profile");
        v
    }

    /// The engine configuration for `command` and the supplied stems: the options by
    /// their CLI names, turned into a configuration by `tactus_batch` as for a library.
    fn config(
        &self,
        command: Command,
        mode: ModeArg,
    ) -> Result<(
        tactus_engine::EngineConfig,
        Vec<(tactus_dsp::Stem, PathBuf)>,
    )> {
        let mut opts = self.options(mode);
        for s in &self.stems {
            let (name, path) = s
                .split_once('=')
                .ok_or_else(|| anyhow!("--stem {s:?}: expected NAME=PATH"))?;
            opts.stems.push((name.to_string(), path.into()));
        }
        Ok(opts.config_for(command, true)?)
    }

    /// The options by their CLI names (stems left out).
    fn options(&self, mode: ModeArg) -> RenderOptions {
        fn name<T: ValueEnum>(v: &T) -> Option<String> {
            v.to_possible_value().map(|p| p.get_name().to_string())
        }
        RenderOptions {
            separator: name(&self.separator),
            model: self.model.clone(),
            bin_ms: self.bin_ms,
            levels: Some(self.levels),
            map: self.map.as_ref().map(|p| p.display().to_string()),
            pitch: self.pitch.as_ref().and_then(name),
            drums: self.drums.as_ref().and_then(name),
            drum_model: self.drum_model.clone(),
            levels_rule: name(&self.levels_rule),
            note_onsets: name(&self.note_onsets),
            kit_mask: name(&self.kit_mask),
            mode: name(&mode),
            stems: Vec::new(),
            threads: self.threads,
            profile: self.profile.as_ref().and_then(name),
        }
    }
}

#[derive(Subcommand)]
enum Cmd {
    /// Render a song to a glove pattern (and optionally features and a plot).
    Render {
        /// The song: WAV, FLAC, MP3, OGG/Vorbis, AAC/M4A. With --out-dir, any number of
        /// songs, directories (searched recursively for audio files) and quoted globs.
        #[arg(required = true, num_args = 1..)]
        inputs: Vec<PathBuf>,
        #[command(flatten)]
        batch: batch::BatchArgs,
        /// Pattern file to write ("-" for stdout).
        #[arg(short = 'o', long = "output")]
        output: Option<PathBuf>,
        /// Features file to write (JSON).
        #[arg(long)]
        features: Option<PathBuf>,
        /// Plot to write (.svg, or .png rasterised with the system's fonts).
        #[arg(long)]
        plot: Option<PathBuf>,
        /// Browser preview to write: one self-contained page that plays the song (embedded)
        /// and animates the glove in sync with it.
        #[arg(long, value_name = "PAGE.html")]
        html: Option<PathBuf>,
        /// Export for other tools, by extension (repeatable): .csv (one row per bin, one 0/1
        /// column per dot) or .ahap (Apple Core Haptics: drums as transients, bass as
        /// continuous sharpness).
        #[arg(long, value_name = "FILE.csv|FILE.ahap")]
        export: Vec<PathBuf>,
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
        #[arg(long, default_value_t = 0, allow_hyphen_values = true,
              value_parser = clap::value_parser!(i64).range(-60_000..=60_000))]
        offset_ms: i64,
        /// Play no sound and time frames on the wall clock. Without it, a build with the
        /// `audio` feature plays the song on the default output device and times frames on
        /// the audio clock.
        #[arg(long)]
        no_audio: bool,
        /// The song of a pattern file, when it is not at the pattern's recorded path; it
        /// must match the pattern's SHA-256.
        #[arg(long, value_name = "FILE", conflicts_with = "no_audio")]
        audio: Option<PathBuf>,
        /// Draw the glove in the terminal as it plays: five fingers, two cells of eight
        /// dots each, the link and the lead (stdout must be a terminal).
        #[arg(long)]
        tui: bool,
        /// A song: render it whole (offline) before playing, so every level range is the
        /// song's own from its first note, at the cost of a wait before the sound starts
        /// (about 1 % of the song's duration). Without it the song is rendered as it plays
        /// (streaming), and its first seconds are the least accurate.
        #[arg(long, conflicts_with = "audio")]
        whole: bool,
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

/// The `--html` page, with a note of its size and a warning when browsers may not play
/// the song.
fn html_page(input: &Path, out: &tactus_engine::render::RenderOutput) -> Result<Vec<u8>> {
    let page = tactus_glove::html::page_for_song(input, &out.pattern, &out.features)?;
    if let Some(why) = &page.audio.unplayable {
        eprintln!("tactus: warning: --html: browsers may not play this audio ({why}); the page's glove runs on the wall clock");
    }
    eprintln!(
        "tactus: --html: page {:.1} MB, of which audio {:.1} MB ({}, the source file as base64)",
        page.html.len() as f64 / 1e6,
        page.audio_bytes as f64 * 4.0 / 3.0 / 1e6,
        page.audio.name
    );
    Ok(page.html.into_bytes())
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
            audio,
            tui,
            whole,
            engine,
        } => play::run(
            &input,
            &glove,
            offset_ms,
            no_audio,
            audio.as_deref(),
            tui,
            whole,
            &engine,
        ),
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
        Cmd::Render {
            inputs,
            batch,
            output,
            features,
            plot,
            html,
            export,
            engine,
            mode,
            verbose,
        } => {
            if let Some(dir) = &batch.out_dir {
                let single = [
                    ("-o", output.is_some()),
                    ("--features", features.is_some()),
                    ("--plot", plot.is_some()),
                    ("--html", html.is_some()),
                    ("--export", !export.is_empty()),
                    ("--stem", !engine.stems.is_empty()),
                ];
                if let Some((flag, _)) = single.iter().find(|(_, on)| *on) {
                    bail!(
                        "{flag} names one song's output and does not go with --out-dir \
                         (use --with-features or --with-plot svg|png for a library)"
                    );
                }
                return batch::run(&inputs, dir, &batch, &engine, mode, verbose);
            }
            if let Some(flag) = batch.given() {
                bail!("{flag} needs --out-dir DIR");
            }
            let [input] = &inputs[..] else {
                bail!(
                    "{} inputs: rendering several songs needs --out-dir DIR",
                    inputs.len()
                );
            };
            if input.is_dir() {
                bail!(
                    "{} is a directory: add --out-dir DIR to render the songs in it",
                    input.display()
                );
            }
            let input = input.clone();
            let (config, stems) = engine.config(Command::Render, mode)?;
            let export_kinds = export
                .iter()
                .map(|p| {
                    ExportFormat::of(p).ok_or_else(|| {
                        anyhow!(
                            "--export {}: unknown format (use a .csv or .ahap file name)",
                            p.display()
                        )
                    })
                })
                .collect::<Result<Vec<_>>>()?;
            // Outputs are one transaction: checked and their temporary files created now,
            // renamed over their targets only when every one is complete.
            let outputs: Vec<(&str, &Path)> = [
                ("-o", output.as_deref()),
                ("--features", features.as_deref()),
                ("--plot", plot.as_deref()),
                ("--html", html.as_deref()),
            ]
            .into_iter()
            .chain(export.iter().map(|p| ("--export", Some(p.as_path()))))
            .filter_map(|(label, p)| p.map(|p| (label, p)))
            .collect();
            let mut inputs: Vec<&Path> = vec![input.as_path()];
            inputs.extend(stems.iter().map(|(_, p)| p.as_path()));
            inputs.extend(engine.model.as_deref());
            inputs.extend(engine.map.as_deref());
            let mut out_set = OutputSet::prepare(&outputs, &inputs)?;
            let plot_format = match plot.as_deref() {
                Some(p) => Some(PlotFormat::of(p).ok_or_else(|| {
                    anyhow!("--plot {}: the plot must end in .svg or .png", p.display())
                })?),
                None => None,
            };
            // Ctrl-C: remove the temporary files and leave every existing file as it was.
            let _ = ctrlc::set_handler(|| {
                tactus_glove::atomic::remove_pending_temporaries();
                eprintln!("tactus: interrupted: no output written");
                std::process::exit(130);
            });
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
            let mut plot_bytes = match (&plot, plot_format) {
                (Some(p), Some(format)) => {
                    let png = plot_bytes(&out.pattern, &out.features, format)
                        .with_context(|| format!("--plot {}", p.display()))?;
                    if !png.fonts {
                        eprintln!(
                            "tactus: warning: --plot {}: no system font found, so the PNG \
                             has no text (install e.g. fonts-dejavu-core, or use .svg)",
                            p.display()
                        );
                    }
                    Some(png.bytes)
                }
                _ => None,
            };
            let mut html_bytes = match &html {
                Some(p) => Some(
                    html_page(&input, &out).with_context(|| format!("--html {}", p.display()))?,
                ),
                None => None,
            };
            let mut export_bytes = export_kinds
                .iter()
                .map(|k| k.bytes(&out.pattern, &out.features));
            let mut stdout_bytes = None;
            for (i, &(label, p)) in outputs.iter().enumerate() {
                let bytes = match label {
                    "-o" => out.pattern.to_json_string()?.into_bytes(),
                    "--features" => out.features.to_json_string()?.into_bytes(),
                    "--html" => html_bytes.take().unwrap_or_default(),
                    "--export" => export_bytes.next().unwrap_or_default(),
                    _ => plot_bytes.take().unwrap_or_default(),
                };
                if p == Path::new("-") {
                    stdout_bytes = Some(bytes);
                } else {
                    out_set.write(i, &bytes)?;
                }
            }
            out_set.commit()?;
            if let Some(bytes) = stdout_bytes {
                write_atomic(Path::new("-"), |w| w.write_all(&bytes))
                    .context("writing the pattern to standard output")?;
            }
            if outputs.is_empty() {
                eprintln!(
                    "tactus: rendered {} ({:.1} s, {} frames of {} ms) and wrote nothing: add \
                     -o PATTERN.json (or -o - for standard output), --features FEAT.json or \
                     --plot OUT.svg to keep the result",
                    input.display(),
                    out.duration_s,
                    out.pattern.frames.len(),
                    out.pattern.bin_ms
                );
            }
            if verbose {
                eprint!("{}", out.report_text());
            }
            Ok(())
        }
    }
}
