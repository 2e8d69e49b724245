//! The `serial:PATH[@BAUD]` sink: the 16-byte wire packets on a UART (the glove's USB-serial
//! or the JDY-33's UART side), through the [`serialport`] crate.
//!
//! * 8N1, no flow control, default 115200 baud ([`crate::DEFAULT_BAUD`]).
//! * DTR, RTS and CTS are never touched: pseudo-terminals reject those ioctls ("Not a
//!   typewriter") and the glove does not use them.
//! * Writes time out after 200 ms; a timeout, a write error or a hang-up marks the link down
//!   and the sink reconnects with backoff (see [`crate::sink`]).
//! * Latency: 16 bytes × 10 bits / 115200 baud = 1.4 ms on the wire.
//!
//! [`list_serial_ports`] enumerates ports. With the cargo feature `udev` it uses libudev
//! (USB vendor/product details); without it, it scans `/sys/class/tty` (Linux), which needs
//! no system library. Pseudo-terminals are never listed: give their path explicitly.

use std::io::Write as _;
use std::time::Duration;

use tactus_glove::protocol::PACKET_LEN;
use tactus_glove::Packet;

use crate::link::Link;
use crate::LinkError;
use crate::TransportError;

/// How long one packet write may take before the link counts as stuck.
pub const WRITE_TIMEOUT: Duration = Duration::from_millis(200);

pub(crate) struct SerialLink {
    path: String,
    baud: u32,
    port: Option<Box<dyn serialport::SerialPort>>,
}

impl SerialLink {
    pub(crate) fn new(path: String, baud: u32) -> SerialLink {
        SerialLink {
            path,
            baud,
            port: None,
        }
    }
}

impl Link for SerialLink {
    fn connect(&mut self) -> Result<(), LinkError> {
        let port = serialport::new(&self.path, self.baud)
            .timeout(WRITE_TIMEOUT)
            .open()?;
        self.port = Some(port);
        Ok(())
    }

    fn write(&mut self, _: &Packet, bytes: &[u8; PACKET_LEN]) -> Result<(), LinkError> {
        let port = self.port.as_mut().ok_or(LinkError::NotOpen("port"))?;
        // No flush(): on a tty it is tcdrain(), which waits for the far end (on a pty, for
        // socat to be scheduled) and would stall the sink; write() hands the 16 bytes to the
        // kernel, which is all latest-state sending needs.
        port.write_all(bytes).map_err(|source| LinkError::Write {
            path: self.path.clone(),
            source,
        })
    }

    fn disconnect(&mut self) {
        self.port = None;
    }
}

/// One serial port found by [`list_serial_ports`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SerialPortEntry {
    /// Device path, usable as `serial:PATH`.
    pub path: String,
    /// What the system says it is (USB ids and product with the `udev` feature).
    pub description: String,
}

/// Lists the serial ports of this machine (see the module docs). Never panics; a machine
/// without `/sys/class/tty` or without ports gives an empty list.
pub fn list_serial_ports() -> Result<Vec<SerialPortEntry>, TransportError> {
    #[cfg(all(target_os = "linux", not(feature = "udev")))]
    if !std::path::Path::new("/sys/class/tty").is_dir() {
        // serialport's sysfs scan would panic without it.
        return Ok(Vec::new());
    }
    let ports = serialport::available_ports().map_err(|e| TransportError::Serial {
        path: "(enumeration)".into(),
        source: e.into(),
    })?;
    Ok(ports
        .into_iter()
        .map(|p| SerialPortEntry {
            path: p.port_name,
            description: describe(&p.port_type),
        })
        .collect())
}

fn describe(t: &serialport::SerialPortType) -> String {
    match t {
        serialport::SerialPortType::UsbPort(u) => {
            let mut s = format!("USB {:04x}:{:04x}", u.vid, u.pid);
            for part in [&u.manufacturer, &u.product, &u.serial_number]
                .into_iter()
                .flatten()
            {
                s.push(' ');
                s.push_str(part);
            }
            s
        }
        serialport::SerialPortType::BluetoothPort => "Bluetooth RFCOMM".into(),
        serialport::SerialPortType::PciPort => "PCI".into(),
        serialport::SerialPortType::Unknown => "unknown".into(),
    }
}
