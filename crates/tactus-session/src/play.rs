//! `play`: a song (rendered frame by frame as it plays) or a pattern's frames, sent to a
//! sink on a clock.
//!
//! ## A song ([`play_song`])
//! The song is decoded **once**: the engine renders it on its own thread
//! ([`render_tapped`], streaming mode) and hands every decoded block on to a feeder thread
//! that pushes it into the speakers ([`tactus_audio::device::PlaybackFeed`], feature
//! `device`). The calling thread sends frame `k` when the play clock reads
//! `k · bin_ms − lead` (the lead is the pin rise plus the link's latency plus the user's
//! offset). The play clock is the audio output's position when speakers are asked for and
//! open, otherwise the caller's [`Clock`] (the wall clock, or a fake one in tests). Rendering
//! runs far faster than real time, but only [`PlayOptions::render_ahead_ms`] (2 s: 80 frames
//! at 25 ms bins) ahead of the clock: the frames wait in a bounded queue and the renderer
//! blocks when it holds that many. A frame that is not ready in time is skipped (the next
//! frame carries the full state anyway). Every exit (end, stop, error) sends all-down.
//!
//! ## A song rendered whole first ([`play_song_whole`])
//! The engine renders the whole song offline before the first frame (every level range is
//! the song's own from the start), then its frames are played like a pattern's, below.
//!
//! ## A pattern ([`play_pattern`])
//! Its frames are sent by the same scheduler ([`tactus_transport::schedule`]), on the audio
//! clock of its song when one is given (decoded and played, no engine), else on the caller's
//! clock.

use std::collections::VecDeque;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;
#[cfg(feature = "device")]
use std::time::Instant;

use tactus_engine::render::{render_tapped, render_until, RenderRequest};
use tactus_engine::EngineError;
use tactus_glove::Frame;
use tactus_transport::{
    schedule, Clock, FrameSource, PlayStatus, ScheduleError, SinkHandle, Slot, Timing,
};

use crate::SessionError;

/// How far, in ms of song time, the renderer may run ahead of the play clock by default.
pub const RENDER_AHEAD_MS: u32 = 2000;

/// How a play session runs.
#[derive(Debug, Clone, PartialEq)]
pub struct PlayOptions {
    /// Send frames this much early, ms ([`tactus_transport::lead_ms`]).
    pub lead_ms: i64,
    /// Play the sound on the default output device and time frames on its clock (feature
    /// `device`; without it, or when no device opens, the caller's clock is used and the
    /// report says why).
    pub speakers: bool,
    /// How far the renderer may run ahead of the clock, ms.
    pub render_ahead_ms: u32,
    /// A clock that stops moving for this long (a stalled audio device) ends playback.
    pub stall: Duration,
    /// What happens to a frame of a song that is not rendered when its time comes.
    pub late: Late,
}

/// What happens to a frame that is not rendered when its time comes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Late {
    /// Skip it: the next frame carries the full state anyway (real time: the default).
    #[default]
    Skip,
    /// Wait for it, holding the clock's frame schedule back: for clocks that are not real
    /// time (a simulation, a fake clock in tests), where nothing can be late.
    Wait,
}

impl Default for PlayOptions {
    fn default() -> Self {
        PlayOptions {
            lead_ms: i64::from(tactus_glove::PIN_RISE_MS),
            speakers: false,
            render_ahead_ms: RENDER_AHEAD_MS,
            stall: Duration::from_secs(10),
            late: Late::Skip,
        }
    }
}

/// What the speakers did.
#[derive(Debug, Clone, PartialEq)]
pub struct SoundReport {
    /// The output device.
    pub device: String,
    /// Its rate, Hz.
    pub rate: u32,
    /// The song's length, s.
    pub song_s: f64,
    /// The audio clock at the end, s.
    pub clock_s: f64,
    /// Wall time from the first sample audible to the end, s.
    pub wall_s: f64,
    /// Output latency cpal reported, ms.
    pub latency_ms: f64,
    /// Output callbacks that found the ring short.
    pub underruns: u64,
    /// Whether decoding failed part-way.
    pub feed_failed: bool,
}

/// `audio on DEVICE at RATE Hz: song …, audio clock … (drift …), output latency …,
/// underruns …`, as `tactus play` prints it.
impl std::fmt::Display for SoundReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "audio on {} at {} Hz: song {:.3} s, audio clock {:.3} s after {:.3} s of wall time (drift {:+.1} ms), output latency {:.1} ms, underruns {}{}",
            self.device,
            self.rate,
            self.song_s,
            self.clock_s,
            self.wall_s,
            (self.clock_s - self.wall_s) * 1e3,
            self.latency_ms,
            self.underruns,
            if self.feed_failed { ", decoding failed part-way" } else { "" }
        )
    }
}

/// What a play session did.
#[derive(Debug, Clone, PartialEq)]
pub struct PlayReport {
    /// The scheduler's report: frames sent, frames not ready in time (skipped), jitter.
    pub timing: tactus_transport::PlayReport,
    /// The speakers, when they played.
    pub sound: Option<SoundReport>,
    /// Things the user should know (no audio output, and why).
    pub warnings: Vec<String>,
}

/// Frames between the rendering thread and the sender: a bounded queue.
#[derive(Default)]
struct Queue {
    /// Frames `base ..` not yet sent.
    frames: VecDeque<Frame>,
    /// Index of `frames[0]`.
    base: usize,
    done: bool,
    error: Option<EngineError>,
}

type SharedQueue = Arc<(Mutex<Queue>, Condvar)>;

fn crashed() -> SessionError {
    SessionError::Renderer("the rendering thread crashed".into())
}

/// The speakers, when open: the playback and the clock on it.
#[cfg(feature = "device")]
mod speakers {
    use super::*;
    use tactus_audio::device::{Playback, PlaybackFeed};

    /// The audio clock: song time audible now; `-inf` before the first callback.
    pub struct AudioClock<'a>(pub &'a Playback);

    impl Clock for AudioClock<'_> {
        fn now_ms(&self) -> f64 {
            self.0.now_ms().unwrap_or(f64::NEG_INFINITY)
        }
    }

    /// Opens the default output for a song at `rate`; on failure the warning says why.
    pub fn open(
        rate: u32,
        pad_ms: u32,
        stop: &Arc<AtomicBool>,
        warnings: &mut Vec<String>,
    ) -> Option<(Playback, PlaybackFeed)> {
        match Playback::open(rate, pad_ms, stop.clone()) {
            Ok(p) => Some(p),
            Err(e) => {
                let mut msg = e.to_string();
                let mut src = std::error::Error::source(&e);
                while let Some(c) = src {
                    msg.push_str(&format!(": {c}"));
                    src = c.source();
                }
                warnings.push(format!(
                    "no audio output ({}); timing frames on the wall clock",
                    msg.replace('\n', " ")
                ));
                None
            }
        }
    }

    /// Lets the song play out, then describes the audio clock against the wall clock.
    pub fn finish(out: &Playback, stop: &AtomicBool) -> SoundReport {
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
        SoundReport {
            device: out.device().to_string(),
            rate: out.rate(),
            song_s: out.duration_ms().unwrap_or(0.0) / 1e3,
            clock_s: out.now_ms().unwrap_or(0.0) / 1e3,
            // Wall time from the first sample being audible (first callback + output
            // latency) to now.
            wall_s: st
                .first_callback
                .map(|f| f.elapsed().as_secs_f64() - st.latency_ms / 1e3)
                .unwrap_or(0.0),
            latency_ms: st.latency_ms,
            underruns: st.underruns,
            feed_failed: out.feed_failed(),
        }
    }
}

/// Blocks of decoded audio on their way to the speakers' feed.
#[cfg(not(feature = "device"))]
type BlockTx = std::sync::mpsc::Sender<(Vec<f32>, Vec<f32>)>;

/// Plays a song: renders it on its own thread as it plays and sends each frame on the clock
/// (the speakers' when `opts.speakers` and they open, else `clock`). See the module docs.
///
/// Errors: the song cannot be opened or decoded, the engine cannot be built or fails, or the
/// play clock stalls.
pub fn play_song(
    req: RenderRequest,
    sink: &SinkHandle,
    clock: &dyn Clock,
    opts: &PlayOptions,
    stop: &Arc<AtomicBool>,
) -> Result<PlayReport, SessionError> {
    let bin_ms = req.config.bin_ms.max(1);
    let ahead = (opts.render_ahead_ms.div_ceil(bin_ms) as usize).max(8);
    let mut warnings = Vec::new();
    let pad_ms = opts.lead_ms.max(0) as u32;
    #[cfg(feature = "device")]
    let opened = if opts.speakers {
        let rate = tactus_audio::AudioSource::open(&req.input)?
            .info()
            .sample_rate;
        speakers::open(rate, pad_ms, stop, &mut warnings)
    } else {
        None
    };
    #[cfg(not(feature = "device"))]
    if opts.speakers {
        let _ = pad_ms;
        warnings.push(
            "built without the `audio` feature: no sound; timing frames on the wall clock (--no-audio)"
                .into(),
        );
    }
    #[cfg(feature = "device")]
    let (playback, block_tx, feeder) = match opened {
        Some((playback, mut feed)) => {
            let (tx, rx) = std::sync::mpsc::channel::<(Vec<f32>, Vec<f32>)>();
            let h = std::thread::Builder::new()
                .name("tactus-audio-feed".into())
                .spawn(move || {
                    for (l, r) in rx.iter() {
                        if !feed.push(&l, &r) {
                            return;
                        }
                    }
                    feed.finish();
                })
                .map_err(|source| SessionError::Spawn {
                    what: "audio feeder",
                    source,
                })?;
            (Some(playback), Some(tx), Some(h))
        }
        None => (None, None, None),
    };
    #[cfg(not(feature = "device"))]
    let (block_tx, feeder): (Option<BlockTx>, Option<std::thread::JoinHandle<()>>) = (None, None);
    let shared: SharedQueue = Arc::new((Mutex::new(Queue::default()), Condvar::new()));
    let producer = {
        let shared = shared.clone();
        let stop = stop.clone();
        std::thread::spawn(move || {
            let (m, cv) = &*shared;
            let tx = block_tx;
            // Returning `false` (stopped, or a poisoned lock) ends the render at once.
            let result = render_tapped(
                &req,
                &mut |_| {},
                &mut |l, r| {
                    if let Some(tx) = &tx {
                        let _ = tx.send((l.to_vec(), r.to_vec()));
                    }
                },
                &mut |k, f| {
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
                },
            );
            drop(tx);
            // A stop is not an error to report.
            let result = match result {
                Err(EngineError::Cancelled) => Ok(()),
                other => other.map(|_| ()),
            };
            if let Ok(mut g) = m.lock() {
                g.done = true;
                if let Err(e) = result {
                    g.error = Some(e);
                }
                cv.notify_all();
            }
        })
    };
    let mut source = QueueSource {
        shared: &shared,
        late: opts.late,
    };
    let outcome = wait_first_frame(&shared, stop).and_then(|()| {
        #[cfg(feature = "device")]
        if let Some(playback) = &playback {
            playback.wait_prefilled(Duration::from_secs(5));
            playback.start()?;
            return schedule_on(
                &mut source,
                sink,
                &speakers::AudioClock(playback),
                bin_ms,
                opts,
                stop,
                &mut |_| {},
            );
        }
        schedule_on(&mut source, sink, clock, bin_ms, opts, stop, &mut |_| {})
    });
    if outcome.is_err() {
        sink.all_down();
    }
    #[cfg(feature = "device")]
    let sound = playback
        .as_ref()
        .filter(|_| outcome.is_ok())
        .map(|p| speakers::finish(p, stop));
    #[cfg(not(feature = "device"))]
    let sound = None;
    stop.store(true, Ordering::SeqCst);
    #[cfg(feature = "device")]
    drop(playback);
    let _ = producer.join();
    if let Some(f) = feeder {
        let _ = f.join();
    }
    Ok(PlayReport {
        timing: outcome?,
        sound,
        warnings,
    })
}

/// Plays a song rendered whole first ([`tactus_engine::Mode::Offline`], whatever mode
/// `req` asks for): the engine reads the whole song before the first frame, so every level
/// range is the song's own from the first note (a streaming render learns it as the song
/// goes, and its first seconds are the least accurate: `docs/limitations.md`, "Streaming
/// levels need the song's range"). The frames are then played as [`play_pattern`] plays a pattern's, on the
/// song's audio clock. `rendered(seconds)` is called once the render is done. Costs a wait
/// before the sound starts (about 1 % of the song's duration on 2 cores) and the whole
/// pattern in memory (about 100 KB for 3.5 minutes at 25 ms bins).
///
/// A stop during the render returns at once (the render checks between decoded blocks of
/// about 2 s of audio), with [`tactus_transport::PlayReport::stopped`] set and nothing sent
/// but all-down.
pub fn play_song_whole(
    mut req: RenderRequest,
    sink: &SinkHandle,
    clock: &dyn Clock,
    opts: &PlayOptions,
    stop: &Arc<AtomicBool>,
    rendered: &mut dyn FnMut(f64),
) -> Result<PlayReport, SessionError> {
    req.config.mode = tactus_engine::Mode::Offline;
    let t = std::time::Instant::now();
    // Only the frames are kept for playback: the rest of the render (the features file's
    // per-hop records) is dropped with the match arm.
    let (pattern, mut warnings) =
        match render_until(&req, &mut |_| {}, &mut || !stop.load(Ordering::Relaxed)) {
            Ok(out) => (out.pattern, out.warnings),
            Err(EngineError::Cancelled) => {
                sink.all_down();
                return Ok(PlayReport {
                    timing: tactus_transport::PlayReport {
                        stopped: true,
                        ..Default::default()
                    },
                    sound: None,
                    warnings: Vec::new(),
                });
            }
            Err(e) => return Err(e.into()),
        };
    rendered(t.elapsed().as_secs_f64());
    // Playback starts now: the caller's clock, read from here (the render took its time).
    let zero = clock.now_ms();
    let after = Shifted {
        inner: clock,
        zero: if zero.is_finite() { zero } else { 0.0 },
    };
    let mut report = play_pattern(
        &pattern.frames,
        pattern.bin_ms,
        Some(&req.input),
        sink,
        &after,
        opts,
        stop,
        &mut |_| {},
    )?;
    warnings.append(&mut report.warnings);
    report.warnings = warnings;
    Ok(report)
}

/// A clock read from `zero` on: [`play_song_whole`]'s playback starts after its render.
struct Shifted<'a> {
    inner: &'a dyn Clock,
    zero: f64,
}

impl Clock for Shifted<'_> {
    fn now_ms(&self) -> f64 {
        // −inf (a clock not started yet) stays −inf.
        self.inner.now_ms() - self.zero
    }
    fn sleep_ms(&self, ms: f64) {
        self.inner.sleep_ms(ms)
    }
}

// Eight arguments: the frames and their bin, the song, the sink, the clock, the options, the
// stop flag and the status callback are each a separate thing the caller owns.
#[allow(clippy::too_many_arguments)]
/// Plays a pattern's frames. With `song` (and speakers asked for), the song is decoded and
/// played and the frames follow its audio clock (and [`PlayReport::sound`] says how it
/// went); otherwise they follow `clock` and `status` is called after each frame.
pub fn play_pattern(
    frames: &[Frame],
    bin_ms: u32,
    song: Option<&Path>,
    sink: &SinkHandle,
    clock: &dyn Clock,
    opts: &PlayOptions,
    stop: &Arc<AtomicBool>,
    status: &mut dyn FnMut(tactus_transport::PlayStatus),
) -> Result<PlayReport, SessionError> {
    #[cfg_attr(not(feature = "device"), allow(unused_mut))]
    let mut warnings = Vec::new();
    #[cfg(feature = "device")]
    if let (Some(song), true) = (song, opts.speakers) {
        let mut source = tactus_audio::AudioSource::open(song)?;
        let rate = source.info().sample_rate;
        if let Some((playback, mut feed)) =
            speakers::open(rate, opts.lead_ms.max(0) as u32, stop, &mut warnings)
        {
            let feeder = std::thread::Builder::new()
                .name("tactus-audio-feed".into())
                .spawn(move || {
                    let (mut l, mut r) = (Vec::new(), Vec::new());
                    loop {
                        l.clear();
                        r.clear();
                        match source.read_block(&mut l, &mut r) {
                            Ok(0) => break feed.finish(),
                            Ok(_) => {
                                if !feed.push(&l, &r) {
                                    break;
                                }
                            }
                            Err(_) => break feed.fail(),
                        }
                    }
                })
                .map_err(|source| SessionError::Spawn {
                    what: "audio feeder",
                    source,
                })?;
            playback.wait_prefilled(Duration::from_secs(5));
            let outcome = playback.start().map_err(SessionError::from).and_then(|()| {
                schedule_on(
                    &mut { frames },
                    sink,
                    &speakers::AudioClock(&playback),
                    bin_ms.max(1),
                    opts,
                    stop,
                    &mut |_| {},
                )
            });
            if outcome.is_err() {
                sink.all_down();
            }
            let sound = outcome.is_ok().then(|| speakers::finish(&playback, stop));
            stop.store(true, Ordering::SeqCst);
            drop(playback);
            let _ = feeder.join();
            return Ok(PlayReport {
                timing: outcome?,
                sound,
                warnings,
            });
        }
    }
    #[cfg(not(feature = "device"))]
    let _ = song;
    Ok(PlayReport {
        timing: schedule_on(&mut { frames }, sink, clock, bin_ms, opts, stop, status)?,
        sound: None,
        warnings,
    })
}

/// Waits (holding the lock between checks) while `pending(queue)` holds, the renderer is
/// not done and `stop` is not set; then reports a rendering error if there is one.
fn wait_while<'a>(
    shared: &'a SharedQueue,
    mut g: std::sync::MutexGuard<'a, Queue>,
    stop: &AtomicBool,
    pending: impl Fn(&Queue) -> bool,
) -> Result<std::sync::MutexGuard<'a, Queue>, SessionError> {
    while pending(&g) && !g.done && !stop.load(Ordering::Relaxed) {
        g = shared
            .1
            .wait_timeout(g, Duration::from_millis(50))
            .map_err(|_| crashed())?
            .0;
    }
    if let Some(e) = g.error.take() {
        return Err(e.into());
    }
    Ok(g)
}

/// Waits until the renderer has produced its first frame (or failed, or ended).
fn wait_first_frame(shared: &SharedQueue, stop: &AtomicBool) -> Result<(), SessionError> {
    let g = shared.0.lock().map_err(|_| crashed())?;
    wait_while(shared, g, stop, |q| q.frames.is_empty()).map(drop)
}

/// The rendering thread's queue as the scheduler's frame source: frame `k` if it is queued,
/// else skipped ([`Late::Skip`]) or waited for ([`Late::Wait`]); the end once the renderer
/// is done and the queue is empty.
struct QueueSource<'a> {
    shared: &'a SharedQueue,
    late: Late,
}

impl FrameSource for QueueSource<'_> {
    type Error = SessionError;

    fn take(&mut self, k: usize, stop: &AtomicBool) -> Result<Slot, SessionError> {
        let (m, cv) = &**self.shared;
        let g = m.lock().map_err(|_| crashed())?;
        let wait = self.late == Late::Wait;
        let mut g = wait_while(self.shared, g, stop, |q| {
            wait && q.base + q.frames.len() <= k
        })?;
        // Frames that came too late for their turn.
        while g.base < k && !g.frames.is_empty() {
            g.frames.pop_front();
            g.base += 1;
        }
        if g.base == k && !g.frames.is_empty() {
            let f = g.frames.pop_front().expect("checked non-empty");
            g.base += 1;
            cv.notify_all();
            Ok(Slot::Frame(f))
        } else if g.done {
            Ok(Slot::End)
        } else {
            Ok(Slot::Missing)
        }
    }
}

/// Runs [`tactus_transport::schedule`]: frame `k` of `source` is sent when `clock` reads
/// `k · bin_ms − lead_ms`; a clock that stands still for `opts.stall` ends it. Ends with
/// all-down.
fn schedule_on<S>(
    source: &mut S,
    sink: &SinkHandle,
    clock: &dyn Clock,
    bin_ms: u32,
    opts: &PlayOptions,
    stop: &AtomicBool,
    status: &mut dyn FnMut(PlayStatus),
) -> Result<tactus_transport::PlayReport, SessionError>
where
    S: FrameSource + ?Sized,
    S::Error: Into<SessionError>,
{
    let timing = Timing {
        bin_ms,
        lead_ms: opts.lead_ms,
        stall: Some(opts.stall),
    };
    schedule(source, sink, clock, &timing, stop, status).map_err(|e| match e {
        ScheduleError::Stalled { seconds } => SessionError::ClockStalled { seconds },
        ScheduleError::Source(e) => e.into(),
    })
}

/// The song of a pattern: `audio` if given, else the recorded path (as given, then relative
/// to the pattern file's folder); its SHA-256 must be the pattern's.
///
/// Errors: no song found ([`SessionError::SongNotFound`]), unreadable
/// ([`SessionError::Io`]), or another file than the one rendered
/// ([`SessionError::SongMismatch`]).
pub fn pattern_song(
    pattern_path: &Path,
    pattern: &tactus_glove::Pattern,
    audio: Option<&Path>,
) -> Result<std::path::PathBuf, SessionError> {
    let recorded = Path::new(&pattern.source.path);
    let song = match audio {
        Some(a) => a.to_path_buf(),
        None => {
            let beside = pattern_path
                .parent()
                .map(|d| d.join(recorded))
                .filter(|_| recorded.is_relative());
            std::iter::once(recorded.to_path_buf())
                .chain(beside)
                .find(|p| p.is_file())
                .ok_or_else(|| SessionError::SongNotFound(recorded.to_path_buf()))?
        }
    };
    let sha = tactus_glove::sha256_file(&song).map_err(|e| SessionError::Io(song.clone(), e))?;
    if sha != pattern.source.sha256 {
        return Err(SessionError::SongMismatch {
            path: song,
            sha256: sha,
            want: pattern.source.sha256.clone(),
        });
    }
    Ok(song)
}
