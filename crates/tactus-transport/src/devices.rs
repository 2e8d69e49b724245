//! Device discovery for `tactus devices`: serial ports and BLE devices, each degrading to a
//! one-line note when its subsystem is missing or not built in.

use std::fmt::Write as _;
use std::time::Duration;

pub use crate::ble::{list_ble_devices, BleDevice};
use crate::serial::list_serial_ports;

/// The text `tactus devices` prints: serial ports, then BLE devices (scanning for
/// `ble_timeout`), each with the `--glove` spec that selects it, or a note why none can be
/// listed.
pub fn devices_report(ble_timeout: Duration) -> String {
    let mut out = String::new();
    out.push_str("Serial ports:\n");
    match list_serial_ports() {
        Ok(ports) if ports.is_empty() => {
            out.push_str("  (none found; pseudo-terminals are never listed, pass serial:PATH)\n")
        }
        Ok(ports) => {
            for p in ports {
                let _ = writeln!(out, "  --glove serial:{}   {}", p.path, p.description);
            }
        }
        Err(e) => {
            let _ = writeln!(out, "  (cannot list: {e})");
        }
    }
    if !cfg!(feature = "udev") {
        out.push_str(
            "  note: no USB details in this build (rebuild with `--features udev` for them)\n",
        );
    }
    out.push_str("Bluetooth LE devices:\n");
    match list_ble_devices(ble_timeout) {
        Ok(devs) if devs.is_empty() => out.push_str("  (none seen)\n"),
        Ok(devs) => {
            for d in devs {
                let target = d.name.clone().unwrap_or_else(|| d.address.clone());
                let _ = writeln!(
                    out,
                    "  --glove ble:{target}   {}{}",
                    d.address,
                    if d.glove_service {
                        "  [service 0xFFE0]"
                    } else {
                        ""
                    }
                );
            }
        }
        Err(e) => {
            let _ = writeln!(out, "  (unavailable: {e})");
        }
    }
    out
}
