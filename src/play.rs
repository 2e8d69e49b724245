//! `tactus play`, `tactus live` and `tactus emulate`: the path from the engine to the glove's
//! pins.
//!
//! ## play
//! A song is rendered by the streaming engine on its own thread, frame by frame; the main
//! thread sends frame `k` when the play clock reads `k · bin_ms − lead`, where the lead is
//! the 50 ms pin rise plus the link's latency plus `--offset-ms`. The play clock is the
//! audio output ([`crate::audio::Playback::now_ms`], the song time audible now) when the
//! `audio` feature is built and an output device opens, otherwise the wall clock started when
//! the first frame exists. Rendering runs far faster than real time, but only
//! [`RENDER_AHEAD_MS`] (2 s, so N = 80 frames at 25 ms bins) ahead of the clock: the frames
//! wait in a bounded queue and the renderer blocks when it holds N. A frame that is not ready
//! in time is skipped (the next frame carries the full state anyway). Every exit (end,
//! Ctrl-C, error) sends "all pins down".
//!
//! A pattern file plays its own song: the file at `--audio` or at the pattern's recorded
//! path (as given, then beside the pattern), refused unless its SHA-256 is the pattern's.
//! Its frames are the queue, sent on the audio clock exactly as a song's; `--no-audio` (or
//! a build without the `audio` feature) keeps the wall clock and needs no song. Engine
//! options with a pattern file are an error, not ignored.
//!
//! ## live (feature `audio`)
//! [`crate::audio::Capture`] hands mono samples through a lock-free ring to this thread,
//! which resamples them to 44.1 kHz ([`StreamResampler`]), feeds the streaming engine in
//! whatever blocks arrive, and sends each frame as soon as it is final. Latency: the device
//! period, the resampler (`StreamResampler::latency_samples`), the engine's look-ahead and
//! the bin, then the link and the 50 ms pin rise; the budget is printed at the end together
//! with the measured delay from the end of a bin's audio (as captured) to its frame's send.

use std::collections::VecDeque;
use std::io::IsTerminal;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};

/// What the sink's "dropped" counter means, printed next to it.
const DROPPED: &str = "frames replaced by a newer one before the link could send them; \
                       each frame carries the whole glove state, so nothing is lost but time";
use tactus_engine::render::{render_with, RenderRequest};
use tactus_engine::Mode;
use tactus_glove::{Frame, Pattern};
use tactus_transport::{lead_ms, open_sink, play_frames, SinkOptions, SinkSpec, WallClock};

use crate::{engine_config, stop_flag, EngineArgs};

/// How far, in ms of song time, the renderer may run ahead of the play clock: it blocks
/// when `RENDER_AHEAD_MS / bin_ms` frames (80 at 25 ms) wait to be sent.
pub const RENDER_AHEAD_MS: u32 = 2000;

/// Frames between the rendering thread and the sender: a bounded queue.
#[derive(Default)]
struct Shared {
    /// Frames `base ..` not yet sent.
    frames: VecDeque<Frame>,
    /// Index of `frames[0]`.
    base: usize,
    done: bool,
    error: Option<String>,
}

type SharedQueue = Arc<(Mutex<Shared>, Condvar)>;

/// The play clock: song time in ms (negative before the song starts), `None` until known.
type SongClock<'a> = &'a dyn Fn() -> Option<f64>;

pub fn run(
    input: &Path,
    glove: &str,
    offset_ms: i64,
    no_audio: bool,
    audio: Option<&Path>,
    engine: &EngineArgs,
) -> Result<()> {
    let spec: SinkSpec = glove.parse().with_context(|| format!("--glove {glove}"))?;
    let stop = stop_flag();
    let is_pattern = input
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    let lead = lead_ms(&spec, offset_ms);
    if is_pattern {
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
        if !no_audio && cfg!(feature = "audio") {
            let song = pattern_song(input, &pattern, audio)?;
            let output = open_output(&song, lead.max(0) as u32, false, &stop);
            let sink = open_sink(&spec, &SinkOptions::default())?;
            // The whole pattern is the queue: nothing to render.
            let shared: SharedQueue = Arc::new((
                Mutex::new(Shared {
                    frames: pattern.frames.iter().copied().collect(),
                    base: 0,
                    done: true,
                    error: None,
                }),
                Condvar::new(),
            ));
            return send_and_report(&shared, output, sink, &spec, pattern.bin_ms, lead, &stop);
        }
        if !no_audio {
            eprintln!("tactus: note: built without the `audio` feature: no sound; timing frames on the wall clock");
        }
        if audio.is_some() {
            anyhow::bail!("--audio needs a build with the `audio` feature");
        }
        let sink = open_sink(&spec, &SinkOptions::default())?;
        let tty = std::io::stderr().is_terminal();
        let report = play_frames(
            &pattern.frames,
            pattern.bin_ms,
            &sink,
            &WallClock::new(),
            lead,
            &stop,
            &mut |s| {
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
        );
        if tty {
            eprintln!();
        }
        let stats = sink.close();
        eprintln!(
            "tactus: played {} frames to {}: jitter p95 {:.2} ms, max {:.2} ms; sent {}, dropped {} ({DROPPED}), reconnects {}{}",
            report.frames_sent,
            spec,
            report.jitter_p95_ms,
            report.jitter_max_ms,
            stats.sent,
            stats.dropped,
            stats.reconnects,
            if report.stopped { " (stopped)" } else { "" }
        );
        return Ok(());
    }
    if audio.is_some() {
        anyhow::bail!("--audio is for a pattern file's song; a song plays itself");
    }

    let (config, stems) = engine_config(engine, Mode::Streaming, 25, false)?;
    let bin_ms = config.bin_ms;
    let ahead = (RENDER_AHEAD_MS.div_ceil(bin_ms) as usize).max(8);
    let req = RenderRequest {
        input: input.to_path_buf(),
        stems,
        config,
    };
    let output = open_output(input, lead.max(0) as u32, no_audio, &stop);
    let sink = open_sink(&spec, &SinkOptions::default())?;
    let shared: SharedQueue = Arc::new((Mutex::new(Shared::default()), Condvar::new()));
    let producer = {
        let shared = shared.clone();
        let stop = stop.clone();
        std::thread::spawn(move || {
            let (m, cv) = &*shared;
            // Returning `false` (stopped, or a poisoned lock) ends the render at once.
            let result = render_with(&req, &mut |_| {}, &mut |k, f| {
                let Ok(mut g) = m.lock() else { return false };
                // The bounded buffer: wait while `ahead` frames are queued.
                while g.frames.len() >= ahead && !stop.load(Ordering::Relaxed) {
                    g = match cv.wait_timeout(g, Duration::from_millis(50)) {
                        Ok(r) => r.0,
                        Err(_) => return false,
                    };
                }
                if stop.load(Ordering::Relaxed) {
                    return false;
                }
                if k < g.base + g.frames.len() {
                    return true;
                }
                if g.frames.is_empty() {
                    g.base = k;
                }
                g.frames.push_back(f);
                cv.notify_all();
                true
            });
            // A stop is not an error to report.
            let result = match result {
                Err(tactus_engine::EngineError::Cancelled) => Ok(()),
                other => other.map(|_| ()),
            };
            if let Ok(mut g) = m.lock() {
                g.done = true;
                if let Err(e) = result {
                    g.error = Some(e.to_string());
                }
                cv.notify_all();
            }
        })
    };
    if let Err(e) = wait_first_frame(&shared, &stop) {
        stop.store(true, Ordering::SeqCst);
        sink.close();
        let _ = producer.join();
        return Err(e);
    }
    let result = send_and_report(&shared, output, sink, &spec, bin_ms, lead, &stop);
    let _ = producer.join();
    result
}

/// Sends the queued frames on the audio clock (or the wall clock when `output` is `None`),
/// then closes the sink and prints the report. Sets `stop` when done, which ends a producer.
fn send_and_report(
    shared: &SharedQueue,
    output: Option<Output>,
    sink: tactus_transport::SinkHandle,
    spec: &SinkSpec,
    bin_ms: u32,
    lead: i64,
    stop: &Arc<AtomicBool>,
) -> Result<()> {
    let outcome = match &output {
        #[cfg(feature = "audio")]
        Some(out) => out.start().and_then(|()| {
            let clock = || out.now_ms();
            send_clocked(shared, &sink, bin_ms, lead, stop, &clock)
        }),
        _ => {
            let t0 = Instant::now();
            let clock = || Some(t0.elapsed().as_secs_f64() * 1e3 - lead as f64);
            send_clocked(shared, &sink, bin_ms, lead, stop, &clock)
        }
    };
    #[cfg(feature = "audio")]
    let audio_line = output.as_ref().map(|out| finish_audio(out, stop));
    #[cfg(not(feature = "audio"))]
    let audio_line: Option<String> = None;
    stop.store(true, Ordering::SeqCst);
    let stats = sink.close();
    let (sent, skipped) = outcome?;
    eprintln!(
        "tactus: streamed {sent} frames ({skipped} not ready in time) to {spec}; sink sent {}, dropped {} ({DROPPED}), reconnects {}",
        stats.sent, stats.dropped, stats.reconnects
    );
    if let Some(line) = audio_line {
        eprintln!("{line}");
    }
    Ok(())
}

/// The song of a pattern: `--audio FILE`, else the recorded path (as given, then relative
/// to the pattern file's folder); its SHA-256 must be the pattern's.
fn pattern_song(
    pattern_path: &Path,
    pattern: &Pattern,
    audio: Option<&Path>,
) -> Result<std::path::PathBuf> {
    let recorded = Path::new(&pattern.source.path);
    let song = match audio {
        Some(a) => a.to_path_buf(),
        None => {
            let beside = pattern_path
                .parent()
                .map(|d| d.join(recorded))
                .filter(|_| recorded.is_relative());
            match std::iter::once(recorded.to_path_buf())
                .chain(beside)
                .find(|p| p.is_file())
            {
                Some(p) => p,
                None => anyhow::bail!(
                    "the pattern's song {} was not found (nor beside the pattern): pass --audio FILE, or --no-audio to play without sound",
                    recorded.display()
                ),
            }
        }
    };
    let sha =
        tactus_glove::sha256_file(&song).with_context(|| format!("reading {}", song.display()))?;
    if sha != pattern.source.sha256 {
        anyhow::bail!(
            "{}: SHA-256 {sha} does not match the pattern's {} (a different file?): pass the song it was rendered from with --audio FILE, or --no-audio",
            song.display(),
            pattern.source.sha256
        );
    }
    Ok(song)
}

#[cfg(feature = "audio")]
type Output = crate::audio::Playback;
#[cfg(not(feature = "audio"))]
type Output = ();

/// Opens the audio output for a song, or says (one line) why frames follow the wall clock.
fn open_output(
    input: &Path,
    pad_ms: u32,
    no_audio: bool,
    stop: &Arc<AtomicBool>,
) -> Option<Output> {
    if no_audio {
        return None;
    }
    #[cfg(feature = "audio")]
    {
        match crate::audio::Playback::open(input, pad_ms, stop.clone()) {
            Ok(p) => Some(p),
            Err(e) => {
                let msg = format!("{e:#}").replace('\n', " ");
                eprintln!(
                    "tactus: warning: no audio output ({msg}); timing frames on the wall clock"
                );
                None
            }
        }
    }
    #[cfg(not(feature = "audio"))]
    {
        let _ = (input, pad_ms, stop);
        eprintln!("tactus: warning: built without the `audio` feature: no sound; timing frames on the wall clock (--no-audio)");
        None
    }
}

/// Lets the song play out, then describes the audio clock against the wall clock.
#[cfg(feature = "audio")]
fn finish_audio(out: &crate::audio::Playback, stop: &AtomicBool) -> String {
    // The song is over when its last frame is audible; give up 5 s after it should be.
    let t = Instant::now();
    while !stop.load(Ordering::Relaxed) && !out.finished() {
        let remaining = match (out.duration_ms(), out.now_ms()) {
            (Some(d), Some(now)) => d - now,
            _ => 10_000.0,
        };
        if t.elapsed() > Duration::from_secs_f64(remaining.max(0.0) / 1e3 + 5.0) {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let st = out.stats();
    let song_s = out.duration_ms().unwrap_or(0.0) / 1e3;
    let clock_s = out.now_ms().unwrap_or(0.0) / 1e3;
    // Wall time from the first sample being audible (first callback + output latency) to now.
    let wall_s = st
        .first_callback
        .map(|f| f.elapsed().as_secs_f64() - st.latency_ms / 1e3)
        .unwrap_or(0.0);
    format!(
        "tactus: audio on {} at {} Hz: song {song_s:.3} s, audio clock {clock_s:.3} s after {wall_s:.3} s of wall time (drift {:+.1} ms), output latency {:.1} ms, underruns {}{}",
        out.device(),
        out.rate(),
        (clock_s - wall_s) * 1e3,
        st.latency_ms,
        st.underruns,
        if out.feed_failed() { ", decoding failed part-way" } else { "" }
    )
}

/// Waits until the renderer has produced its first frame (or failed, or ended).
fn wait_first_frame(shared: &SharedQueue, stop: &AtomicBool) -> Result<()> {
    let (m, cv) = &**shared;
    let mut g = m.lock().map_err(|_| anyhow::anyhow!("renderer crashed"))?;
    while g.frames.is_empty() && !g.done && !stop.load(Ordering::Relaxed) {
        g = cv
            .wait_timeout(g, Duration::from_millis(50))
            .map_err(|_| anyhow::anyhow!("renderer crashed"))?
            .0;
    }
    if let Some(e) = &g.error {
        anyhow::bail!("{e}");
    }
    Ok(())
}

/// Sends frame `k` when `clock` reads `k · bin_ms − lead_ms`. Returns (sent, skipped).
fn send_clocked(
    shared: &SharedQueue,
    sink: &tactus_transport::SinkHandle,
    bin_ms: u32,
    lead_ms: i64,
    stop: &AtomicBool,
    clock: SongClock<'_>,
) -> Result<(usize, usize)> {
    let (m, cv) = &**shared;
    let (mut k, mut sent, mut skipped) = (0usize, 0usize, 0usize);
    // A clock that stops moving for this long (a stalled audio device) ends playback.
    let stall = Duration::from_secs(10);
    let (mut last, mut moved) = (None, Instant::now());
    'frames: while !stop.load(Ordering::Relaxed) {
        let due = k as f64 * f64::from(bin_ms) - lead_ms as f64;
        loop {
            if stop.load(Ordering::Relaxed) {
                break 'frames;
            }
            let now = clock();
            if now != last {
                (last, moved) = (now, Instant::now());
            } else if moved.elapsed() > stall {
                sink.all_down();
                anyhow::bail!("the play clock stopped for {} s (audio output stalled?); rerun with --no-audio", stall.as_secs());
            }
            match now {
                Some(t) if t >= due => break,
                Some(t) => std::thread::sleep(Duration::from_secs_f64((due - t).min(10.0) / 1e3)),
                None => std::thread::sleep(Duration::from_millis(2)),
            }
        }
        let mut g = m.lock().map_err(|_| anyhow::anyhow!("renderer crashed"))?;
        if let Some(e) = &g.error {
            anyhow::bail!("{e}");
        }
        // Frames that came too late for their turn.
        while g.base < k && !g.frames.is_empty() {
            g.frames.pop_front();
            g.base += 1;
        }
        if g.base == k && !g.frames.is_empty() {
            let f = g.frames.pop_front().expect("checked non-empty");
            g.base += 1;
            cv.notify_all();
            drop(g);
            sink.send_frame(f, (k as u64 * u64::from(bin_ms)) as u32);
            sent += 1;
        } else if g.done {
            break;
        } else {
            skipped += 1;
        }
        k += 1;
    }
    sink.all_down();
    Ok((sent, skipped))
}

/// Capture period the live profile asks for (issue 13): 256 frames, 5.8 ms at 44.1 kHz.
#[cfg(feature = "audio")]
const LIVE_PERIOD_FRAMES: u32 = 256;

/// `tactus live`: capture → engine → glove, until Ctrl-C or `seconds` of captured audio.
#[cfg(feature = "audio")]
pub fn live(
    input: Option<&str>,
    glove: &str,
    seconds: Option<f64>,
    tui: bool,
    engine: &EngineArgs,
) -> Result<()> {
    use tactus_engine::resample::StreamResampler;
    use tactus_engine::{Engine, ENGINE_RATE};

    let spec: SinkSpec = glove.parse().with_context(|| format!("--glove {glove}"))?;
    let (config, stems) = engine_config(engine, Mode::Streaming, 25, true)?;
    if !stems.is_empty() {
        anyhow::bail!("--stem cannot be used with live: there is only the captured mix");
    }
    let bin_ms = config.bin_ms;
    let live_profile = config.profile == tactus_engine::Profile::Live;
    let mut eng = Engine::new(config)?;
    let stop = stop_flag();
    // Issue 13: real-time scheduling for this (engine) thread, asked for before the capture
    // and sink threads exist so that they inherit it. On a loaded machine a normal thread
    // waited up to 300 ms for the CPU (benches/live_latency.py at load 10-16). Refused
    // without the privilege (RLIMIT_RTPRIO, CAP_SYS_NICE): then a note, and live goes on.
    let realtime =
        audio_thread_priority::promote_current_thread_to_real_time(LIVE_PERIOD_FRAMES, ENGINE_RATE)
            .map_err(|e| e.to_string());
    // Issue 13: the live profile asks the device for the engine's rate (no resampler) and
    // a short period (PulseAudio's default period alone cost about 350 ms).
    let request = crate::audio::CaptureRequest {
        rate: live_profile.then_some(ENGINE_RATE),
        period_frames: live_profile.then_some(LIVE_PERIOD_FRAMES),
    };
    let mut cap = crate::audio::Capture::open_with(input, &request)?;
    let rate = cap.rate();
    let mut rs = StreamResampler::new(rate, ENGINE_RATE, 1)?;
    let sink = open_sink(&spec, &SinkOptions::default())?;
    eprintln!(
        "tactus: live from {} ({} Hz, {} ch) to {spec}, {bin_ms} ms bins{}",
        cap.device(),
        rate,
        cap.channels(),
        if seconds.is_some() {
            ""
        } else {
            "; Ctrl-C stops"
        }
    );
    // Everything the loop touches is allocated here.
    let mut raw: Vec<f32> = Vec::with_capacity(cap.capacity());
    let ratio = f64::from(ENGINE_RATE) / f64::from(rate);
    let mut out = vec![Vec::with_capacity(
        (cap.capacity() as f64 * ratio) as usize + 4 * rs.latency_samples() + 8192,
    )];
    let mut latencies: Vec<f64> = Vec::with_capacity(1 << 16);
    let limit = seconds.map(|s| (s.max(0.0) * f64::from(rate)) as u64);
    let bin_samples = eng.bin_samples() as f64;
    let (mut captured, mut delivered) = (0u64, 0usize);
    let t_open = Instant::now();
    let mut last_tui = Instant::now();
    let mut peak = 0.0f32;
    let result: Result<()> = loop {
        if stop.load(Ordering::Relaxed) {
            break Ok(());
        }
        raw.clear();
        if cap.read(&mut raw) == 0 {
            if cap.first_callback().is_none() && t_open.elapsed() > Duration::from_secs(10) {
                break Err(anyhow::anyhow!(
                    "input device {} delivered no audio in 10 s",
                    cap.device()
                ));
            }
            if cap.had_error() && cap.first_callback().is_none() {
                break Err(anyhow::anyhow!("input device {} failed", cap.device()));
            }
            std::thread::sleep(Duration::from_millis(2));
        } else {
            if let Some(l) = limit {
                raw.truncate((l - captured).min(raw.len() as u64) as usize);
            }
            captured += raw.len() as u64;
            out[0].clear();
            rs.process(&[&raw], &mut out);
            eng.process(&out[0], &out[0], &[]);
            if let Some(e) = eng.take_separator_error() {
                break Err(e.into());
            }
            // Issue 13: each finger group goes out as soon as it is final
            // (Engine::live_frame); the pitch chains' look-ahead no longer holds back the
            // rhythm pins.
            let ready = eng.live_ready_bins();
            let first = cap.first_callback();
            while delivered < ready {
                sink.send_frame(
                    eng.live_frame(delivered),
                    (delivered as u64 * u64::from(bin_ms)) as u32,
                );
                if let Some((t0, n0)) = first {
                    // The bin's last sample, in device frames, was captured about
                    // (n − n0) / rate after the first callback (which brought n0 frames).
                    let end = (delivered + 1) as f64 * bin_samples / ratio;
                    let captured_at = (end - n0 as f64) / f64::from(rate);
                    if latencies.len() < latencies.capacity() {
                        latencies.push(t0.elapsed().as_secs_f64() * 1e3 - captured_at * 1e3);
                    }
                }
                delivered += 1;
            }
            if limit.is_some_and(|l| captured >= l) {
                break Ok(());
            }
        }
        if tui && last_tui.elapsed() >= Duration::from_millis(100) {
            last_tui = Instant::now();
            peak = peak.max(cap.take_peak());
            let st = sink.stats();
            let db = 20.0 * f64::from(peak.max(1e-6)).log10();
            let bar = "#".repeat((((db + 60.0) / 3.0).clamp(0.0, 20.0)) as usize);
            eprint!(
                "\r{:>7.1} s  frames {delivered}  dropped {}  overruns {}  link {}  level {db:>6.1} dBFS {bar:<20}",
                captured as f64 / f64::from(rate),
                st.dropped,
                cap.overruns(),
                if st.link_up { "up" } else { "DOWN" },
            );
            peak = 0.0;
        }
    };
    if tui {
        eprintln!();
    }
    sink.all_down();
    let stats = sink.close();
    result?;

    let ms = |n: usize, r: u32| n as f64 * 1e3 / f64::from(r);
    // Issue 13: the capture device's own buffering on its own line, then one budget per
    // finger group (stages in samples at the engine rate and in ms).
    let period = cap.first_callback().map_or(0, |(_, n)| n);
    eprintln!(
        "tactus: capture: {} at {} Hz, period {period} frames ({:.1} ms), input delay {:.1} ms reported by the device; threads {}",
        cap.device(),
        rate,
        ms(period as usize, rate),
        cap.input_delay_ms(),
        match &realtime {
            Ok(_) => "real-time".to_string(),
            Err(e) => format!("at normal priority (real-time refused: {e})"),
        }
    );
    for (group, stages) in eng.latency_paths() {
        let mut budget: Vec<(String, usize)> = Vec::new();
        if rate != ENGINE_RATE {
            budget.push((
                format!("resample {rate} -> {ENGINE_RATE} Hz"),
                rs.latency_samples(),
            ));
        }
        budget.extend(stages);
        eprintln!(
            "tactus: latency budget, {group} fingers ({} profile; after the capture period):",
            eng.config().profile.name()
        );
        let mut sum = 0.0;
        for (name, n) in &budget {
            let v = ms(*n, ENGINE_RATE);
            sum += v;
            eprintln!("    {name:<44} {n:>6} samples {v:>7.1} ms");
        }
        let link = (lead_ms(&spec, 0) - 50) as f64;
        eprintln!("    {:<44} {:>14} {link:>7.1} ms", "link", "");
        eprintln!(
            "    {:<44} {:>14} {:>7.1} ms",
            "total to the glove",
            "",
            sum + link
        );
        eprintln!(
            "    {:<44} {:>14} {:>7.1} ms",
            "(then the pin rise)", "", 50.0
        );
    }
    latencies.sort_by(f64::total_cmp);
    if !latencies.is_empty() {
        let p = |q: f64| {
            latencies[((latencies.len() as f64 * q).ceil() as usize).clamp(1, latencies.len()) - 1]
        };
        eprintln!(
            "tactus: measured bin end (captured) -> frame sent: median {:.1} ms, p95 {:.1} ms, max {:.1} ms",
            p(0.5),
            p(0.95),
            p(1.0)
        );
    }
    let wall = cap
        .first_callback()
        .map(|(t, n0)| (t.elapsed().as_secs_f64(), n0))
        .unwrap_or((0.0, 0));
    eprintln!(
        "tactus: captured {:.3} s ({} callbacks, overruns {} samples; capture clock {:+.1} ms vs wall since the first callback), {delivered} frames to {spec}; sink sent {}, dropped {} ({DROPPED}), reconnects {}",
        captured as f64 / f64::from(rate),
        cap.callbacks(),
        cap.overruns(),
        ((cap.frames() - wall.1) as f64 / f64::from(rate) - wall.0) * 1e3,
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
    eprintln!(
        "tactus: emulated glove: {} packets ({} pin frames, {} all-down, {} keep-alive), \
         {} CRC errors, {} malformed, {} sequence gaps, {} garbage bytes, {} pin changes; \
         final frame {}",
        r.packets,
        r.frames.len(),
        r.all_downs,
        r.keep_alives,
        r.crc_errors,
        r.malformed,
        r.sequence_gaps,
        r.garbage_bytes,
        r.actuations,
        r.final_frame.to_hex()
    );
    let mut report = serde_json::json!({
        "packets": r.packets,
        "pin_frames": r.frames.len(),
        "crc_errors": r.crc_errors,
        "malformed": r.malformed,
        "sequence_gaps": r.sequence_gaps,
        "garbage_bytes": r.garbage_bytes,
        "all_downs": r.all_downs,
        "keep_alives": r.keep_alives,
        "actuations": r.actuations,
        "final_frame": r.final_frame.to_hex(),
    });
    if json_frames {
        report["frames"] = r
            .frames
            .iter()
            .map(|f| {
                serde_json::json!({
                    "arrival_ms": f.arrival_ms, "seq": f.seq, "time_ms": f.time_ms, "frame": f.frame.to_hex()
                })
            })
            .collect();
    }
    println!("{report}");
    Ok(())
}
