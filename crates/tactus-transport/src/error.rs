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
    #[error("serial port {path}: {source}")]
    Serial {
        /// The port path.
        path: String,
        /// The error.
        #[source]
        source: LinkError,
    },
    /// Bluetooth LE failed (no adapter, device not found, no 0xFFE0/0xFFE1, D-Bus down, ...).
    #[error("bluetooth: {0}")]
    Ble(#[source] LinkError),
    /// This build lacks the cargo feature a request needs.
    #[error(
        "{what} is not in this build of tactus: rebuild it with `cargo build --release \
         --features {feature}` (see docs/install.md, \"The binary\")"
    )]
    NotBuilt {
        /// What was asked for.
        what: &'static str,
        /// The feature to enable.
        feature: &'static str,
    },
    /// The sink thread could not be started.
    #[error("cannot start the sink thread: {0}")]
    Thread(#[source] std::io::Error),
}

/// Why a link could not connect or write. After the first connection the sink thread
/// reconnects and keeps the latest one in [`SinkStats::last_error`](crate::SinkStats); the
/// first connection's failure becomes a [`TransportError`] with this as its source.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LinkError {
    /// A write before the link was opened.
    #[error("{0} not open")]
    NotOpen(&'static str),
    /// Opening a file or device failed.
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// Writing to a named file or port failed.
    #[error("{path}: {source}")]
    Write {
        /// The file or port.
        path: String,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The serial port library failed (opening, listing ports).
    #[error(transparent)]
    Serial(#[from] serialport::Error),
    /// A Bluetooth LE step failed with the BLE library's error.
    #[cfg(feature = "ble")]
    #[error("{what}: {source}")]
    Btle {
        /// The step (`connect`, `service discovery`, `BLE write`, ...).
        what: &'static str,
        /// The BLE library's error.
        #[source]
        source: btleplug::Error,
    },
    /// Bluetooth LE found nothing to connect to, or timed out (the message says which).
    #[error("{0}")]
    Ble(String),
}
