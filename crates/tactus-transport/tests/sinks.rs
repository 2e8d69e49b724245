//! In-process sinks (file, null, emulator), all-down on close and drop, the virtual glove's
//! robustness to corrupted input and its pin-rise model, and the player's stop path.

mod common;

use std::sync::atomic::AtomicBool;
use std::time::Duration;

use common::pattern;
use tactus_glove::{Packet, PacketType};
use tactus_transport::emulator::{VirtualGlove, RISE_MS};
use tactus_transport::{open_sink, play_frames, Frame, SinkOptions, SinkSpec, WallClock};

fn quiet() -> SinkOptions {
    SinkOptions {
        keep_alive: None,
        ..SinkOptions::default()
    }
}

/// Tiny deterministic generator (xorshift64*), so the corruption test is reproducible.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
}

#[test]
fn file_sink_writes_valid_json_lines() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("glove.jsonl");
    let spec: SinkSpec = format!("file:{}", path.display()).parse().unwrap();
    let frames = pattern(30);
    let sink = open_sink(&spec, &quiet()).unwrap();
    let stop = AtomicBool::new(false);
    play_frames(&frames, 5, &sink, &WallClock::new(), 0, &stop, &mut |_| {});
    let stats = sink.close();
    assert_eq!(stats.frames_sent + stats.dropped, 30, "{stats:?}");

    let text = std::fs::read_to_string(&path).unwrap();
    let lines: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).expect("each line is one JSON object"))
        .collect();
    assert_eq!(lines.len() as u64, stats.sent);
    let mut last_mono = -1.0;
    let mut frame_index = 0;
    for (i, v) in lines.iter().enumerate() {
        assert_eq!(
            v["seq"].as_u64().unwrap(),
            i as u64,
            "consecutive sequence numbers"
        );
        let mono = v["mono_ms"].as_f64().unwrap();
        assert!(mono >= last_mono, "monotonic send timestamps");
        last_mono = mono;
        assert!(
            v["wall_ms"].as_u64().unwrap() > 1_600_000_000_000,
            "wall clock in ms"
        );
        // The recorded bytes are exactly the encoded packet (independent re-encode).
        let bytes = hex_bytes(v["bytes"].as_str().unwrap());
        let packet = Packet::decode(bytes.as_slice().try_into().unwrap()).unwrap();
        assert_eq!(packet.seq as u64, i as u64);
        assert_eq!(u64::from(packet.time_ms), v["time_ms"].as_u64().unwrap());
        assert_eq!(packet.frame.to_hex(), v["frame"].as_str().unwrap());
        match v["type"].as_str().unwrap() {
            "pins" => {
                assert_eq!(packet.kind, PacketType::Pins);
                // Frames appear in order (some may be superseded if the thread lagged).
                let k = frames[frame_index..]
                    .iter()
                    .position(|f| *f == packet.frame)
                    .unwrap();
                frame_index += k + 1;
                assert_eq!(u32::from(packet.time_ms), (frame_index as u32 - 1) * 5);
            }
            "all_down" => {
                assert_eq!(packet.kind, PacketType::AllDown);
                assert_eq!(i, lines.len() - 1, "all-down is last");
            }
            other => panic!("unexpected type {other}"),
        }
    }
    assert_eq!(stats.all_down_sent, 1);
}

fn hex_bytes(s: &str) -> Vec<u8> {
    (0..s.len() / 2)
        .map(|i| u8::from_str_radix(&s[2 * i..2 * i + 2], 16).unwrap())
        .collect()
}

#[test]
fn null_sink_counts() {
    let sink = open_sink(&SinkSpec::Null, &quiet()).unwrap();
    for (k, f) in pattern(50).into_iter().enumerate() {
        sink.send_frame(f, k as u32 * 10);
        // Give the thread a chance to write each one (it may also supersede some).
        std::thread::sleep(Duration::from_millis(1));
    }
    let stats = sink.close();
    assert_eq!(stats.frames_sent + stats.dropped, 50, "{stats:?}");
    assert!(stats.frames_sent >= 1);
    assert_eq!(stats.all_down_sent, 1);
    assert_eq!(stats.sent, stats.frames_sent + 1);
    assert!(!stats.link_up, "closed");
}

/// The terminal view: the stats show the state the last packet written put on
/// the glove, and its frame time.
#[test]
fn stats_show_what_the_last_packet_put_on_the_glove() {
    let sink = open_sink(&SinkSpec::Null, &quiet()).unwrap();
    assert_eq!(sink.stats().shown, Frame::DOWN);
    let frames = pattern(5);
    for (k, f) in frames.iter().enumerate() {
        sink.send_frame(*f, 100 * k as u32 + 7);
        let t0 = std::time::Instant::now();
        while sink.stats().shown_time_ms != 100 * k as u32 + 7 {
            assert!(
                t0.elapsed() < Duration::from_secs(5),
                "frame {k} never written"
            );
            std::thread::sleep(Duration::from_millis(1));
        }
        assert_eq!(sink.stats().shown, *f);
    }
    let stats = sink.close();
    assert_eq!(stats.shown, Frame::DOWN, "closing lowers every pin");
}

#[test]
fn superseded_frames_are_dropped_not_queued() {
    // 1000 frames handed over back to back: the sink never queues more than one pending
    // state, so every frame is either written or counted as dropped, and the last written
    // frame is the newest one.
    let sink = open_sink(&SinkSpec::Emulator(None), &quiet()).unwrap();
    let frames = pattern(1000);
    for (k, f) in frames.iter().enumerate() {
        sink.send_frame(*f, k as u32);
    }
    let glove = sink.virtual_glove().unwrap();
    // The newest state is delivered (nothing waits behind the pending slot).
    let t0 = std::time::Instant::now();
    while glove.lock().unwrap().commanded() != frames[999] {
        assert!(
            t0.elapsed() < Duration::from_secs(5),
            "newest frame never delivered"
        );
        std::thread::sleep(Duration::from_millis(1));
    }
    let stats = sink.close();
    assert_eq!(stats.frames_sent + stats.dropped, 1000, "{stats:?}");
    let g = glove.lock().unwrap();
    let r = g.report();
    assert_eq!(r.frames.len() as u64, stats.frames_sent);
    assert_eq!(r.frames.last().unwrap().frame, frames[999]);
    assert!(r.frames.windows(2).all(|w| w[0].time_ms < w[1].time_ms));
    assert_eq!(
        r.sequence_gaps, 0,
        "sequence numbers count written packets only"
    );
    assert_eq!(r.final_frame, Frame::DOWN);
}

#[test]
fn all_down_on_close_and_on_drop() {
    let up = Frame([0xff; 10]);
    for close in [true, false] {
        let sink = open_sink(&SinkSpec::Emulator(None), &quiet()).unwrap();
        sink.send_frame(up, 0);
        let glove = sink.virtual_glove().unwrap();
        // Wait until the frame is on the glove.
        while glove.lock().unwrap().commanded() != up {
            std::thread::sleep(Duration::from_millis(1));
        }
        if close {
            let stats = sink.close();
            assert_eq!(stats.all_down_sent, 1);
        } else {
            drop(sink);
        }
        let g = glove.lock().unwrap();
        assert_eq!(g.commanded(), Frame::DOWN, "close={close}");
        assert_eq!(g.report().all_downs, 1, "close={close}");
    }
}

#[test]
fn player_stop_sends_all_down() {
    let sink = open_sink(&SinkSpec::Emulator(None), &quiet()).unwrap();
    let stop = AtomicBool::new(false);
    let frames = vec![Frame([0xff; 10]); 100];
    let report = play_frames(&frames, 10, &sink, &WallClock::new(), 0, &stop, &mut |s| {
        if s.frame_index == 5 {
            stop.store(true, std::sync::atomic::Ordering::Relaxed);
        }
    });
    assert!(report.stopped);
    assert_eq!(report.frames_sent, 6);
    let glove = sink.virtual_glove().unwrap();
    let stats = sink.close();
    assert_eq!(stats.all_down_sent, 1, "exactly one all-down: {stats:?}");
    assert_eq!(glove.lock().unwrap().commanded(), Frame::DOWN);
}

#[test]
fn player_sends_early_by_the_offset() {
    // offset 30 ms at 10 ms bins: frames 0..=3 are due at or before t = 0 and go at once;
    // frame k > 3 is due at 10k - 30 ms.
    let sink = open_sink(&SinkSpec::Null, &quiet()).unwrap();
    let stop = AtomicBool::new(false);
    let clock = WallClock::new();
    let mut sent_at = Vec::new();
    let report = play_frames(&pattern(10), 10, &sink, &clock, 30, &stop, &mut |s| {
        sent_at.push(s.clock_ms)
    });
    sink.close();
    assert_eq!(report.frames_sent, 10);
    for (k, t) in sent_at.iter().enumerate() {
        let due = (k as f64 * 10.0 - 30.0).max(0.0);
        assert!(*t >= due, "frame {k} sent at {t} before {due}");
    }
    // All-down at the end of the song minus the offset: 100 - 30 = 70 ms.
    assert!(report.end_ms >= 70.0);
}

#[test]
fn corrupted_stream_drops_bad_packets_and_keeps_going() {
    // Valid packets with random garbage between them, and some packets with one flipped bit.
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let frames = pattern(150);
    let mut stream = Vec::new();
    let mut garbage = 0u64;
    let mut flipped = Vec::new();
    let mut expected = Vec::new();
    let mut seq = 0u8;
    for (k, f) in frames.iter().enumerate() {
        let mut bytes = Packet::pins(seq, k as u16 * 20, *f).encode();
        seq = seq.wrapping_add(1);
        if rng.next() % 5 < 1 {
            // One flipped bit in bytes 1..=15: CRC-8 detects every single-bit error.
            let byte = 1 + (rng.next() % 15) as usize;
            bytes[byte] ^= 1 << (rng.next() % 8);
            flipped.push(k);
        } else {
            expected.push(k);
        }
        stream.extend_from_slice(&bytes);
        let n = rng.next() % 24;
        for _ in 0..n {
            // Garbage rich in sync bytes, to exercise resynchronisation.
            let b = if rng.next() % 4 < 1 {
                0xA5
            } else {
                rng.next() as u8
            };
            stream.push(b);
            garbage += 1;
        }
    }
    let mut glove = VirtualGlove::new(None, RISE_MS).unwrap();
    // Feed in random chunk sizes, like a UART would deliver.
    let mut i = 0;
    while i < stream.len() {
        let n = (1 + rng.next() % 40) as usize;
        let end = (i + n).min(stream.len());
        glove.push(&stream[i..end], i as f64);
        i = end;
    }
    let r = glove.report();
    let got: Vec<Frame> = r.frames.iter().map(|x| x.frame).collect();
    let want: Vec<Frame> = expected.iter().map(|&k| frames[k]).collect();
    // Garbage could in principle forge a packet (CRC-8 passes 1 in 256 random candidates);
    // require every valid packet, in order, and nothing else.
    assert_eq!(got, want, "every intact packet recovered, in order");
    assert!(
        r.crc_errors + r.malformed >= flipped.len() as u64,
        "every corrupted packet rejected and counted: {} < {}",
        r.crc_errors + r.malformed,
        flipped.len()
    );
    assert!(!flipped.is_empty());
    // Lost packets show up as sequence gaps: exactly the corrupted ones between the first
    // and the last intact packet.
    let (first, last) = (expected[0], *expected.last().unwrap());
    let inside = flipped.iter().filter(|&&k| first < k && k < last).count() as u64;
    assert_eq!(r.sequence_gaps, inside);
    // Byte accounting: 16 per accepted packet + garbage (noise + rejected) = everything fed.
    assert_eq!(
        16 * r.packets + r.garbage_bytes + glove_pending(&r, &stream),
        stream.len() as u64
    );
    assert!(r.garbage_bytes >= garbage);
    eprintln!(
        "corruption: {} packets ok, {} corrupted, crc_errors {}, malformed {}, garbage bytes {} (noise {})",
        r.packets,
        flipped.len(),
        r.crc_errors,
        r.malformed,
        r.garbage_bytes,
        garbage
    );
}

/// Bytes the decoder still holds: everything not accounted for (at most 15).
fn glove_pending(r: &tactus_transport::EmulatorReport, stream: &[u8]) -> u64 {
    let pending = stream.len() as u64 - 16 * r.packets - r.garbage_bytes;
    assert!(pending < 16);
    pending
}

#[test]
fn pin_rise_model_takes_50_ms() {
    let mut g = VirtualGlove::new(None, RISE_MS).unwrap();
    let mut f = Frame::DOWN;
    f.0[0] = 0b0000_0001;
    g.push(&Packet::pins(0, 0, f).encode(), 100.0);
    assert_eq!(g.physical_at(149.9), Frame::DOWN, "not up before 50 ms");
    assert_eq!(g.physical_at(150.0), f, "up at 50 ms");
    // A second pin raised later rises on its own schedule; the first stays up.
    let mut f2 = f;
    f2.0[9] = 0x80;
    g.push(&Packet::pins(1, 20, f2).encode(), 160.0);
    assert_eq!(g.physical_at(170.0), f);
    assert_eq!(g.physical_at(210.0), f2);
    // Lowering is immediate.
    g.push(&Packet::all_down(2, 40).encode(), 220.0);
    assert_eq!(g.physical_at(220.0), Frame::DOWN);
    assert_eq!(g.report().actuations, 4);
}

#[test]
fn devices_report_degrades_gracefully() {
    // No Bluetooth daemon here (or no `ble` feature): the report still lists both sections
    // and says why BLE devices are unavailable instead of failing.
    let text = tactus_transport::devices_report(Duration::from_millis(100));
    assert!(text.starts_with("Serial ports:\n"), "{text}");
    assert!(text.contains("Bluetooth LE devices:\n"), "{text}");
    if !cfg!(feature = "ble") {
        assert!(text.contains("--features ble"), "{text}");
        assert!(
            !text.contains("tactus-transport"),
            "no internal crate names: {text}"
        );
    }
    eprintln!("{text}");
}
