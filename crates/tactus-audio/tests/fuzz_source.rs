//! Bounded fuzzing of the audio front door: every container and codec fixture,
//! mutated by a seeded xorshift generator (bit flips, overwritten header bytes, inserted
//! and deleted runs, truncation, random bytes), then opened and decoded to the end. Every
//! case must return: samples or one clear error line, never a panic.
//!
//! `cargo test -p tactus-engine --test fuzz_source` runs [`CI_CASES`] (CI); the long run,
//! `cargo test -p tactus-engine --test fuzz_source -- --ignored --nocapture`, runs
//! [`LONG_CASES`] and prints the counts.

use std::path::Path;

use tactus_audio::source::decode_all;

const CI_CASES: u64 = 2_000;
const LONG_CASES: u64 = 1_000_000;

/// xorshift64* (Vigna 2016).
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
}

fn mutate(rng: &mut Rng, base: &[u8]) -> Vec<u8> {
    if rng.below(32) == 0 {
        let n = rng.below(4096);
        return (0..n).map(|_| rng.next() as u8).collect();
    }
    let mut v = base.to_vec();
    for _ in 0..1 + rng.below(6) {
        // Headers are where parsers trust numbers: half the edits land in the first 256 bytes.
        let span = if rng.below(2) == 0 {
            v.len().min(256)
        } else {
            v.len()
        };
        let at = rng.below(span + 1).min(v.len());
        match rng.below(6) {
            0 if at < v.len() => v[at] ^= 1 << rng.below(8),
            1 if at < v.len() => v[at] = [0x00, 0xFF, 0x7F, 0x80][rng.below(4)],
            2 => {
                let n = rng.below(64);
                let bytes: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
                v.splice(at..at, bytes);
            }
            3 if at < v.len() => {
                let n = rng.below(256).min(v.len() - at);
                v.drain(at..at + n);
            }
            4 => v.truncate(at.max(rng.below(v.len() + 1))),
            _ if at + 4 <= v.len() => {
                // A length or count field set to an extreme.
                let x = [0u32, 1, u32::MAX, 0x7FFF_FFFF, 0x8000_0000][rng.below(5)];
                v[at..at + 4].copy_from_slice(&x.to_le_bytes());
            }
            _ => {}
        }
    }
    v
}

fn run(cases: u64) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let mut fixtures: Vec<(String, Vec<u8>)> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e != "sh"))
        .map(|p| {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read(&p).unwrap())
        })
        .collect();
    fixtures.sort();
    assert!(fixtures.len() >= 10);
    let tmp = tempfile::tempdir().unwrap();
    let mut rng = Rng(0xA0D1_0F00D);
    let (mut decoded, mut rejected) = (0u64, 0u64);
    for case in 0..cases {
        let (name, base) = &fixtures[(case as usize) % fixtures.len()];
        let bytes = mutate(&mut rng, base);
        // Keep the extension: it is the decoder's hint, as for a user's file.
        let path = tmp.path().join(name);
        std::fs::write(&path, &bytes).unwrap();
        match decode_all(&path) {
            Ok(d) => {
                decoded += 1;
                assert_eq!(d.left.len(), d.right.len());
                assert!(d.left.iter().chain(&d.right).all(|x| x.is_finite()));
            }
            Err(e) => {
                rejected += 1;
                let msg = e.to_string();
                assert!(
                    !msg.contains('\n') && msg.contains(name.as_str()),
                    "{msg:?}"
                );
            }
        }
    }
    println!("audio front door: {cases} cases, {decoded} decoded, {rejected} rejected with a one-line error");
}

#[test]
fn mutated_audio_files_never_panic() {
    run(CI_CASES);
}

#[test]
#[ignore = "long run: --ignored"]
fn a_million_mutated_audio_files() {
    // TACTUS_FUZZ_CASES overrides the count (a shorter or longer run).
    let cases = std::env::var("TACTUS_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(LONG_CASES);
    run(cases);
}
