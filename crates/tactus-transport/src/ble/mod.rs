//! Bluetooth LE: the devices a scan sees ([`BleDevice`], [`list_ble_devices`]) and, with the
//! cargo feature `ble`, the sink to the glove's JDY-33 module and the scan itself (`link`).

use std::time::Duration;

use crate::TransportError;

#[cfg(feature = "ble")]
mod link;
#[cfg(feature = "ble")]
pub(crate) use link::BleLink;

/// A Bluetooth LE device seen in a scan.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BleDevice {
    /// Advertised name, if any.
    pub name: Option<String>,
    /// Address, `AA:BB:CC:DD:EE:FF`.
    pub address: String,
    /// Whether it advertises the glove's service 0xFFE0.
    pub glove_service: bool,
}

/// Scans for Bluetooth LE devices for `timeout` (feature `ble`).
///
/// Errors: no BlueZ on the system D-Bus, no adapter, or built without the `ble` feature.
pub fn list_ble_devices(timeout: Duration) -> Result<Vec<BleDevice>, TransportError> {
    #[cfg(feature = "ble")]
    {
        link::scan(timeout)
    }
    #[cfg(not(feature = "ble"))]
    {
        let _ = timeout;
        Err(TransportError::NotBuilt {
            what: "BLE scanning",
            feature: "ble",
        })
    }
}
