//! The `ble[:NAME|ADDRESS]` sink (cargo feature `ble`): the glove's JDY-33 module over
//! Bluetooth LE, through btleplug (BlueZ over D-Bus on Linux; needs libdbus-1-dev to build).
//!
//! ## Algorithm
//! 1. Take the first adapter; scan (no filter) for up to [`SinkOptions::scan_timeout`]
//!    (default 10 s), polling the peripherals every 100 ms, until one matches: the exact
//!    advertised name, the address, or (plain `ble`) any device advertising service 0xFFE0.
//! 2. Connect, discover services, find characteristic 0xFFE1 of service 0xFFE0 (the JDY-33's
//!    transparent UART characteristic).
//! 3. Write each 16-byte packet as one write *without response* (≤ 20 bytes, so it fits the
//!    default ATT MTU of 23 with its 3-byte header). The MTU btleplug reports is published in
//!    [`SinkStats::mtu`](crate::SinkStats::mtu).
//! 4. A write error or time-out (500 ms) marks the link down; the sink thread reconnects
//!    with backoff (the whole of 1–2 again, with a shorter 2 s scan).
//!
//! A current-thread tokio runtime lives inside the sink thread; nothing async leaks out.
//! Latency: one connection interval (7.5–30 ms, typically 15 ms) per packet.
//!
//! [`SinkOptions::scan_timeout`]: crate::SinkOptions::scan_timeout

use std::time::Duration;

use btleplug::api::bleuuid::uuid_from_u16;
use btleplug::api::{
    Central, Characteristic, Manager as _, Peripheral as _, ScanFilter, WriteType,
};
use btleplug::platform::{Adapter, Manager, Peripheral};
use tactus_glove::protocol::PACKET_LEN;
use tactus_glove::Packet;
use tokio::runtime::Runtime;
use uuid::Uuid;

use super::BleDevice;
use crate::link::Link;
use crate::spec::BleTarget;
use crate::{LinkError, TransportError};

/// GATT service of the JDY-33 module.
pub(crate) const SERVICE: Uuid = uuid_from_u16(0xFFE0);
/// Its write characteristic.
pub(crate) const CHARACTERISTIC: Uuid = uuid_from_u16(0xFFE1);
const WRITE_TIMEOUT: Duration = Duration::from_millis(500);
const RESCAN_TIMEOUT: Duration = Duration::from_secs(2);

fn runtime() -> Result<Runtime, TransportError> {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(|e| {
            TransportError::Ble(LinkError::Ble(format!(
                "cannot start the async runtime: {e}"
            )))
        })
}

async fn first_adapter() -> Result<Adapter, LinkError> {
    let manager = Manager::new()
        .await
        .map_err(|e| LinkError::Ble(format!("no BlueZ on the system D-Bus ({e})")))?;
    manager
        .adapters()
        .await
        .map_err(|source| LinkError::Btle {
            what: "cannot list adapters",
            source,
        })?
        .into_iter()
        .next()
        .ok_or_else(|| LinkError::Ble("no Bluetooth adapter".into()))
}

async fn describe(p: &Peripheral) -> Option<BleDevice> {
    let props = p.properties().await.ok()??;
    Some(BleDevice {
        name: props.local_name.or(props.advertisement_name),
        address: props.address.to_string().to_ascii_uppercase(),
        glove_service: props.services.contains(&SERVICE),
    })
}

fn matches(target: &BleTarget, d: &BleDevice) -> bool {
    match target {
        BleTarget::Any => d.glove_service,
        BleTarget::Name(n) => d.name.as_deref() == Some(n.as_str()),
        BleTarget::Address(a) => d.address.eq_ignore_ascii_case(a),
    }
}

async fn find(
    adapter: &Adapter,
    target: &BleTarget,
    timeout: Duration,
) -> Result<Peripheral, LinkError> {
    adapter
        .start_scan(ScanFilter::default())
        .await
        .map_err(|source| LinkError::Btle {
            what: "cannot scan",
            source,
        })?;
    let deadline = tokio::time::Instant::now() + timeout;
    let mut seen = Vec::new();
    let found = loop {
        seen.clear();
        let mut hit = None;
        let peripherals = adapter
            .peripherals()
            .await
            .map_err(|source| LinkError::Btle {
                what: "cannot list devices",
                source,
            })?;
        for p in peripherals {
            if let Some(d) = describe(&p).await {
                if matches(target, &d) {
                    hit = Some(p);
                    break;
                }
                seen.push(d.name.unwrap_or(d.address));
            }
        }
        if hit.is_some() || tokio::time::Instant::now() >= deadline {
            break hit;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    let _ = adapter.stop_scan().await;
    found.ok_or_else(|| {
        let what = match target {
            BleTarget::Any => "no device with service 0xFFE0".to_string(),
            BleTarget::Name(n) => format!("no device named {n:?}"),
            BleTarget::Address(a) => format!("no device at {a}"),
        };
        LinkError::Ble(format!(
            "{what} found within {:.1} s (seen: {})",
            timeout.as_secs_f64(),
            if seen.is_empty() {
                "none".to_string()
            } else {
                seen.join(", ")
            }
        ))
    })
}

async fn connect(
    target: &BleTarget,
    timeout: Duration,
) -> Result<(Peripheral, Characteristic), LinkError> {
    let adapter = first_adapter().await?;
    let p = find(&adapter, target, timeout).await?;
    if !p.is_connected().await.unwrap_or(false) {
        p.connect().await.map_err(|source| LinkError::Btle {
            what: "connect",
            source,
        })?;
    }
    p.discover_services()
        .await
        .map_err(|source| LinkError::Btle {
            what: "service discovery",
            source,
        })?;
    let ch = p
        .characteristics()
        .into_iter()
        .find(|c| c.uuid == CHARACTERISTIC && c.service_uuid == SERVICE)
        .ok_or_else(|| {
            LinkError::Ble("device has no characteristic 0xFFE1 in service 0xFFE0".into())
        })?;
    Ok((p, ch))
}

pub(crate) struct BleLink {
    target: BleTarget,
    scan_timeout: Duration,
    rt: Runtime,
    conn: Option<(Peripheral, Characteristic)>,
    connected_once: bool,
}

impl BleLink {
    pub(crate) fn new(
        target: BleTarget,
        scan_timeout: Duration,
    ) -> Result<BleLink, TransportError> {
        Ok(BleLink {
            target,
            scan_timeout,
            rt: runtime()?,
            conn: None,
            connected_once: false,
        })
    }
}

impl Link for BleLink {
    fn connect(&mut self) -> Result<(), LinkError> {
        let timeout = if self.connected_once {
            RESCAN_TIMEOUT.min(self.scan_timeout)
        } else {
            self.scan_timeout
        };
        let conn = self.rt.block_on(connect(&self.target, timeout))?;
        self.conn = Some(conn);
        self.connected_once = true;
        Ok(())
    }

    fn write(&mut self, _: &Packet, bytes: &[u8; PACKET_LEN]) -> Result<(), LinkError> {
        let (p, ch) = self
            .conn
            .as_ref()
            .ok_or(LinkError::NotOpen("BLE connection"))?;
        self.rt
            .block_on(async {
                tokio::time::timeout(
                    WRITE_TIMEOUT,
                    p.write(ch, bytes, WriteType::WithoutResponse),
                )
                .await
            })
            .map_err(|_| LinkError::Ble("BLE write timed out".into()))?
            .map_err(|source| LinkError::Btle {
                what: "BLE write",
                source,
            })
    }

    fn disconnect(&mut self) {
        if let Some((p, _)) = self.conn.take() {
            let _ = self.rt.block_on(async {
                tokio::time::timeout(Duration::from_secs(1), p.disconnect()).await
            });
        }
    }

    fn mtu(&self) -> Option<u16> {
        self.conn.as_ref().map(|(p, _)| p.mtu())
    }
}

/// Scans for `timeout` and lists every device seen.
pub(crate) fn scan(timeout: Duration) -> Result<Vec<BleDevice>, TransportError> {
    runtime()?.block_on(async {
        let adapter = first_adapter().await.map_err(TransportError::Ble)?;
        adapter
            .start_scan(ScanFilter::default())
            .await
            .map_err(|source| {
                TransportError::Ble(LinkError::Btle {
                    what: "cannot scan",
                    source,
                })
            })?;
        tokio::time::sleep(timeout).await;
        let mut out = Vec::new();
        for p in adapter.peripherals().await.map_err(|source| {
            TransportError::Ble(LinkError::Btle {
                what: "cannot list devices",
                source,
            })
        })? {
            if let Some(d) = describe(&p).await {
                out.push(d);
            }
        }
        let _ = adapter.stop_scan().await;
        Ok(out)
    })
}
