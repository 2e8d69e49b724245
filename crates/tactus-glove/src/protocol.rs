//! Wire protocol v1, host → glove (docs/design.md, "Wire protocol v1", a contract).
//!
//! Every packet is 16 bytes, so one fits a single 20-byte BLE write (service 0xFFE0,
//! characteristic 0xFFE1, write without response) and the same bytes go over a UART
//! (default 115200 baud):
//!
//! | byte | meaning |
//! |---|---|
//! | 0 | [`SYNC`] = 0xA5 |
//! | 1 | type: 0x01 pins, 0x02 all pins down, 0x03 keep-alive ([`PacketType`]) |
//! | 2 | sequence number, u8, wraps |
//! | 3–4 | frame time in ms since stream start, u16 little-endian, wraps |
//! | 5–14 | the 10 cell bytes (all zero for types 0x02 and 0x03) |
//! | 15 | CRC-8 ([`crc8`]: polynomial 0x07, init 0x00, no reflection, no final xor) over bytes 1–14 |
//!
//! Every pins packet carries the full state, so a lost packet is repaired by the next one.
//! One sequence counter covers all packet types. The [`Decoder`] (the glove's side, also
//! used by the emulator and tests) resynchronises on the sync byte after garbage, drops
//! packets with a bad CRC, and counts lost packets from the sequence numbers. Encoding and
//! decoding never allocate; decoding adds no latency beyond the packet's own 16 bytes.

use crate::glove::{Frame, CELLS};

/// First byte of every packet.
pub const SYNC: u8 = 0xA5;
/// Bytes in a packet.
pub const PACKET_LEN: usize = 16;

/// What a packet asks the glove to do.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum PacketType {
    /// Set all 80 pins to the packet's frame.
    Pins = 1,
    /// Lower all pins (frame bytes are zero).
    AllDown = 2,
    /// Nothing changes; keeps the link alive (frame bytes are zero).
    KeepAlive = 3,
}

impl PacketType {
    /// The type's name in logs (the actuation log, the JSON Lines recorder): `pins`,
    /// `all_down`, `keep_alive`.
    pub fn name(self) -> &'static str {
        match self {
            PacketType::Pins => "pins",
            PacketType::AllDown => "all_down",
            PacketType::KeepAlive => "keep_alive",
        }
    }

    /// The type for a wire byte, if it is one.
    pub fn from_byte(b: u8) -> Option<PacketType> {
        match b {
            1 => Some(PacketType::Pins),
            2 => Some(PacketType::AllDown),
            3 => Some(PacketType::KeepAlive),
            _ => None,
        }
    }
}

/// One decoded (or to-be-encoded) packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Packet {
    /// Packet type.
    pub kind: PacketType,
    /// Sequence number (wraps at 256).
    pub seq: u8,
    /// Frame time in ms since stream start (wraps at 65536).
    pub time_ms: u16,
    /// Pin state; only meaningful for [`PacketType::Pins`].
    pub frame: Frame,
}

/// CRC-8 with polynomial 0x07, initial value 0x00, no reflection and no final xor
/// (the CRC-8/SMBUS parameters: check value of `"123456789"` is 0xF4).
///
/// A bitwise loop: 14 bytes per packet make a lookup table pointless.
pub fn crc8(bytes: &[u8]) -> u8 {
    let mut crc = 0u8;
    for &b in bytes {
        crc ^= b;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 {
                (crc << 1) ^ 0x07
            } else {
                crc << 1
            };
        }
    }
    crc
}

impl Packet {
    /// A pins packet.
    pub fn pins(seq: u8, time_ms: u16, frame: Frame) -> Packet {
        Packet {
            kind: PacketType::Pins,
            seq,
            time_ms,
            frame,
        }
    }

    /// An all-pins-down packet.
    pub fn all_down(seq: u8, time_ms: u16) -> Packet {
        Packet {
            kind: PacketType::AllDown,
            seq,
            time_ms,
            frame: Frame::DOWN,
        }
    }

    /// A keep-alive packet.
    pub fn keep_alive(seq: u8, time_ms: u16) -> Packet {
        Packet {
            kind: PacketType::KeepAlive,
            seq,
            time_ms,
            frame: Frame::DOWN,
        }
    }

    /// The 16 wire bytes. The frame is sent only for [`PacketType::Pins`]; the other types
    /// carry zero cell bytes whatever `self.frame` holds.
    pub fn encode(&self) -> [u8; PACKET_LEN] {
        let mut out = [0u8; PACKET_LEN];
        out[0] = SYNC;
        out[1] = self.kind as u8;
        out[2] = self.seq;
        out[3..5].copy_from_slice(&self.time_ms.to_le_bytes());
        if self.kind == PacketType::Pins {
            out[5..5 + CELLS].copy_from_slice(&self.frame.0);
        }
        out[15] = crc8(&out[1..15]);
        out
    }

    /// Parses exactly one packet, or says why not.
    pub fn decode(bytes: &[u8; PACKET_LEN]) -> Result<Packet, Reject> {
        if bytes[0] != SYNC {
            return Err(Reject::NoSync);
        }
        if crc8(&bytes[1..15]) != bytes[15] {
            return Err(Reject::Crc);
        }
        let kind = PacketType::from_byte(bytes[1]).ok_or(Reject::Malformed)?;
        let mut frame = Frame::DOWN;
        frame.0.copy_from_slice(&bytes[5..5 + CELLS]);
        if kind != PacketType::Pins && frame != Frame::DOWN {
            return Err(Reject::Malformed);
        }
        Ok(Packet {
            kind,
            seq: bytes[2],
            time_ms: u16::from_le_bytes([bytes[3], bytes[4]]),
            frame,
        })
    }
}

/// Why 16 bytes are not a packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reject {
    /// Byte 0 is not [`SYNC`].
    NoSync,
    /// The CRC does not match.
    Crc,
    /// The CRC matches but the type is unknown, or a non-pins packet has non-zero cells.
    Malformed,
}

/// Counters kept by a [`Decoder`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DecoderStats {
    /// Packets accepted.
    pub packets: u64,
    /// Candidate packets (starting with [`SYNC`]) dropped for a bad CRC.
    pub crc_errors: u64,
    /// Candidate packets with a good CRC but an unknown type or non-zero cells on a
    /// non-pins packet.
    pub malformed: u64,
    /// Packets lost, from the sequence numbers: `seq - last_seq - 1` modulo 256 summed over
    /// accepted packets (a repeated sequence number therefore counts as 255 lost).
    pub sequence_gaps: u64,
    /// Bytes that were not part of any accepted packet (noise, rejected candidates).
    pub garbage_bytes: u64,
}

/// Streaming packet decoder: feed it byte chunks of any size.
///
/// Invariant: `16 * packets + garbage_bytes + pending()` equals the bytes pushed so far.
/// A rejected candidate is dropped up to the next [`SYNC`] inside it, so a real packet that
/// starts inside noise is still found. No allocation.
#[derive(Debug, Clone, Default)]
pub struct Decoder {
    buf: [u8; PACKET_LEN],
    len: usize,
    last_seq: Option<u8>,
    stats: DecoderStats,
}

impl Decoder {
    /// A decoder waiting for a sync byte.
    pub fn new() -> Decoder {
        Decoder::default()
    }

    /// The counters so far.
    pub fn stats(&self) -> DecoderStats {
        self.stats
    }

    /// Bytes of an incomplete candidate packet held back.
    pub fn pending(&self) -> usize {
        self.len
    }

    /// Back to the just-constructed state (counters cleared).
    pub fn reset(&mut self) {
        *self = Decoder::default();
    }

    /// Feeds bytes; calls `emit` for each valid packet, in stream order.
    pub fn push(&mut self, bytes: &[u8], emit: &mut dyn FnMut(Packet)) {
        for &b in bytes {
            if self.len == 0 {
                if b == SYNC {
                    self.buf[0] = b;
                    self.len = 1;
                } else {
                    self.stats.garbage_bytes += 1;
                }
                continue;
            }
            self.buf[self.len] = b;
            self.len += 1;
            if self.len == PACKET_LEN {
                self.complete(emit);
            }
        }
    }

    fn complete(&mut self, emit: &mut dyn FnMut(Packet)) {
        match Packet::decode(&self.buf) {
            Ok(packet) => {
                if let Some(last) = self.last_seq {
                    self.stats.sequence_gaps +=
                        u64::from(packet.seq.wrapping_sub(last).wrapping_sub(1));
                }
                self.last_seq = Some(packet.seq);
                self.stats.packets += 1;
                self.len = 0;
                emit(packet);
            }
            Err(reject) => {
                match reject {
                    Reject::Crc => self.stats.crc_errors += 1,
                    Reject::Malformed => self.stats.malformed += 1,
                    // The buffer always starts with SYNC.
                    Reject::NoSync => {}
                }
                // Drop up to the next sync byte after position 0 and keep the rest: it may be
                // the start of a real packet. The kept bytes are fewer than 16, so no packet
                // can complete here.
                let next = self.buf[1..]
                    .iter()
                    .position(|&x| x == SYNC)
                    .map_or(PACKET_LEN, |p| p + 1);
                self.stats.garbage_bytes += next as u64;
                self.buf.copy_within(next.., 0);
                self.len = PACKET_LEN - next;
            }
        }
    }
}
