//! `tactus play`, `tactus live` and `tactus emulate`: arguments in, a session from
//! `tactus-session` run, its report printed. The sessions themselves (the render → send
//! queue, the scheduler, the speakers, the live loop) live in `tactus-session`.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};

use tactus_batch::Command;
use tactus_engine::render::RenderRequest;
use tactus_glove::Pattern;
use tactus_session::view::{with_view, ViewExtra};
use tactus_session::{PlayOptions, PlayReport};
use tactus_transport::{lead_ms, open_sink, SinkOptions, SinkSpec, WallClock};

use crate::args::{EngineArgs, ModeArg};
use crate::stop_flag;

/// What the sink's "dropped" counter means, printed next to it.
const DROPPED: &str = "frames replaced by a newer one before the link could send them; \
                       each frame carries the whole glove state, so nothing is lost but time";

// The arguments of `tactus play` (its help text is the subcommand's, in main.rs).
#[derive(clap::Args)]
pub(crate) struct PlayArgs {
    /// A song, or a pattern file (.json) from `tactus render`.
    pub(crate) input: PathBuf,
    /// Where the frames go: serial:PATH[@BAUD] | ble[:NAME|ADDRESS] | file:LOG.jsonl | emulator[:LOG.jsonl] | null
    #[arg(long)]
    pub(crate) glove: String,
    /// Send frames this much earlier (positive) or later (negative), on top of the
    /// 50 ms pin rise and the link latency.
    #[arg(long, default_value_t = 0, allow_hyphen_values = true,
          value_parser = clap::value_parser!(i64).range(-60_000..=60_000))]
    pub(crate) offset_ms: i64,
    /// Play no sound and time frames on the wall clock. Without it, a build with the
    /// `audio` feature plays the song on the default output device and times frames on
    /// the audio clock.
    #[arg(long)]
    pub(crate) no_audio: bool,
    /// The song of a pattern file, when it is not at the pattern's recorded path; it
    /// must match the pattern's SHA-256.
    #[arg(long, value_name = "FILE", conflicts_with = "no_audio")]
    pub(crate) audio: Option<PathBuf>,
    /// Draw the glove in the terminal as it plays: five fingers, two cells of eight
    /// dots each, the link and the lead (stdout must be a terminal).
    #[arg(long)]
    pub(crate) tui: bool,
    /// A song: render it whole (offline) before playing, so every level range is the
    /// song's own from its first note, at the cost of a wait before the sound starts
    /// (about 1 % of the song's duration). Without it the song is rendered as it plays
    /// (streaming), and its first seconds are the least accurate.
    #[arg(long, conflicts_with = "audio")]
    pub(crate) whole: bool,
    #[command(flatten)]
    pub(crate) engine: EngineArgs,
}

/// `tactus play`: a pattern file as rendered, or a song rendered as it plays (or whole,
/// first, with `--whole`).
pub(crate) fn run(args: &PlayArgs) -> Result<()> {
    let PlayArgs {
        input,
        glove,
        offset_ms,
        no_audio,
        audio,
        tui,
        whole,
        engine,
    } = args;
    let (input, offset_ms, no_audio, audio, tui, whole) = (
        input.as_path(),
        *offset_ms,
        *no_audio,
        audio.as_deref(),
        *tui,
        *whole,
    );
    let spec: SinkSpec = glove.parse().with_context(|| format!("--glove {glove}"))?;
    let stop = stop_flag();
    let mut view = tui_out(tui);
    let is_pattern = input
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    let opts = PlayOptions {
        lead_ms: lead_ms(&spec, offset_ms),
        speakers: !no_audio,
        ..PlayOptions::default()
    };
    if is_pattern {
        return play_pattern(args, &spec, &opts, &stop, &mut view);
    }
    if audio.is_some() {
        bail!("--audio is for a pattern file's song; a song plays itself");
    }
    let mode = if whole {
        ModeArg::Offline
    } else {
        ModeArg::Streaming
    };
    let (config, stems) = engine.config(Command::Play, mode)?;
    let req = RenderRequest {
        input: input.to_path_buf(),
        stems,
        config,
    };
    let sink = open_sink(&spec, &SinkOptions::default())?;
    let (report, stats) = with_view(sink, "play", as_view(&mut view), |sink, feed| {
        feed.set(ViewExtra {
            latency: Some(lead(opts.lead_ms)),
            ..ViewExtra::default()
        });
        if whole {
            let mut rendered = |s: f64| eprintln!("tactus: rendered the whole song in {s:.2} s");
            tactus_session::play_song_whole(
                req,
                sink,
                &WallClock::new(),
                &opts,
                &stop,
                &mut rendered,
            )
        } else {
            tactus_session::play_song(req, sink, &WallClock::new(), &opts, &stop)
        }
    });
    print_play(&report?, &spec, &stats);
    Ok(())
}

/// `tactus play PATTERN.json`: the frames as rendered, with the song's sound when the build
/// has the `audio` feature.
fn play_pattern(
    args: &PlayArgs,
    spec: &SinkSpec,
    opts: &PlayOptions,
    stop: &Arc<AtomicBool>,
    view: &mut Option<std::io::Stdout>,
) -> Result<()> {
    let PlayArgs {
        input,
        no_audio,
        audio,
        tui,
        whole,
        engine,
        ..
    } = args;
    let (input, no_audio, audio, tui, whole) =
        (input.as_path(), *no_audio, audio.as_deref(), *tui, *whole);
    if whole {
        bail!(
            "{}: --whole is for a song; a pattern file is already rendered whole",
            input.display()
        );
    }
    let given = engine.given();
    if !given.is_empty() {
        bail!(
            "{}: a pattern file is played as rendered, so {} cannot apply: render it again \
             with them (tactus render SONG -o PATTERN.json ...), or play the song itself",
            input.display(),
            given.join(", ")
        );
    }
    let pattern = Pattern::from_path(input)?;
    let song = if !no_audio && cfg!(feature = "audio") {
        Some(tactus_session::pattern_song(input, &pattern, audio)?)
    } else {
        if !no_audio {
            eprintln!("tactus: note: built without the `audio` feature: no sound; timing frames on the wall clock");
        }
        if audio.is_some() {
            bail!("--audio needs a build with the `audio` feature");
        }
        None
    };
    let sink = open_sink(spec, &SinkOptions::default())?;
    let tty = std::io::stderr().is_terminal() && !tui;
    let lead = lead(opts.lead_ms);
    let drawing = view.is_some();
    let (played, stats) = with_view(sink, "play", as_view(view), |sink, feed| {
        feed.set(ViewExtra {
            latency: Some(lead.clone()),
            ..ViewExtra::default()
        });
        tactus_session::play_pattern(
            &pattern.frames,
            pattern.bin_ms,
            song.as_deref(),
            sink,
            &WallClock::new(),
            opts,
            stop,
            &mut |s| {
                if drawing {
                    feed.set(ViewExtra {
                        latency: Some(lead.clone()),
                        counters: format!(
                            "frame {}/{}  late {:+.1} ms",
                            s.frame_index + 1,
                            s.frames,
                            s.late_ms
                        ),
                        ..ViewExtra::default()
                    });
                }
                if tty {
                    eprint!(
                        "\r{:>7.1} s  frame {}/{}  late {:+.1} ms  link {}   ",
                        s.clock_ms / 1000.0,
                        s.frame_index + 1,
                        s.frames,
                        s.late_ms,
                        if s.link_up { "up" } else { "DOWN" }
                    );
                }
            },
        )
    });
    let report = played?;
    // Without the speakers the frames followed the wall clock: say how closely.
    let wall_clock = report.sound.is_none();
    if tty && wall_clock {
        eprintln!();
    }
    if wall_clock {
        let r = &report.timing;
        eprintln!(
            "tactus: played {} frames to {}: jitter p95 {:.2} ms, max {:.2} ms; sent {}, dropped {} ({DROPPED}), reconnects {}{}",
            r.frames_sent,
            spec,
            r.jitter_p95_ms,
            r.jitter_max_ms,
            stats.sent,
            stats.dropped,
            stats.reconnects,
            if r.stopped { " (stopped)" } else { "" }
        );
    } else {
        print_play(&report, spec, &stats);
    }
    Ok(())
}

/// `--tui`: the terminal to draw the glove view on, stdout when it is a terminal;
/// otherwise one line saying so, and the session runs without the view.
fn tui_out(tui: bool) -> Option<std::io::Stdout> {
    if !tui {
        return None;
    }
    if std::io::stdout().is_terminal() {
        Some(std::io::stdout())
    } else {
        eprintln!("tactus: --tui: stdout is not a terminal, so the glove view is not drawn");
        None
    }
}

fn as_view(out: &mut Option<std::io::Stdout>) -> Option<&mut (dyn std::io::Write + Send)> {
    out.as_mut().map(|o| o as &mut (dyn std::io::Write + Send))
}

/// The latency `play`'s view shows: the frames' lead.
fn lead(lead_ms: i64) -> (f64, String) {
    (lead_ms as f64, "frames sent early".to_string())
}

/// The lines `play` prints after a song or an audio-clocked pattern.
fn print_play(r: &PlayReport, spec: &SinkSpec, stats: &tactus_transport::SinkStats) {
    for w in &r.warnings {
        eprintln!("tactus: warning: {w}");
    }
    eprintln!(
        "tactus: streamed {} frames ({} not ready in time) to {spec}; sink sent {}, dropped {} ({DROPPED}), reconnects {}",
        r.timing.frames_sent, r.timing.skipped, stats.sent, stats.dropped, stats.reconnects
    );
    if let Some(s) = &r.sound {
        eprintln!("tactus: {s}");
    }
}

/// `tactus live`: capture → engine → glove, until Ctrl-C or `seconds` of captured audio.
#[cfg(feature = "audio")]
pub fn live(
    input: Option<&str>,
    glove: &str,
    seconds: Option<f64>,
    tui: bool,
    engine: &EngineArgs,
) -> Result<()> {
    use tactus_session::{device::LiveDevice, LiveOptions};
    let spec: SinkSpec = glove.parse().with_context(|| format!("--glove {glove}"))?;
    let (config, stems) = engine.config(Command::Live, ModeArg::Streaming)?;
    if !stems.is_empty() {
        bail!("--stem cannot be used with live: there is only the captured mix");
    }
    let (bin_ms, profile) = (config.bin_ms, config.profile);
    let stop = stop_flag();
    let mut dev = LiveDevice::open(input, config)?;
    let rate = dev.rate();
    let sink = open_sink(&spec, &SinkOptions::default())?;
    eprintln!(
        "tactus: live from {} ({rate} Hz, {} ch) to {spec}, {bin_ms} ms bins{}",
        dev.name(),
        dev.channels(),
        if seconds.is_some() {
            ""
        } else {
            "; Ctrl-C stops"
        }
    );
    let opts = LiveOptions {
        seconds,
        lead_ms: lead_ms(&spec, 0),
        // Fallen behind by more than this, drop audio to catch up.
        max_backlog: Some(tactus_session::MAX_BACKLOG),
        ..LiveOptions::default()
    };
    let mut view = tui_out(tui);
    let drawing = view.is_some();
    let (result, stats) = with_view(sink, "live", as_view(&mut view), |sink, feed| {
        dev.run(sink, &opts, &stop, &mut |s| {
            if !drawing {
                return;
            }
            feed.set(ViewExtra {
                level_dbfs: Some(20.0 * s.peak.max(1e-6).log10()),
                latency: s.latency_ms.map(|l| (l, "bin end -> sent".to_string())),
                counters: format!(
                    "frames {}  dropped {}  overruns {}  xruns {}  backlog {:.0} ms  caught up {:.1} s",
                    s.frames,
                    sink.stats().dropped,
                    s.overruns,
                    s.xruns,
                    s.backlog_ms,
                    s.caught_up_s
                ),
            });
        })
    });
    let r = result?;
    // The capture device's own buffering on its own line, then one budget per
    // finger group (stages in samples at the engine rate and in ms).
    let period = dev.period_frames();
    eprintln!(
        "tactus: capture: {} at {rate} Hz, period {period} frames ({:.1} ms), input delay {:.1} ms reported by the device; threads {}",
        dev.name(),
        period as f64 * 1e3 / f64::from(rate),
        r.input_delay_ms,
        match dev.realtime() {
            Ok(()) => "real-time".to_string(),
            Err(e) => format!("at normal priority (real-time refused: {e})"),
        }
    );
    for line in r.budget_text(profile.name()).lines() {
        eprintln!(
            "{}{line}",
            if line.starts_with(' ') {
                ""
            } else {
                "tactus: "
            }
        );
    }
    for line in r.timing_text(rate).lines() {
        eprintln!("tactus: {line}");
    }
    eprintln!(
        "tactus: captured {:.3} s ({} callbacks, overruns {} samples; capture clock {:+.1} ms vs wall since the first callback), {} frames to {spec}; sink sent {}, dropped {} ({DROPPED}), reconnects {}",
        r.captured_s,
        r.callbacks,
        r.overruns,
        r.capture_drift_ms,
        r.frames,
        stats.sent,
        stats.dropped,
        stats.reconnects
    );
    Ok(())
}

pub fn emulate(
    port: &Path,
    log: Option<&Path>,
    duration: Option<f64>,
    until_idle: bool,
    json_frames: bool,
) -> Result<()> {
    let stop = stop_flag();
    let opts = tactus_transport::emulator::EmulatorOptions {
        max_duration: duration.map(|d| Duration::from_secs_f64(d.max(0.0))),
        idle_stop: until_idle.then_some(Duration::from_secs(2)),
        ..Default::default()
    };
    let tty = std::io::stderr().is_terminal();
    let t0 = Instant::now();
    let mut last_line = Instant::now();
    let r = tactus_transport::emulator::run_emulator_on_port_with(
        port,
        log,
        &stop,
        &opts,
        &mut |c, open| {
            let line = format!(
                "{:>7.1} s  packets {}  crc errors {}  sequence gaps {}  actuations {}  port {}",
                t0.elapsed().as_secs_f64(),
                c.packets,
                c.crc_errors,
                c.sequence_gaps,
                c.actuations,
                if open { "open" } else { "GONE" }
            );
            if tty {
                eprint!("\r{line}   ");
            } else if last_line.elapsed() >= Duration::from_secs(10) {
                // Not a terminal (a log file): one line every 10 s.
                last_line = Instant::now();
                eprintln!("tactus: emulate: {line}");
            }
        },
    )?;
    if tty {
        eprintln!();
    }
    eprintln!("tactus: emulated glove: {r}");
    let report = r.to_json(json_frames);
    println!("{report}");
    Ok(())
}
