//! `tactus play` and `tactus emulate`: the path from the engine to the glove's pins.
//!
//! A song is rendered by the streaming engine on its own thread, frame by frame; the main
//! thread sends frame `k` at `k · bin_ms − lead` on the wall clock, where the lead is the
//! 50 ms pin rise plus the link's latency plus `--offset-ms`. Rendering runs far faster
//! than real time, so a frame is normally ready long before it is due; one that is not
//! ready in time is skipped (the next frame carries the full state anyway). Every exit
//! (end, Ctrl-C, error) sends "all pins down".

use std::io::IsTerminal;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use tactus_engine::render::{render_with, RenderRequest};
use tactus_engine::Mode;
use tactus_glove::{Frame, Pattern};
use tactus_transport::{lead_ms, open_sink, play_frames, SinkOptions, SinkSpec, WallClock};

use crate::{engine_config, stop_flag, EngineArgs};

/// Frames shared between the rendering thread and the sender.
#[derive(Default)]
struct Shared {
    frames: Vec<Frame>,
    done: bool,
    error: Option<String>,
}

pub fn run(
    input: &Path,
    glove: &str,
    offset_ms: i64,
    no_audio: bool,
    engine: &EngineArgs,
) -> Result<()> {
    let spec: SinkSpec = glove.parse().with_context(|| format!("--glove {glove}"))?;
    if !no_audio {
        eprintln!("tactus: note: this build has no audio output; timing frames on the wall clock (--no-audio)");
    }
    let stop = stop_flag();
    let is_pattern = input
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    let lead = lead_ms(&spec, offset_ms);
    if is_pattern {
        let pattern = Pattern::from_path(input)?;
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
            "tactus: played {} frames to {}: jitter p95 {:.2} ms, max {:.2} ms; sent {}, dropped {}, reconnects {}{}",
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

    let (config, stems) = engine_config(engine, Mode::Streaming, 25)?;
    let bin_ms = config.bin_ms;
    let req = RenderRequest {
        input: input.to_path_buf(),
        stems,
        config,
    };
    let sink = open_sink(&spec, &SinkOptions::default())?;
    let shared = Arc::new((Mutex::new(Shared::default()), Condvar::new()));
    let producer = {
        let shared = shared.clone();
        let stop = stop.clone();
        std::thread::spawn(move || {
            let push = |k: usize, f: Frame| {
                let (m, cv) = &*shared;
                if let Ok(mut g) = m.lock() {
                    debug_assert_eq!(k, g.frames.len());
                    g.frames.push(f);
                    cv.notify_all();
                }
            };

            let result = render_with(&req, &mut |_| {}, &mut |k, f| {
                if !stop.load(Ordering::Relaxed) {
                    push(k, f)
                }
            });
            let (m, cv) = &*shared;
            if let Ok(mut g) = m.lock() {
                g.done = true;
                if let Err(e) = result {
                    g.error = Some(e.to_string());
                }
                cv.notify_all();
            }
        })
    };
    let outcome = send_live(&shared, &sink, bin_ms, lead, &stop);
    stop.store(true, Ordering::SeqCst);
    let stats = sink.close();
    let _ = producer.join();
    let (sent, skipped) = outcome?;
    eprintln!(
        "tactus: streamed {sent} frames ({skipped} not ready in time) to {spec}; sink sent {}, dropped {}, reconnects {}",
        stats.sent, stats.dropped, stats.reconnects
    );
    Ok(())
}

/// Sends frames on the wall clock as the renderer produces them. Returns (sent, skipped).
fn send_live(
    shared: &Arc<(Mutex<Shared>, Condvar)>,
    sink: &tactus_transport::SinkHandle,
    bin_ms: u32,
    lead_ms: i64,
    stop: &AtomicBool,
) -> Result<(usize, usize)> {
    let (m, cv) = &**shared;
    // Start the clock when the first frame exists, so engine start-up does not eat the lead.
    {
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
    }
    let start = Instant::now() + Duration::from_millis(lead_ms.max(0) as u64);
    let (mut k, mut sent, mut skipped) = (0usize, 0usize, 0usize);
    while !stop.load(Ordering::Relaxed) {
        let due = start + Duration::from_millis(k as u64 * bin_ms as u64)
            - Duration::from_millis(lead_ms.max(0) as u64);
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
        let g = m.lock().map_err(|_| anyhow::anyhow!("renderer crashed"))?;
        if let Some(e) = &g.error {
            anyhow::bail!("{e}");
        }
        if k < g.frames.len() {
            let f = g.frames[k];
            drop(g);
            sink.send_frame(f, (k as u64 * bin_ms as u64) as u32);
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

pub fn emulate(port: &Path, log: Option<&Path>, duration: Option<f64>) -> Result<()> {
    let stop = stop_flag();
    let opts = tactus_transport::emulator::EmulatorOptions {
        max_duration: duration.map(|d| Duration::from_secs_f64(d.max(0.0))),
        ..Default::default()
    };
    let r = tactus_transport::run_emulator_on_port(port, log, &stop, &opts)?;
    let report = serde_json::json!({
        "packets": r.packets,
        "crc_errors": r.crc_errors,
        "malformed": r.malformed,
        "sequence_gaps": r.sequence_gaps,
        "garbage_bytes": r.garbage_bytes,
        "all_downs": r.all_downs,
        "actuations": r.actuations,
        "final_frame": r.final_frame.to_hex(),
        "frames": r.frames.iter().map(|f| serde_json::json!({
            "arrival_ms": f.arrival_ms, "seq": f.seq, "time_ms": f.time_ms, "frame": f.frame.to_hex()
        })).collect::<Vec<_>>(),
    });
    println!("{report}");
    Ok(())
}
