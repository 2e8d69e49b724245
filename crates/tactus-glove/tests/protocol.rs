//! Wire protocol v1: CRC check values, layout, round trips, resync, corruption, chunking.

use proptest::prelude::*;
use tactus_glove::protocol::PACKET_LEN;
use tactus_glove::{crc8, Decoder, DecoderStats, Frame, Packet, PacketType, SYNC};

/// Slow oracle: CRC as polynomial long division over the message bits followed by 8 zero
/// bits (GF(2)), no table, no shifting register tricks.
fn crc8_long_division(bytes: &[u8]) -> u8 {
    let mut bits: Vec<u8> = bytes
        .iter()
        .flat_map(|b| (0..8).rev().map(move |k| (b >> k) & 1))
        .collect();
    bits.extend([0; 8]);
    let poly = [1u8, 0, 0, 0, 0, 0, 1, 1, 1]; // x^8 + x^2 + x + 1
    for i in 0..bits.len() - 8 {
        if bits[i] == 1 {
            for (j, p) in poly.iter().enumerate() {
                bits[i + j] ^= p;
            }
        }
    }
    bits[bits.len() - 8..]
        .iter()
        .fold(0, |acc, b| (acc << 1) | b)
}

fn decode_all(bytes: &[u8]) -> (Vec<Packet>, DecoderStats, usize) {
    let mut d = Decoder::new();
    let mut out = Vec::new();
    d.push(bytes, &mut |p| out.push(p));
    (out, d.stats(), d.pending())
}

#[test]
fn crc8_check_values() {
    // CRC-8/SMBUS (poly 0x07, init 0, refin/refout false, xorout 0): check = 0xF4.
    assert_eq!(crc8(b"123456789"), 0xF4);
    assert_eq!(crc8(b""), 0x00);
    assert_eq!(crc8(&[0x00]), 0x00);
    assert_eq!(crc8(&[0x01]), 0x07);
    assert_eq!(crc8(&[0x80]), 0x89);
    assert_eq!(crc8_long_division(b"123456789"), 0xF4);
}

#[test]
fn packet_layout_is_the_contract() {
    let frame = Frame([1, 2, 3, 4, 5, 6, 7, 8, 9, 10]);
    let bytes = Packet::pins(0x42, 0x1234, frame).encode();
    assert_eq!(&bytes[..5], &[0xA5, 0x01, 0x42, 0x34, 0x12]);
    assert_eq!(&bytes[5..15], &[1, 2, 3, 4, 5, 6, 7, 8, 9, 10]);
    assert_eq!(bytes[15], crc8_long_division(&bytes[1..15]));

    let down = Packet {
        kind: PacketType::AllDown,
        seq: 7,
        time_ms: 65535,
        frame,
    }
    .encode();
    assert_eq!(&down[..5], &[0xA5, 0x02, 7, 0xFF, 0xFF]);
    assert_eq!(&down[5..15], &[0; 10], "cell bytes are zero for all-down");
    let keep = Packet::keep_alive(8, 0).encode();
    assert_eq!(keep[1], 0x03);
    assert_eq!(&keep[5..15], &[0; 10]);
    const { assert!(PACKET_LEN <= 20, "fits one BLE write") };
}

#[test]
fn non_pins_packet_with_cells_is_malformed() {
    let mut bytes = Packet::keep_alive(1, 2).encode();
    bytes[9] = 1;
    bytes[15] = crc8(&bytes[1..15]);
    let (packets, stats, _) = decode_all(&bytes);
    assert!(packets.is_empty());
    assert_eq!(stats.malformed, 1);
    let mut bytes = Packet::keep_alive(1, 2).encode();
    bytes[1] = 0x04;
    bytes[15] = crc8(&bytes[1..15]);
    assert_eq!(decode_all(&bytes).1.malformed, 1);
}

#[test]
fn resync_after_garbage_prefix_and_between_packets() {
    let a = Packet::pins(1, 100, Frame([0xA5; 10])); // sync bytes inside the payload
    let b = Packet::pins(2, 200, Frame([3; 10]));
    let mut stream = vec![0x00, 0xA5, 0x13, 0xA5, 0xFF, 0x01]; // 2 false syncs in noise
    stream.extend(a.encode());
    stream.extend([0xA5, 0xA5, 0x01, 0x02]);
    stream.extend(b.encode());
    stream.extend([0x42, 0xA5, 0x01]); // trailing partial
    let (packets, stats, pending) = decode_all(&stream);
    assert_eq!(packets, vec![a, b]);
    assert_eq!(stats.packets, 2);
    assert_eq!(stats.sequence_gaps, 0);
    // The invariant: every byte is accounted for.
    assert_eq!(
        16 * stats.packets + stats.garbage_bytes + pending as u64,
        stream.len() as u64
    );
    assert_eq!(pending, 2, "the trailing 0xA5 0x01 wait for more bytes");
}

#[test]
fn every_single_bit_flip_is_rejected() {
    let p = Packet::pins(9, 999, Frame([0x5A, 0, 0xFF, 1, 2, 3, 4, 5, 6, 7]));
    let good = p.encode();
    for bit in 0..PACKET_LEN * 8 {
        let mut bytes = good;
        bytes[bit / 8] ^= 1 << (bit % 8);
        let (packets, stats, _) = decode_all(&bytes);
        assert!(packets.is_empty(), "bit {bit} flip accepted");
        if bit >= 8 {
            assert_eq!(stats.crc_errors, 1, "bit {bit}");
        }
        // A corrupted packet followed by a good one: the good one still decodes.
        let mut stream = bytes.to_vec();
        stream.extend(good);
        let (packets, _, _) = decode_all(&stream);
        assert_eq!(packets.last(), Some(&p), "bit {bit}");
    }
}

#[test]
fn sequence_gaps_across_u8_wrap() {
    let mut stream = Vec::new();
    // 250, 251, 253 (1 lost), 255, 1 (0 lost... 255 -> 0 -> 1: 1 lost), 2, 5 (2 lost)
    for seq in [250u8, 251, 253, 255, 1, 2, 5] {
        stream.extend(Packet::pins(seq, 0, Frame::DOWN).encode());
    }
    let (packets, stats, _) = decode_all(&stream);
    assert_eq!(packets.len(), 7);
    assert_eq!(stats.sequence_gaps, 1 + 1 + 1 + 2);
    // Lost packets on the wire are counted: drop the middle one of three.
    let s: Vec<u8> = [0u8, 2]
        .iter()
        .flat_map(|&q| Packet::all_down(q, 0).encode())
        .collect();
    assert_eq!(decode_all(&s).1.sequence_gaps, 1);
}

fn arb_packet() -> impl Strategy<Value = Packet> {
    (0u8..3, any::<u8>(), any::<u16>(), any::<[u8; 10]>()).prop_map(|(k, seq, time_ms, cells)| {
        match k {
            0 => Packet::pins(seq, time_ms, Frame(cells)),
            1 => Packet::all_down(seq, time_ms),
            _ => Packet::keep_alive(seq, time_ms),
        }
    })
}

fn contains(hay: &[u8], needle: &[u8]) -> bool {
    hay.windows(needle.len()).any(|w| w == needle)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn encode_decode_round_trip(p in arb_packet()) {
        let bytes = p.encode();
        prop_assert_eq!(bytes[15], crc8_long_division(&bytes[1..15]));
        let (packets, stats, pending) = decode_all(&bytes);
        prop_assert_eq!(packets, vec![p]);
        prop_assert_eq!(stats.garbage_bytes + stats.crc_errors + pending as u64, 0);
    }

    #[test]
    fn crc_matches_long_division(bytes in proptest::collection::vec(any::<u8>(), 0..40)) {
        prop_assert_eq!(crc8(&bytes), crc8_long_division(&bytes));
    }

    #[test]
    fn arbitrary_bytes_never_panic_nor_emit_bad_packets(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let (packets, stats, pending) = decode_all(&bytes);
        for p in &packets {
            // Every emitted packet is exactly 16 bytes that occur in the input, with a good CRC.
            let enc = p.encode();
            prop_assert!(contains(&bytes, &enc));
            prop_assert_eq!(enc[15], crc8_long_division(&enc[1..15]));
        }
        prop_assert_eq!(16 * stats.packets + stats.garbage_bytes + pending as u64, bytes.len() as u64);
    }

    #[test]
    fn packets_survive_sync_free_noise(
        packets in proptest::collection::vec(arb_packet(), 1..8),
        noise in proptest::collection::vec(proptest::collection::vec(any::<u8>().prop_filter("no sync", |b| *b != SYNC), 0..20), 8),
    ) {
        let mut stream = Vec::new();
        for (p, n) in packets.iter().zip(noise.iter().cycle()) {
            stream.extend(n);
            stream.extend(p.encode());
        }
        let (got, stats, _) = decode_all(&stream);
        prop_assert_eq!(&got, &packets);
        prop_assert_eq!(stats.crc_errors, 0);
    }

    #[test]
    fn chunked_feeding_is_identical(
        bytes in proptest::collection::vec(any::<u8>(), 0..300),
        packets in proptest::collection::vec(arb_packet(), 0..6),
        cuts in proptest::collection::vec(1usize..40, 1..30),
    ) {
        // Interleave random bytes and real packets, then feed in random chunk sizes.
        let mut stream = Vec::new();
        let step = bytes.len() / (packets.len() + 1) + 1;
        let mut chunks = bytes.chunks(step);
        for p in &packets {
            stream.extend(chunks.next().unwrap_or(&[]));
            stream.extend(p.encode());
        }
        for c in chunks { stream.extend(c); }

        let (whole, whole_stats, whole_pending) = decode_all(&stream);
        let mut d = Decoder::new();
        let mut pieces = Vec::new();
        let mut rest = &stream[..];
        let mut i = 0;
        while !rest.is_empty() {
            let n = cuts[i % cuts.len()].min(rest.len());
            d.push(&rest[..n], &mut |p| pieces.push(p));
            rest = &rest[n..];
            i += 1;
        }
        prop_assert_eq!(pieces, whole);
        prop_assert_eq!(d.stats(), whole_stats);
        prop_assert_eq!(d.pending(), whole_pending);
    }
}
