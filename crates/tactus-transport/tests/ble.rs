//! BLE sink against BlueZ's D-Bus API mocked by python3-dbusmock (no radio needed):
//! a private bus, the bluez5 template, an adapter, a device "HMP-Glove" with service 0xFFE0
//! and characteristic 0xFFE1. The mock's call log must show every packet's exact bytes, in
//! order. Run with `cargo test -p tactus-transport --features ble --test ble`.
//! Skips (with a printed reason) when dbus-daemon or python3-dbusmock is missing.

/// A build without the feature (CI runs this file again with it) refuses every BLE sink and
/// BLE scanning with the error that names the feature, and the message says how to rebuild.
#[cfg(not(feature = "ble"))]
#[test]
fn ble_sink_needs_the_ble_feature() {
    use std::time::Duration;
    use tactus_transport::{list_ble_devices, open_sink, SinkOptions, SinkSpec, TransportError};

    let check = |what: &str, err: TransportError| {
        assert!(
            matches!(err, TransportError::NotBuilt { feature: "ble", .. }),
            "{what}: {err:?}"
        );
        let msg = err.to_string();
        assert!(msg.contains("--features ble"), "{what}: {msg}");
    };
    for spec in ["ble", "ble:HMP-Glove", "ble:AA:BB:CC:DD:EE:FF"] {
        let spec: SinkSpec = spec.parse().unwrap();
        match open_sink(&spec, &SinkOptions::default()) {
            Ok(_) => panic!("{spec}: opened without the `ble` feature"),
            Err(e) => check(&spec.to_string(), e),
        }
    }
    check(
        "scan",
        list_ble_devices(Duration::from_millis(10)).unwrap_err(),
    );
    eprintln!(
        "ble tests not built: run `cargo test -p tactus-transport --features ble` \
         (needs libdbus-1-dev, dbus, python3-dbusmock)"
    );
}

#[cfg(feature = "ble")]
mod common;

#[cfg(feature = "ble")]
mod mock {

    use std::path::Path;
    use std::process::{Child, Command, Stdio};
    use std::time::{Duration, Instant};

    use crate::common::{pattern, skip, skip_without};
    use tactus_glove::Packet;
    use tactus_transport::{list_ble_devices, open_sink, Frame, SinkOptions, SinkSpec};

    const PYTHON: &str = "/usr/bin/python3";

    /// Adds the adapter, the glove and its GATT objects to the running mock.
    const SETUP: &str = r#"
import dbus
bus = dbus.SystemBus()
root = bus.get_object('org.bluez', '/')
bluez = dbus.Interface(root, 'org.bluez.Mock')
mock = dbus.Interface(root, 'org.freedesktop.DBus.Mock')
FFE0 = '0000ffe0-0000-1000-8000-00805f9b34fb'
FFE1 = '0000ffe1-0000-1000-8000-00805f9b34fb'
bluez.AddAdapter('hci0', 'tactus-test')
dev = bluez.AddDevice('hci0', 'AA:BB:CC:DD:EE:01', 'HMP-Glove')
bluez.AddDevice('hci0', 'AA:BB:CC:DD:EE:02', 'Other-Thing')
svc = dev + '/service0010'
mock.AddObject(svc, 'org.bluez.GattService1', {
    'UUID': FFE0, 'Primary': True, 'Device': dbus.ObjectPath(dev),
    'Includes': dbus.Array([], signature='o'), 'Handle': dbus.UInt16(16),
}, [('Dummy', '', '', '')])
ch = svc + '/char0011'
mock.AddObject(ch, 'org.bluez.GattCharacteristic1', {
    'UUID': FFE1, 'Service': dbus.ObjectPath(svc),
    'Value': dbus.Array([], signature='y'),
    'Flags': dbus.Array(['read', 'write', 'write-without-response'], signature='s'),
    'Handle': dbus.UInt16(17), 'MTU': dbus.UInt16(23), 'Notifying': False,
}, [('WriteValue', 'aya{sv}', '', ''), ('ReadValue', 'a{sv}', 'ay', 'ret = dbus.Array([], signature="y")')])
d = dbus.Interface(bus.get_object('org.bluez', dev), 'org.freedesktop.DBus.Mock')
d.UpdateProperties('org.bluez.Device1', {
    'ServicesResolved': True, 'UUIDs': dbus.Array([FFE0], signature='s'),
})
print('ok')
"#;

    struct Procs(Vec<Child>);
    impl Drop for Procs {
        fn drop(&mut self) {
            for c in self.0.iter_mut().rev() {
                let _ = c.kill();
                let _ = c.wait();
            }
        }
    }

    fn wait_for(what: &str, mut ok: impl FnMut() -> bool) {
        let t0 = Instant::now();
        while !ok() {
            assert!(
                t0.elapsed() < Duration::from_secs(10),
                "{what} did not come up"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn has_dbusmock() -> bool {
        Command::new(PYTHON)
            .args(["-c", "import dbusmock"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    }

    /// The byte vectors of every WriteValue call in the mock's log, in order.
    fn writes(log: &Path) -> Vec<Vec<u8>> {
        let text = std::fs::read_to_string(log).unwrap_or_default();
        text.lines()
            .filter_map(|l| {
                let rest = &l[l.find(" WriteValue [")? + " WriteValue [".len()..];
                let inner = &rest[..rest.find(']')?];
                Some(
                    inner
                        .split(", ")
                        .map(|x| x.trim().parse::<u8>().unwrap())
                        .collect(),
                )
            })
            .collect()
    }

    #[test]
    fn ble_sink_writes_exact_packets_in_order() {
        if skip_without("dbus-daemon", "ble_sink_writes_exact_packets_in_order") {
            return;
        }
        if !Path::new(PYTHON).exists() || !has_dbusmock() {
            skip(
                "ble_sink_writes_exact_packets_in_order: python3-dbusmock is not installed \
                 (apt-get install python3-dbusmock)",
            );
            return;
        }
        let dir = tempfile::tempdir().unwrap();
        let socket = dir.path().join("system_bus_socket");
        let address = format!("unix:path={}", socket.display());
        let log = dir.path().join("calls.log");
        let mut procs = Procs(Vec::new());
        procs.0.push(
            Command::new("dbus-daemon")
                .args(["--session", "--nofork", "--nopidfile"])
                .arg(format!("--address={address}"))
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .expect("dbus-daemon starts"),
        );
        wait_for("the private bus", || socket.exists());
        // This test binary has a single test, so setting the variable races with nothing.
        std::env::set_var("DBUS_SYSTEM_BUS_ADDRESS", &address);
        procs.0.push(
            Command::new(PYTHON)
                .args(["-m", "dbusmock", "--system", "--template", "bluez5", "-l"])
                .arg(&log)
                .stdout(Stdio::null())
                .spawn()
                .expect("dbusmock starts"),
        );
        let setup = || {
            Command::new(PYTHON)
                .args(["-c", SETUP])
                .output()
                .map(|o| String::from_utf8_lossy(&o.stdout).contains("ok"))
                .unwrap_or(false)
        };
        wait_for("the bluez mock", setup);

        // Discovery lists both devices, the glove with its service.
        let devices = list_ble_devices(Duration::from_millis(300)).unwrap();
        let glove = devices
            .iter()
            .find(|d| d.name.as_deref() == Some("HMP-Glove"))
            .expect("glove listed");
        assert_eq!(glove.address, "AA:BB:CC:DD:EE:01");
        assert!(glove.glove_service);
        assert!(devices
            .iter()
            .any(|d| d.name.as_deref() == Some("Other-Thing")));

        let opts = SinkOptions {
            keep_alive: None,
            scan_timeout: Duration::from_secs(5),
            ..SinkOptions::default()
        };
        // A name that is not there fails with a clear error after the scan timeout.
        let missing = SinkOptions {
            scan_timeout: Duration::from_millis(300),
            ..opts.clone()
        };
        let err = open_sink(&"ble:No-Such-Glove".parse().unwrap(), &missing)
            .err()
            .expect("no such device")
            .to_string();
        assert!(
            err.contains("No-Such-Glove") && err.contains("HMP-Glove"),
            "{err}"
        );

        let spec: SinkSpec = "ble:HMP-Glove".parse().unwrap();
        let sink = open_sink(&spec, &opts).unwrap();
        assert_eq!(sink.stats().mtu, Some(23), "MTU from the characteristic");
        let frames = pattern(20);
        let mut expected: Vec<Vec<u8>> = Vec::new();
        let mut seq = 0u8;
        for (k, f) in frames.iter().enumerate() {
            sink.send_frame(*f, k as u32 * 25);
            // Wait until written so that no frame is superseded and the order is exact.
            wait_for("the write", || sink.stats().frames_sent == k as u64 + 1);
            expected.push(Packet::pins(seq, k as u16 * 25, *f).encode().to_vec());
            seq = seq.wrapping_add(1);
        }
        let stats = sink.close();
        expected.push(Packet::all_down(seq, 19 * 25).encode().to_vec());
        assert_eq!(stats.frames_sent, 20);
        assert_eq!(stats.all_down_sent, 1);
        assert_eq!(stats.errors, 0, "{stats:?}");

        let got = writes(&log);
        assert_eq!(got.len(), expected.len(), "one WriteValue per packet");
        for (i, (g, e)) in got.iter().zip(&expected).enumerate() {
            assert_eq!(g, e, "packet {i}");
            assert!(g.len() <= 20, "fits one BLE write");
        }
        // The last packet lowers every pin.
        let last: [u8; 16] = got.last().unwrap().as_slice().try_into().unwrap();
        assert_eq!(Packet::decode(&last).unwrap().frame, Frame::DOWN);
        let text = std::fs::read_to_string(&log).unwrap();
        assert!(
            text.contains("\"type\": \"command\""),
            "write without response: {text}"
        );

        // Reconnect: make WriteValue fail (the link drops), then work again. The sink marks the
        // link down, reconnects (scan, connect, discover) and sends the current state.
        let sink = open_sink(&spec, &opts).unwrap();
        let set_write = |code: &str| {
            let script = format!(
            "import dbus\nbus = dbus.SystemBus()\n\
             ch = bus.get_object('org.bluez', '/org/bluez/hci0/dev_AA_BB_CC_DD_EE_01/service0010/char0011')\n\
             dbus.Interface(ch, 'org.freedesktop.DBus.Mock').AddMethod(\
             'org.bluez.GattCharacteristic1', 'WriteValue', 'aya{{sv}}', '', {code:?})\nprint('ok')"
        );
            let out = Command::new(PYTHON).args(["-c", &script]).output().unwrap();
            assert!(
                String::from_utf8_lossy(&out.stdout).contains("ok"),
                "{out:?}"
            );
        };
        sink.send_frame(frames[0], 0);
        wait_for("first write", || sink.stats().frames_sent == 1);
        set_write(
            "raise dbus.exceptions.DBusException('gone', name='org.bluez.Error.NotConnected')",
        );
        sink.send_frame(frames[1], 25);
        wait_for("the write error", || sink.stats().errors >= 1);
        for (k, f) in frames.iter().enumerate().take(6).skip(2) {
            sink.send_frame(*f, k as u32 * 25);
            std::thread::sleep(Duration::from_millis(20));
        }
        set_write("");
        wait_for("reconnect and resend", || {
            let st = sink.stats();
            st.reconnects >= 1 && st.frames_sent >= 2
        });
        let stats = sink.close();
        assert!(stats.reconnects >= 1, "{stats:?}");
        assert!(
            stats
                .last_error
                .as_deref()
                .is_some_and(|e| e.contains("gone")),
            "{stats:?}"
        );
        // The state after the reconnect is the newest frame (5), then all-down; frames 1-4 were
        // superseded or failed, never replayed as a backlog.
        let got = writes(&log);
        let tail: Vec<Packet> = got[got.len() - 2..]
            .iter()
            .map(|b| Packet::decode(b.as_slice().try_into().unwrap()).unwrap())
            .collect();
        assert_eq!(
            tail[0].frame, frames[5],
            "current state resent after reconnect"
        );
        assert_eq!(tail[1].kind, tactus_glove::PacketType::AllDown);
        eprintln!("ble reconnect: {stats:?}");

        // Link faults: five drops in one session, each recovered, and after each
        // the first packet written is the newest state (never a backlog of the frames that
        // were due while the link was down).
        const DROPS: usize = 5;
        let sink = open_sink(&spec, &opts).unwrap();
        sink.send_frame(frames[0], 0);
        wait_for("first write", || sink.stats().frames_sent == 1);
        let mut recovered = 0;
        let mut stale = 0;
        for drop in 0..DROPS {
            let before = sink.stats();
            set_write(
                "raise dbus.exceptions.DBusException('gone', name='org.bluez.Error.NotConnected')",
            );
            let t = 100 * (drop as u32 + 1);
            sink.send_frame(frames[1], t);
            wait_for("the write error", || sink.stats().errors > before.errors);
            // Frames due during the outage; only the newest may reach the glove.
            for (k, f) in frames.iter().enumerate().take(6).skip(2) {
                sink.send_frame(*f, t + k as u32);
                std::thread::sleep(Duration::from_millis(20));
            }
            let newest = frames[(drop + 7) % frames.len()];
            sink.send_frame(newest, t + 50);
            // Let the sink take the newest state; every write logged from here on (failed
            // attempts included) must carry it.
            std::thread::sleep(Duration::from_millis(100));
            let writes_before = writes(&log).len();
            set_write("");
            wait_for("reconnect and resend", || {
                let st = sink.stats();
                st.reconnects > before.reconnects && st.frames_sent > before.frames_sent
            });
            recovered += 1;
            let got = writes(&log);
            let after: Vec<Packet> = got[writes_before..]
                .iter()
                .filter_map(|b| Packet::decode(b.as_slice().try_into().ok()?).ok())
                .filter(|p| p.kind == tactus_glove::PacketType::Pins)
                .collect();
            assert!(!after.is_empty());
            stale += after.iter().filter(|p| p.frame != newest).count();
        }
        let stats = sink.close();
        eprintln!(
            "{DROPS} BLE drops: recovered {recovered}, stale packets after reconnects {stale}, {stats:?}"
        );
        assert_eq!(recovered, DROPS);
        assert_eq!(stale, 0, "a stale frame was delivered after a reconnect");
        assert!(stats.reconnects >= DROPS as u64, "{stats:?}");
    }
}
