//! Sinks: one thread per link, driven by [`SinkCommand`]s, with latest-state semantics and
//! reconnection.
//!
//! ## Design
//! The producer (player, live engine) talks to a sink through a [`SinkHandle`]. Commands go
//! into a **bounded mailbox** that holds at most one pending *state* command (a frame or
//! all-down), one keep-alive request and the stop flag. Because every pins packet carries
//! the full 80-pin state (docs/design.md, wire protocol v1), a newer state supersedes an older one
//! that has not been written yet: it is overwritten and counted in [`SinkStats::dropped`].
//! So the producer never blocks on a slow or dead link (it only takes an uncontended lock
//! for a few instructions; the sink thread never holds it during I/O), and a link that comes
//! back gets the *current* state, never a backlog of stale frames.
//!
//! The sink thread owns the link. After a write error or a disconnect it marks the link
//! down, closes it and reconnects with exponential backoff ([`SinkOptions::backoff_min`]
//! 50 ms, doubling up to [`SinkOptions::backoff_max`] 2 s); after every reconnect it resends
//! the current state. An idle link gets a keep-alive packet every
//! [`SinkOptions::keep_alive`] (1 s), which also surfaces a dead link between frames.
//!
//! [`SinkHandle::close`] (and, best effort, dropping the handle) sends all-pins-down, waits
//! up to [`SinkOptions::close_timeout`] (1 s) for a dead link to come back to deliver it,
//! joins the thread and returns the final [`SinkStats`].
//!
//! ## Latency
//! A command reaches the link after one condition-variable wake-up (tens of µs) plus the
//! write itself: 16 bytes at 115200 baud take 1.4 ms on a UART, one BLE connection interval
//! (7.5–30 ms typically) over the air.

use std::sync::{mpsc, Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use tactus_glove::{Frame, Packet};

use crate::emulator::VirtualGlove;
use crate::link::Link;
use crate::spec::SinkSpec;
use crate::TransportError;

/// What a sink thread can be asked to do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SinkCommand {
    /// Show this full pin state; `time_ms` is the frame's time since the stream started
    /// (it goes on the wire modulo 65536).
    Frame {
        /// Frame time in ms since stream start.
        time_ms: u32,
        /// The 80-pin state.
        frame: Frame,
    },
    /// Lower every pin.
    AllDown,
    /// Send a keep-alive packet now (the thread also sends them on its own when idle).
    KeepAlive,
    /// Deliver what is pending, then end the thread.
    Stop,
}

/// Counters and link state of one sink.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SinkStats {
    /// Packets written to the link (pins, all-down and keep-alive).
    pub sent: u64,
    /// Pins packets among `sent`.
    pub frames_sent: u64,
    /// All-down packets among `sent`.
    pub all_down_sent: u64,
    /// State commands superseded before they could be written (latest-state semantics).
    pub dropped: u64,
    /// Successful re-connections after the link went down.
    pub reconnects: u64,
    /// Failed connection attempts and failed writes.
    pub errors: u64,
    /// Whether the link is connected now.
    pub link_up: bool,
    /// The most recent error, if any.
    pub last_error: Option<String>,
    /// The link's MTU in bytes, where it reports one (BLE).
    pub mtu: Option<u16>,
    /// The pin state the last pins or all-down packet written to the link showed: what the
    /// glove shows now (for the terminal view, `--tui`). All down before the first packet.
    pub shown: Frame,
    /// That packet's frame time, ms since stream start.
    pub shown_time_ms: u32,
}

/// Tuning of a sink; [`Default`] gives the documented values.
#[derive(Debug, Clone, PartialEq)]
pub struct SinkOptions {
    /// Interval of keep-alive packets on an idle link; `None` sends none. Default 1 s.
    pub keep_alive: Option<Duration>,
    /// First reconnect delay. Default 50 ms.
    pub backoff_min: Duration,
    /// Largest reconnect delay. Default 2 s.
    pub backoff_max: Duration,
    /// How long closing waits for a dead link to come back to deliver all-down. Default 1 s.
    pub close_timeout: Duration,
    /// How long a BLE scan looks for the device. Default 10 s.
    pub scan_timeout: Duration,
}

impl Default for SinkOptions {
    fn default() -> SinkOptions {
        SinkOptions {
            keep_alive: Some(Duration::from_secs(1)),
            backoff_min: Duration::from_millis(50),
            backoff_max: Duration::from_secs(2),
            close_timeout: Duration::from_secs(1),
            scan_timeout: Duration::from_secs(10),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum StateCmd {
    Frame { time_ms: u32, frame: Frame },
    AllDown,
}

#[derive(Default)]
struct Mailbox {
    state: Option<StateCmd>,
    keep_alive: bool,
    stop: bool,
}

struct Shared {
    mailbox: Mutex<Mailbox>,
    wake: Condvar,
    stats: Mutex<SinkStats>,
}

/// Locks ignoring poisoning: every critical section leaves the data consistent.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// The producer's side of a sink. Cheap calls that never block on the link.
pub struct SinkHandle {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
    glove: Option<Arc<Mutex<VirtualGlove>>>,
    spec: String,
}

impl SinkHandle {
    /// Queues a command (see [`SinkCommand`]); a pending older state is superseded.
    /// Commands after [`SinkCommand::Stop`] are ignored.
    pub fn send(&self, cmd: SinkCommand) {
        let mut mb = lock(&self.shared.mailbox);
        if mb.stop {
            return;
        }
        let state = match cmd {
            SinkCommand::Frame { time_ms, frame } => Some(StateCmd::Frame { time_ms, frame }),
            SinkCommand::AllDown => Some(StateCmd::AllDown),
            SinkCommand::KeepAlive => {
                mb.keep_alive = true;
                None
            }
            SinkCommand::Stop => {
                mb.stop = true;
                None
            }
        };
        if let Some(s) = state {
            // A pending all-down replaced by another all-down loses nothing.
            if mb
                .state
                .replace(s)
                .is_some_and(|old| old != s || s != StateCmd::AllDown)
            {
                lock(&self.shared.stats).dropped += 1;
            }
        }
        drop(mb);
        self.shared.wake.notify_one();
    }

    /// Shows `frame`; `time_ms` is its time since stream start.
    pub fn send_frame(&self, frame: Frame, time_ms: u32) {
        self.send(SinkCommand::Frame { time_ms, frame });
    }

    /// Lowers every pin.
    pub fn all_down(&self) {
        self.send(SinkCommand::AllDown);
    }

    /// A snapshot of the counters.
    pub fn stats(&self) -> SinkStats {
        lock(&self.shared.stats).clone()
    }

    /// The sink as given (canonical [`SinkSpec`] text).
    pub fn describe(&self) -> &str {
        &self.spec
    }

    /// The virtual glove behind an `emulator` sink (`None` for other sinks).
    pub fn virtual_glove(&self) -> Option<Arc<Mutex<VirtualGlove>>> {
        self.glove.clone()
    }

    /// Sends all-pins-down, stops the thread (after at most
    /// [`SinkOptions::close_timeout`] of trying to reach a dead link) and returns the final
    /// counters.
    pub fn close(mut self) -> SinkStats {
        self.shutdown();
        self.stats()
    }

    fn shutdown(&mut self) {
        if let Some(thread) = self.thread.take() {
            self.send(SinkCommand::AllDown);
            self.send(SinkCommand::Stop);
            // A panic in the sink thread is a bug; its counters are still returned.
            let _ = thread.join();
        }
    }
}

impl Drop for SinkHandle {
    /// Best effort all-pins-down, like [`SinkHandle::close`].
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// Starts the sink thread on `link` and waits for its first connection; the connection's
/// failure comes back as the link's reason ([`crate::factory::open_sink`] makes it typed).
pub(crate) fn start(
    link: Box<dyn Link>,
    glove: Option<Arc<Mutex<VirtualGlove>>>,
    spec: &SinkSpec,
    opts: &SinkOptions,
) -> Result<Result<SinkHandle, crate::LinkError>, TransportError> {
    let shared = Arc::new(Shared {
        mailbox: Mutex::new(Mailbox::default()),
        wake: Condvar::new(),
        stats: Mutex::new(SinkStats::default()),
    });
    let (ready_tx, ready_rx) = mpsc::channel();
    let thread_shared = Arc::clone(&shared);
    let thread_opts = opts.clone();
    let thread = std::thread::Builder::new()
        .name(format!("tactus-sink {spec}"))
        .spawn(move || run_sink(link, thread_shared, thread_opts, ready_tx))
        .map_err(TransportError::Thread)?;
    match ready_rx.recv() {
        Ok(Ok(())) => Ok(Ok(SinkHandle {
            shared,
            thread: Some(thread),
            glove,
            spec: spec.to_string(),
        })),
        Ok(Err(e)) => {
            let _ = thread.join();
            Ok(Err(e))
        }
        Err(_) => {
            let _ = thread.join();
            Err(TransportError::Thread(std::io::Error::other(
                "sink thread ended during start-up",
            )))
        }
    }
}

/// The sink thread: see the module docs.
fn run_sink(
    mut link: Box<dyn Link>,
    shared: Arc<Shared>,
    opts: SinkOptions,
    ready: mpsc::Sender<Result<(), crate::LinkError>>,
) {
    if let Err(e) = link.connect() {
        let _ = ready.send(Err(e));
        return;
    }
    {
        let mut st = lock(&shared.stats);
        st.link_up = true;
        st.mtu = link.mtu();
    }
    let _ = ready.send(Ok(()));

    let far = Duration::from_secs(3600);
    let mut up = true;
    let mut current: Option<StateCmd> = None;
    let mut dirty = false;
    let mut seq: u8 = 0;
    let mut last_time_ms: u32 = 0;
    let mut backoff = opts.backoff_min;
    let mut next_attempt = Instant::now();
    let mut last_write = Instant::now();
    let mut close_deadline: Option<Instant> = None;
    let mut stop_seen = false;

    loop {
        // Wait for a command, the next reconnect attempt or the next keep-alive.
        let mut deadline = if !up {
            next_attempt
        } else if dirty {
            Instant::now()
        } else {
            last_write + opts.keep_alive.unwrap_or(far)
        };
        if let Some(d) = close_deadline {
            deadline = deadline.min(d);
        }
        let (cmd, ka_request, stop) = take_commands(&shared, deadline, stop_seen);
        if let Some(c) = cmd {
            // An all-down right after a delivered all-down changes nothing on the glove
            // (e.g. the player's final all-down followed by close()): not re-sent.
            let redundant = !dirty && c == StateCmd::AllDown && current == Some(StateCmd::AllDown);
            if !redundant {
                if dirty {
                    lock(&shared.stats).dropped += 1;
                }
                current = Some(c);
                dirty = true;
            }
        }
        let now = Instant::now();
        if stop && !stop_seen {
            stop_seen = true;
            close_deadline = Some(now + opts.close_timeout);
        }

        if !up && now >= next_attempt {
            match link.connect() {
                Ok(()) => {
                    up = true;
                    // The backoff is reset by the next successful write, not here, so a link
                    // that connects but cannot be written is not hammered every 50 ms.
                    // Whatever was on the wire before may be lost: resend the current state.
                    dirty = current.is_some();
                    let mut st = lock(&shared.stats);
                    st.reconnects += 1;
                    st.link_up = true;
                    st.mtu = link.mtu().or(st.mtu);
                }
                Err(e) => {
                    next_attempt = now + backoff;
                    backoff = (backoff * 2).min(opts.backoff_max);
                    let mut st = lock(&shared.stats);
                    st.errors += 1;
                    st.last_error = Some(e.to_string());
                }
            }
        }

        if up {
            let keep_alive_due = opts
                .keep_alive
                .is_some_and(|ka| now.duration_since(last_write) >= ka);
            let packet = match (dirty, current) {
                (true, Some(StateCmd::Frame { time_ms, frame })) => {
                    last_time_ms = time_ms;
                    Some(Packet::pins(seq, time_ms as u16, frame))
                }
                (true, Some(StateCmd::AllDown)) => Some(Packet::all_down(seq, last_time_ms as u16)),
                _ if ka_request || keep_alive_due => {
                    Some(Packet::keep_alive(seq, last_time_ms as u16))
                }
                _ => None,
            };
            if let Some(packet) = packet {
                match link.write(&packet, &packet.encode()) {
                    Ok(()) => {
                        backoff = opts.backoff_min;
                        seq = seq.wrapping_add(1);
                        last_write = Instant::now();
                        if packet.kind != tactus_glove::PacketType::KeepAlive {
                            dirty = false;
                        }
                        note_written(&shared, &packet, last_time_ms);
                    }
                    Err(e) => {
                        link.disconnect();
                        up = false;
                        next_attempt = Instant::now() + backoff;
                        backoff = (backoff * 2).min(opts.backoff_max);
                        let mut st = lock(&shared.stats);
                        st.errors += 1;
                        st.link_up = false;
                        st.last_error = Some(e.to_string());
                    }
                }
            }
        }

        if stop {
            let delivered = up && !dirty;
            let gave_up = close_deadline.is_some_and(|d| Instant::now() >= d);
            if delivered || gave_up {
                break;
            }
        }
    }
    link.disconnect();
    lock(&shared.stats).link_up = false;
}

/// Waits until the mailbox holds a state command or a keep-alive request, a stop not yet
/// seen arrives, or `deadline` passes; takes the state command and the keep-alive request.
/// Returns them with the stop flag.
fn take_commands(
    shared: &Shared,
    deadline: Instant,
    stop_seen: bool,
) -> (Option<StateCmd>, bool, bool) {
    let mut mb = lock(&shared.mailbox);
    loop {
        let now = Instant::now();
        if mb.state.is_some() || mb.keep_alive || (mb.stop && !stop_seen) || now >= deadline {
            break;
        }
        mb = shared
            .wake
            .wait_timeout(mb, deadline - now)
            .unwrap_or_else(|e| e.into_inner())
            .0;
    }
    let ka = std::mem::take(&mut mb.keep_alive);
    (mb.state.take(), ka, mb.stop)
}

/// Counts a packet the link took, and what the glove shows now (`time_ms`: its frame time).
fn note_written(shared: &Shared, packet: &Packet, time_ms: u32) {
    let mut st = lock(&shared.stats);
    st.sent += 1;
    match packet.kind {
        tactus_glove::PacketType::Pins => {
            st.frames_sent += 1;
            st.shown = packet.frame;
            st.shown_time_ms = time_ms;
        }
        tactus_glove::PacketType::AllDown => {
            st.all_down_sent += 1;
            st.shown = Frame::DOWN;
        }
        tactus_glove::PacketType::KeepAlive => {}
    }
}
