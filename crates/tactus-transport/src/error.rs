//! Errors of the transport crate: bad sink specs, devices that cannot be opened, subsystems
//! this build lacks.

use std::path::PathBuf;

/// What can go wrong opening a sink, listing devices or running the emulator.
///
/// Link failures *after* a sink opened are not errors: the sink reconnects and reports them
/// in [`SinkStats`](crate::SinkStats).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TransportError {
    /// The `--glove SINK` text is not a valid sink.
    #[error("bad sink {spec:?}: {reason} (expected serial:PATH[@BAUD] | ble[:NAME|ADDRESS] | file:LOG.jsonl | emulator[:LOG.jsonl] | null)")]
    BadSpec {
        /// The text given.
        spec: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A file (log, recorder) could not be created or written.
    #[error("{path}: {source}")]
    File {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A serial port could not be opened or read.
    #[error("serial port {path}: {reason}")]
    Serial {
        /// The port path.
        path: String,
        /// The error.
        reason: String,
    },
    /// Bluetooth LE failed (no adapter, device not found, no 0xFFE0/0xFFE1, D-Bus down, ...).
    #[error("bluetooth: {0}")]
    Ble(String),
    /// This build lacks the cargo feature a request needs.
    #[error(
        "{what} is not in this build of tactus: rebuild it with `cargo build --release \
         --features {feature}` (see README, \"Live setup\")"
    )]
    NotBuilt {
        /// What was asked for.
        what: &'static str,
        /// The feature to enable.
        feature: &'static str,
    },
    /// The sink thread could not be started.
    #[error("cannot start the sink thread: {0}")]
    Thread(std::io::Error),
}
