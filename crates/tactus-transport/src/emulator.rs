//! The virtual glove: what the real glove's firmware does with the byte stream, plus the
//! paper's app log.
//!
//! ## Algorithm
//! 1. Bytes go through [`tactus_glove::Decoder`]: it resynchronises on the 0xA5 sync byte
//!    after garbage, drops packets with a bad CRC-8 and counts sequence gaps.
//! 2. A pins packet sets the **commanded** state of all 80 pins; all-down lowers them all;
//!    keep-alive changes nothing.
//! 3. **Pin-rise model**: the paper's piezo cells raise a dot in 50 ms (Electronics 2025,
//!    14(18), 3658, §2: "a fast 50 ms dot rising time"), so a pin commanded up at arrival time
//!    `t` is physically up from `t + RISE_MS` on ([`VirtualGlove::physical_at`]). The paper
//!    gives no fall time; we model lowering as immediate (our choice). A pin raised and
//!    lowered again within 50 ms never reaches the finger.
//! 4. Every packet that changes a pin is logged (JSON Lines, one object per line), like the
//!    paper's app log of "the tactile signals transmitted to the haptic glove with their
//!    corresponding timestamps" (§3):
//!    `{"arrival_ms":12.345,"seq":7,"time_ms":140,"type":"pins","frame":"<20 hex>",
//!      "raised":["thumb:0:7"],"lowered":["index:0:1"],"settled_ms":62.345}`
//!    where a pin is `finger:cell:dot` and `settled_ms` = arrival + 50 ms.
//!
//! [`run_emulator_on_port`] runs it on the far end of a serial link (e.g. the second pty of a
//! socat pair), so a host `serial:` sink can be tested without hardware. The in-process
//! `emulator` sink feeds it directly.
//!
//! ## Latency
//! Decoding adds nothing beyond the packet's 16 bytes; the pin model adds [`RISE_MS`].

use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use tactus_glove::protocol::PACKET_LEN;
use tactus_glove::{Decoder, DecoderStats, Frame, Packet, PacketType, PINS};

use crate::link::Link;
use crate::TransportError;

/// Time for a commanded pin to reach "up", in ms ([`tactus_glove::PIN_RISE_MS`]).
pub const RISE_MS: f64 = tactus_glove::PIN_RISE_MS as f64;

/// One pins packet as the glove received it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReceivedFrame {
    /// Arrival time in ms since the glove started.
    pub arrival_ms: f64,
    /// The packet's sequence number.
    pub seq: u8,
    /// The packet's frame time (ms since stream start, modulo 65536).
    pub time_ms: u16,
    /// The pins it commanded.
    pub frame: Frame,
}

/// What a virtual glove saw.
#[derive(Debug, Clone, PartialEq)]
pub struct EmulatorReport {
    /// Valid packets of any type.
    pub packets: u64,
    /// Candidate packets dropped for a bad CRC.
    pub crc_errors: u64,
    /// Candidate packets with a good CRC but an unknown type / non-zero cells on a non-pins packet.
    pub malformed: u64,
    /// Packets lost according to the sequence numbers.
    pub sequence_gaps: u64,
    /// Bytes outside every valid packet.
    pub garbage_bytes: u64,
    /// All-down packets received.
    pub all_downs: u64,
    /// Keep-alive packets received.
    pub keep_alives: u64,
    /// Pin changes (one per pin that went up or down).
    pub actuations: u64,
    /// The commanded state after the last packet.
    pub final_frame: Frame,
    /// Every pins packet, in arrival order.
    pub frames: Vec<ReceivedFrame>,
}

/// `N packets (… pin frames, … all-down, … keep-alive), … CRC errors, … final frame HEX`,
/// as `tactus emulate` prints it.
impl std::fmt::Display for EmulatorReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} packets ({} pin frames, {} all-down, {} keep-alive), {} CRC errors, {} malformed, \
             {} sequence gaps, {} garbage bytes, {} pin changes; final frame {}",
            self.packets,
            self.frames.len(),
            self.all_downs,
            self.keep_alives,
            self.crc_errors,
            self.malformed,
            self.sequence_gaps,
            self.garbage_bytes,
            self.actuations,
            self.final_frame.to_hex()
        )
    }
}

impl EmulatorReport {
    /// The report as `tactus emulate` prints it on stdout; with `frames`, every received
    /// pin frame too.
    pub fn to_json(&self, frames: bool) -> serde_json::Value {
        let mut report = serde_json::json!({
            "packets": self.packets,
            "pin_frames": self.frames.len(),
            "crc_errors": self.crc_errors,
            "malformed": self.malformed,
            "sequence_gaps": self.sequence_gaps,
            "garbage_bytes": self.garbage_bytes,
            "all_downs": self.all_downs,
            "keep_alives": self.keep_alives,
            "actuations": self.actuations,
            "final_frame": self.final_frame.to_hex(),
        });
        if frames {
            report["frames"] = self
                .frames
                .iter()
                .map(|f| {
                    serde_json::json!({
                        "arrival_ms": f.arrival_ms, "seq": f.seq, "time_ms": f.time_ms, "frame": f.frame.to_hex()
                    })
                })
                .collect();
        }
        report
    }
}

/// The virtual glove (see the module docs).
pub struct VirtualGlove {
    decoder: Decoder,
    start: Instant,
    rise_ms: f64,
    commanded: Frame,
    /// Arrival time at which each pin was last commanded up (valid while it is commanded up).
    up_since: [f64; PINS],
    frames: Vec<ReceivedFrame>,
    all_downs: u64,
    keep_alives: u64,
    actuations: u64,
    log: Option<(PathBuf, BufWriter<File>)>,
    log_error: Option<String>,
}

impl VirtualGlove {
    /// A glove with all pins down whose clock starts now; `log` (if any) is
    /// created/truncated now.
    pub fn new(log: Option<&Path>, rise_ms: f64) -> Result<VirtualGlove, TransportError> {
        VirtualGlove::with_epoch(log, rise_ms, Instant::now())
    }

    /// Like [`VirtualGlove::new`], with arrival times measured from `epoch` (e.g. the start
    /// of the player's [`WallClock`](crate::WallClock), to compare send and arrival times).
    pub fn with_epoch(
        log: Option<&Path>,
        rise_ms: f64,
        epoch: Instant,
    ) -> Result<VirtualGlove, TransportError> {
        let log = match log {
            Some(p) => {
                let f = File::create(p).map_err(|source| TransportError::File {
                    path: p.to_path_buf(),
                    source,
                })?;
                Some((p.to_path_buf(), BufWriter::new(f)))
            }
            None => None,
        };
        Ok(VirtualGlove {
            decoder: Decoder::new(),
            start: epoch,
            rise_ms,
            commanded: Frame::DOWN,
            up_since: [0.0; PINS],
            frames: Vec::new(),
            all_downs: 0,
            keep_alives: 0,
            actuations: 0,
            log,
            log_error: None,
        })
    }

    /// Milliseconds since the glove started.
    pub fn now_ms(&self) -> f64 {
        self.start.elapsed().as_secs_f64() * 1e3
    }

    /// Feeds bytes that arrived now.
    pub fn push_now(&mut self, bytes: &[u8]) {
        let t = self.now_ms();
        self.push(bytes, t);
    }

    /// Feeds bytes that arrived at `arrival_ms` (ms since start, non-decreasing).
    pub fn push(&mut self, bytes: &[u8], arrival_ms: f64) {
        let mut packets: [Option<Packet>; 8] = [None; 8];
        // Decode in slices small enough that no more than 8 packets complete per slice
        // (8 * 16 = 128 bytes), so no allocation is needed.
        for chunk in bytes.chunks(8 * PACKET_LEN) {
            let mut n = 0;
            self.decoder.push(chunk, &mut |p| {
                packets[n] = Some(p);
                n += 1;
            });
            for p in packets.iter_mut().take(n) {
                if let Some(p) = p.take() {
                    self.apply(p, arrival_ms);
                }
            }
        }
    }

    fn apply(&mut self, p: Packet, arrival_ms: f64) {
        let new = match p.kind {
            PacketType::Pins => {
                self.frames.push(ReceivedFrame {
                    arrival_ms,
                    seq: p.seq,
                    time_ms: p.time_ms,
                    frame: p.frame,
                });
                p.frame
            }
            PacketType::AllDown => {
                self.all_downs += 1;
                Frame::DOWN
            }
            PacketType::KeepAlive => {
                self.keep_alives += 1;
                return;
            }
        };
        let old = self.commanded;
        if old == new {
            return;
        }
        let mut raised = Vec::new();
        let mut lowered = Vec::new();
        for (i, (o, n)) in old.pins().zip(new.pins()).enumerate() {
            if o.raised == n.raised {
                continue;
            }
            self.actuations += 1;
            let name = format!("{}:{}:{}", n.finger, n.cell, n.dot.number());
            if n.raised {
                self.up_since[i] = arrival_ms;
                raised.push(name);
            } else {
                lowered.push(name);
            }
        }
        self.commanded = new;
        if let Some((path, w)) = &mut self.log {
            let line = serde_json::json!({
                "arrival_ms": (arrival_ms * 1e3).round() / 1e3,
                "seq": p.seq,
                "time_ms": p.time_ms,
                "type": p.kind.name(),
                "frame": new.to_hex(),
                "raised": raised,
                "lowered": lowered,
                "settled_ms": ((arrival_ms + self.rise_ms) * 1e3).round() / 1e3,
            });
            if let Err(e) = writeln!(w, "{line}").and_then(|()| w.flush()) {
                self.log_error = Some(format!("{}: {e}", path.display()));
            }
        }
    }

    /// The commanded pin state (what the last packet asked for).
    pub fn commanded(&self) -> Frame {
        self.commanded
    }

    /// The physical pin state at `t_ms` (ms since start, not before the last packet): a pin
    /// is up when commanded up at least [`RISE_MS`] before `t_ms`.
    pub fn physical_at(&self, t_ms: f64) -> Frame {
        let mut f = Frame::DOWN;
        for (i, pin) in self.commanded.pins().enumerate() {
            if pin.raised && t_ms >= self.up_since[i] + self.rise_ms {
                f.0[i / 8] |= 1 << (i % 8);
            }
        }
        f
    }

    /// The decoder's counters.
    pub fn decoder_stats(&self) -> DecoderStats {
        self.decoder.stats()
    }

    /// The first error writing the actuation log, if any.
    pub fn log_error(&self) -> Option<&str> {
        self.log_error.as_deref()
    }

    /// Everything seen so far.
    pub fn report(&self) -> EmulatorReport {
        EmulatorReport {
            frames: self.frames.clone(),
            ..self.counters()
        }
    }

    /// [`VirtualGlove::report`] without the frames (cheap: no allocation).
    pub fn counters(&self) -> EmulatorReport {
        let s = self.decoder.stats();
        EmulatorReport {
            packets: s.packets,
            crc_errors: s.crc_errors,
            malformed: s.malformed,
            sequence_gaps: s.sequence_gaps,
            garbage_bytes: s.garbage_bytes,
            all_downs: self.all_downs,
            keep_alives: self.keep_alives,
            actuations: self.actuations,
            final_frame: self.commanded,
            frames: Vec::new(),
        }
    }
}

/// The wire type's name in logs ([`PacketType::name`]).
pub fn packet_type_name(kind: PacketType) -> &'static str {
    kind.name()
}

/// The in-process `emulator` sink's link.
pub(crate) struct EmulatorLink(pub(crate) Arc<Mutex<VirtualGlove>>);

impl Link for EmulatorLink {
    fn connect(&mut self) -> Result<(), crate::LinkError> {
        Ok(())
    }
    fn write(&mut self, _: &Packet, bytes: &[u8; PACKET_LEN]) -> Result<(), crate::LinkError> {
        self.0
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push_now(bytes);
        Ok(())
    }
    fn disconnect(&mut self) {}
}

/// When [`run_emulator_on_port`] stops, besides its `stop` flag.
#[derive(Debug, Clone, PartialEq)]
pub struct EmulatorOptions {
    /// Stop after this long in total; `None` runs until stopped. Default `None`.
    pub max_duration: Option<Duration>,
    /// Stop when the port has been gone (read error, hang-up, path missing) this long;
    /// meanwhile the port is re-opened every `poll`. Default 2 s.
    pub gone_timeout: Duration,
    /// Read timeout and re-open interval. Default 20 ms.
    pub poll: Duration,
    /// Pin rise time in ms. Default [`RISE_MS`].
    pub rise_ms: f64,
    /// Time zero of the arrival times; `None` = when the emulator starts.
    pub epoch: Option<Instant>,
    /// Stop once packets have arrived and then none for this long (the player has closed
    /// the link: `tactus emulate --until-idle`). Default `None`.
    pub idle_stop: Option<Duration>,
}

impl Default for EmulatorOptions {
    fn default() -> EmulatorOptions {
        EmulatorOptions {
            max_duration: None,
            gone_timeout: Duration::from_secs(2),
            poll: Duration::from_millis(20),
            rise_ms: RISE_MS,
            epoch: None,
            idle_stop: None,
        }
    }
}

fn open_port(path: &str, poll: Duration) -> serialport::Result<Box<dyn serialport::SerialPort>> {
    // No DTR/RTS changes: ptys reject them ("Not a typewriter").
    serialport::new(path, crate::DEFAULT_BAUD)
        .timeout(poll)
        .open()
}

/// Runs a virtual glove on the serial port (or pty) at `path` until `stop` is set,
/// `opts.max_duration` passes, or the port stays gone for `opts.gone_timeout` (the writer
/// went away). Re-opens the port while it is gone, so a restarted pty pair with the same
/// link names is picked up. Writes the actuation log to `log` if given.
///
/// Errors only when the port cannot be opened at the start or the log cannot be created.
pub fn run_emulator_on_port(
    path: &Path,
    log: Option<&Path>,
    stop: &AtomicBool,
    opts: &EmulatorOptions,
) -> Result<EmulatorReport, TransportError> {
    run_emulator_on_port_with(path, log, stop, opts, &mut |_, _| {})
}

/// How often [`run_emulator_on_port_with`] reports progress.
pub const PROGRESS_EVERY: Duration = Duration::from_millis(500);

/// [`run_emulator_on_port`], calling `progress(counters, port_open)` every
/// [`PROGRESS_EVERY`] ([`VirtualGlove::counters`]: no frames).
pub fn run_emulator_on_port_with(
    path: &Path,
    log: Option<&Path>,
    stop: &AtomicBool,
    opts: &EmulatorOptions,
    progress: &mut dyn FnMut(&EmulatorReport, bool),
) -> Result<EmulatorReport, TransportError> {
    let name = path.to_string_lossy().into_owned();
    let mut glove =
        VirtualGlove::with_epoch(log, opts.rise_ms, opts.epoch.unwrap_or_else(Instant::now))?;
    let mut port = Some(
        open_port(&name, opts.poll).map_err(|e| TransportError::Serial {
            path: name.clone(),
            source: e.into(),
        })?,
    );
    let started = Instant::now();
    let mut gone_since: Option<Instant> = None;
    let mut buf = [0u8; 1024];
    let mut last_progress = Instant::now();
    let mut last_packet: Option<Instant> = None;
    while !stop.load(Ordering::Relaxed) && opts.max_duration.is_none_or(|d| started.elapsed() < d) {
        if last_progress.elapsed() >= PROGRESS_EVERY {
            last_progress = Instant::now();
            progress(&glove.counters(), port.is_some());
        }
        if let (Some(idle), Some(t)) = (opts.idle_stop, last_packet) {
            if t.elapsed() >= idle {
                break;
            }
        }
        match &mut port {
            Some(p) => match p.read(&mut buf) {
                Ok(n) if n > 0 => {
                    let before = glove.decoder.stats().packets;
                    glove.push_now(&buf[..n]);
                    if glove.decoder.stats().packets > before {
                        last_packet = Some(Instant::now());
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                // Ok(0) (end of file) or a real error (EIO: the other side hung up).
                _ => {
                    port = None;
                    gone_since = Some(Instant::now());
                }
            },
            None => {
                if gone_since.is_some_and(|g| g.elapsed() >= opts.gone_timeout) {
                    break;
                }
                std::thread::sleep(opts.poll);
                if let Ok(p) = open_port(&name, opts.poll) {
                    port = Some(p);
                    gone_since = None;
                }
            }
        }
    }
    Ok(glove.report())
}
