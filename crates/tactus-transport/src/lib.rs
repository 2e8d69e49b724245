//! # tactus-transport: getting frames to the glove
//!
//! A [`Sink`](sink) is where the 80-pin [`Frame`]s go: a serial UART, a Bluetooth LE
//! module (JDY-33, feature `ble`), a JSON Lines recorder, the in-process virtual glove
//! ([`emulator`]) or nowhere ([`SinkSpec::Null`]). Every sink speaks wire protocol v1
//! ([`tactus_glove::protocol`]) and runs on its own thread, fed through a bounded
//! command mailbox with *latest-state* semantics: the producer never blocks, a slow or dead
//! link never builds a backlog, and after a reconnect the sink sends the current full state.
//!
//! | module | what |
//! |---|---|
//! | [`spec`] | [`SinkSpec`]: the `--glove SINK` syntax (`serial:PATH[@BAUD]`, `ble[:NAME]`, ...) |
//! | [`factory`] | [`open_sink`]: the link a spec names, started on its sink thread |
//! | [`sink`] | [`SinkHandle`], [`SinkCommand`], [`SinkStats`], reconnect with exponential backoff |
//! | [`serial`] | the UART sink ([`serialport`], no DTR/RTS/CTS), [`list_serial_ports`] |
//! | `ble` | [`BleDevice`], [`list_ble_devices`]; the BLE sink (feature `ble`: btleplug over BlueZ/D-Bus) |
//! | [`file`](mod@file) | the JSON Lines recorder sink |
//! | [`emulator`] | [`VirtualGlove`]: decoder + 50 ms pin-rise model + actuation log; [`run_emulator_on_port`] |
//! | [`clock`] | [`Clock`]: [`WallClock`], [`FakeClock`] (the audio clock lives with the device) |
//! | [`player`] | the one scheduler [`schedule`] (and [`play_frames`] for a pattern): clocked, early sending, Ctrl-C safety |
//! | [`devices`] | [`devices_report`]: what `tactus devices` prints |
//!
//! ## Tutorial
//!
//! ```
//! use std::sync::atomic::AtomicBool;
//! use tactus_glove::Frame;
//! use tactus_transport::{open_sink, play_frames, SinkOptions, SinkSpec, WallClock};
//!
//! // The virtual glove, in process: it decodes the bytes like the real glove would.
//! let spec: SinkSpec = "emulator".parse().unwrap();
//! let sink = open_sink(&spec, &SinkOptions::default()).unwrap();
//! let frames = vec![Frame([1, 0, 0, 0, 0, 0, 0, 0, 0, 0]), Frame([0, 0, 0xff, 0, 0, 0, 0, 0, 0, 0])];
//! let stop = AtomicBool::new(false);
//! let report = play_frames(&frames, 5, &sink, &WallClock::new(), 0, &stop, &mut |_| {});
//! assert_eq!(report.frames_sent, 2);
//! let glove = sink.virtual_glove().unwrap();
//! let stats = sink.close(); // sends all-pins-down, joins the sink thread
//! // Two frames and the all-down; latest-state semantics: a frame the link had not written
//! // yet when the next one came (a busy machine) is superseded and counted as dropped.
//! assert_eq!(stats.sent + stats.dropped, 3);
//! let glove = glove.lock().unwrap();
//! assert_eq!(glove.commanded(), Frame::DOWN);
//! assert_eq!(glove.report().frames.len() as u64, stats.sent - 1); // pins packets
//! ```
#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod ble;
pub mod clock;
pub mod devices;
pub mod emulator;
mod error;
pub mod factory;
pub mod file;
mod link;
mod null;
pub mod player;
pub mod serial;
pub mod sink;
pub mod spec;

pub use clock::{Clock, FakeClock, WallClock};
pub use devices::{devices_report, list_ble_devices, BleDevice};
pub use emulator::{run_emulator_on_port, EmulatorOptions, EmulatorReport, VirtualGlove};
pub use error::{LinkError, TransportError};
pub use factory::open_sink;
pub use player::{
    lead_ms, play_frames, schedule, FrameSource, PlayReport, PlayStatus, ScheduleError, Slot,
    Timing,
};
pub use serial::{list_serial_ports, SerialPortEntry};
pub use sink::{SinkCommand, SinkHandle, SinkOptions, SinkStats};
pub use spec::{SinkSpec, DEFAULT_BAUD};
pub use tactus_glove::Frame;
