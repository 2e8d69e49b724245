//! Bounded fuzzing of the readers: the wire-protocol decoder, the pattern and
//! features files and the map, fed random bytes and mutations of valid inputs from a
//! seeded xorshift generator. Every case must return (no panic); the decoder must accept
//! no packet whose 16 bytes are not in the input with a valid CRC; a file that reads back
//! must write and read back to the same value.
//!
//! `cargo test -p tactus-glove --test fuzz` runs [`CI_CASES`] per reader (CI); the long run,
//! `cargo test --release -p tactus-glove --test fuzz -- --ignored --nocapture`, runs
//! [`LONG_CASES`] per reader and prints the counts.

use tactus_glove::{crc8, Decoder, Features, Frame, GloveMap, Packet, PacketType, Pattern};

const CI_CASES: u64 = 20_000;
const LONG_CASES: u64 = 1_000_000;

/// xorshift64* (Vigna 2016): small, seeded, good enough to drive mutations.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    fn byte(&mut self) -> u8 {
        self.next() as u8
    }
}

/// Bytes and tokens that steer a text reader into its corners.
const TOKENS: &[&str] = &[
    "{",
    "}",
    "[",
    "]",
    "\"",
    ":",
    ",",
    "-1",
    "0",
    "1e999",
    "NaN",
    "null",
    "true",
    "\"\\u0000\"",
    "18446744073709551616",
    "\"format\"",
    "\"version\"",
    "\"frames\"",
    "\"levels\"",
    "\"bin_ms\"",
    "\"ff\"",
    "\"zz\"",
    "=",
    "\n",
    "[thumb]",
    "cell0",
    "{ pitch = \"bass\" }",
    "dots = [9]",
    "\u{feff}",
    "\u{7f}",
    "é",
];

/// One random mutation of `base`: flip, insert, delete, duplicate, truncate, splice a
/// token, or (1 in 16) pure random bytes.
fn mutate(rng: &mut Rng, base: &[u8]) -> Vec<u8> {
    if rng.below(16) == 0 {
        let n = rng.below(256);
        return (0..n).map(|_| rng.byte()).collect();
    }
    let mut v = base.to_vec();
    for _ in 0..1 + rng.below(4) {
        let at = rng.below(v.len() + 1);
        match rng.below(7) {
            0 if !v.is_empty() => {
                let i = at.min(v.len() - 1);
                v[i] ^= 1 << rng.below(8);
            }
            1 => v.insert(at, rng.byte()),
            2 if at < v.len() => {
                let n = rng.below(8).min(v.len() - at);
                v.drain(at..at + n);
            }
            3 if at < v.len() => {
                let n = rng.below(32).min(v.len() - at);
                let chunk = v[at..at + n].to_vec();
                let to = rng.below(v.len() + 1);
                v.splice(to..to, chunk);
            }
            4 => v.truncate(at),
            _ => {
                let t = TOKENS[rng.below(TOKENS.len())].as_bytes();
                v.splice(at..at, t.iter().copied());
            }
        }
    }
    v
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// The decoder on random and mutated packet streams. Returns (cases, packets accepted,
/// packets accepted whose bytes were not in the input with a valid CRC).
fn fuzz_decoder(seed: u64, cases: u64) -> (u64, u64, u64) {
    let mut rng = Rng(seed);
    let (mut accepted, mut bad) = (0u64, 0u64);
    for case in 0..cases {
        // A valid stream of 1..6 packets of every type, then mutated.
        let mut stream = Vec::new();
        for k in 0..1 + rng.below(6) {
            let mut f = Frame::DOWN;
            for b in f.0.iter_mut() {
                *b = rng.byte();
            }
            let p = match rng.below(3) {
                0 => Packet::pins(k as u8, rng.next() as u16, f),
                1 => Packet::all_down(k as u8, rng.next() as u16),
                _ => Packet::keep_alive(k as u8, rng.next() as u16),
            };
            stream.extend_from_slice(&p.encode());
        }
        let input = mutate(&mut rng, &stream);
        let mut dec = Decoder::new();
        let mut got = Vec::new();
        // Fed in random slices, as a serial port delivers it.
        let mut rest = &input[..];
        while !rest.is_empty() {
            let n = 1 + rng.below(rest.len());
            dec.push(&rest[..n], &mut |p| got.push(p));
            rest = &rest[n..];
        }
        for p in got {
            accepted += 1;
            let bytes = p.encode();
            let present = input.windows(16).any(|w| w == bytes);
            if !present || crc8(&bytes[1..15]) != bytes[15] {
                bad += 1;
                eprintln!("case {case}: accepted {p:?} not in the input");
            }
            if p.kind != PacketType::Pins {
                assert_eq!(p.frame, Frame::DOWN);
            }
        }
    }
    (cases, accepted, bad)
}

/// A text reader on mutations of `valid`. Returns (cases, accepted, rejected).
fn fuzz_text<T: PartialEq + std::fmt::Debug>(
    seed: u64,
    cases: u64,
    valid: &str,
    read: impl Fn(&str) -> Result<T, tactus_glove::GloveError>,
    write: impl Fn(&T) -> String,
) -> (u64, u64, u64) {
    let mut rng = Rng(seed);
    let (mut ok, mut err) = (0u64, 0u64);
    for _ in 0..cases {
        let input = text(&mutate(&mut rng, valid.as_bytes()));
        match read(&input) {
            Ok(v) => {
                ok += 1;
                let again = read(&write(&v)).expect("what was read writes back readably");
                assert_eq!(again, v, "round trip of {input:?}");
            }
            Err(e) => {
                err += 1;
                let msg = e.to_string();
                assert!(!msg.is_empty() && !msg.contains('\n'), "{msg:?}");
            }
        }
    }
    (cases, ok, err)
}

fn pattern_json() -> &'static str {
    include_str!("fixtures/pattern-v1.json")
}

fn features_json() -> &'static str {
    include_str!("fixtures/features-v1.json")
}

fn run_all(cases: u64) {
    let (n, acc, bad) = fuzz_decoder(0x7A_C705, cases);
    println!("decoder: {n} cases, {acc} packets accepted, {bad} not in the input with a valid CRC");
    assert_eq!(bad, 0);
    assert!(acc > 0, "the mutations must leave some packets intact");
    let (n, ok, err) = fuzz_text(0x9A77, cases, pattern_json(), Pattern::from_json_str, |p| {
        p.to_json_string().unwrap()
    });
    println!("pattern: {n} cases, {ok} read, {err} rejected with a one-line error");
    let (n, ok, err) = fuzz_text(
        0xFEA7,
        cases,
        features_json(),
        Features::from_json_str,
        |f| f.to_json_string().unwrap(),
    );
    println!("features: {n} cases, {ok} read, {err} rejected with a one-line error");
    let (n, ok, err) = fuzz_text(
        0x3A9,
        cases,
        tactus_glove::map::DEFAULT_MAP_TOML,
        GloveMap::from_toml_str,
        |m| m.to_toml_string(),
    );
    println!("map: {n} cases, {ok} read, {err} rejected with a one-line error");
}

#[test]
fn readers_survive_mutations() {
    run_all(CI_CASES);
}

#[test]
#[ignore = "long run (36 s for 10^6 per reader): --ignored"]
fn readers_survive_a_million_mutations_each() {
    // TACTUS_FUZZ_CASES overrides the count (a shorter or longer run).
    let cases = std::env::var("TACTUS_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(LONG_CASES);
    run_all(cases);
}
