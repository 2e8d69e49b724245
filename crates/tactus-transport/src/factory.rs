//! The factory: opens the link a [`SinkSpec`] names and starts its sink thread.

use std::sync::{Arc, Mutex};

use crate::emulator::VirtualGlove;
use crate::link::Link;
use crate::sink::{SinkHandle, SinkOptions};
use crate::spec::SinkSpec;
use crate::TransportError;

/// Opens the sink named by `spec`: starts its thread and makes the first connection.
///
/// Errors when the first connection fails (no such port, BLE device not found within
/// [`SinkOptions::scan_timeout`], log file not creatable) or the spec needs a cargo
/// feature this build lacks. Later link failures are handled by reconnecting.
pub fn open_sink(spec: &SinkSpec, opts: &SinkOptions) -> Result<SinkHandle, TransportError> {
    let mut glove = None;
    let link: Box<dyn Link> = match spec {
        SinkSpec::Null => Box::new(crate::null::NullLink),
        SinkSpec::File(path) => Box::new(crate::file::FileLink::new(path.clone())),
        SinkSpec::Emulator(log) => {
            let g = Arc::new(Mutex::new(VirtualGlove::new(
                log.as_deref(),
                f64::from(tactus_glove::PIN_RISE_MS),
            )?));
            glove = Some(Arc::clone(&g));
            Box::new(crate::emulator::EmulatorLink(g))
        }
        SinkSpec::Serial { path, baud } => {
            Box::new(crate::serial::SerialLink::new(path.clone(), *baud))
        }
        #[cfg(feature = "ble")]
        SinkSpec::Ble(target) => {
            Box::new(crate::ble::BleLink::new(target.clone(), opts.scan_timeout)?)
        }
        #[cfg(not(feature = "ble"))]
        SinkSpec::Ble(_) => {
            return Err(TransportError::NotBuilt {
                what: "the ble sink",
                feature: "ble",
            })
        }
    };
    match crate::sink::start(link, glove, spec, opts)? {
        Ok(handle) => Ok(handle),
        Err(reason) => Err(connect_error(spec, reason)),
    }
}
/// The error for a failed first connection of `spec`.
fn connect_error(spec: &SinkSpec, reason: crate::LinkError) -> TransportError {
    match (spec, reason) {
        (SinkSpec::Serial { path, .. }, source) => TransportError::Serial {
            path: path.clone(),
            source,
        },
        (SinkSpec::File(path) | SinkSpec::Emulator(Some(path)), reason) => TransportError::File {
            path: path.clone(),
            source: match reason {
                crate::LinkError::Io(e) => e,
                other => std::io::Error::other(other),
            },
        },
        (_, reason) => TransportError::Ble(reason),
    }
}
