//! A synthetic song and a feeder thread that plays it into a capture ring at full speed.
#![allow(dead_code)]

use std::f32::consts::TAU;
use std::thread::JoinHandle;
use std::time::Duration;

use tactus_audio::ring::CaptureWriter;

/// Interleaved stereo frame `i` of a song at `rate`: a kick-like click every 0.5 s, a bass
/// note (110/147 Hz, changing every second, panned centre) and a melody (440/554/659 Hz,
/// panned left) so that pitch tracks, drums and the gate all work.
pub fn frame(i: u64, rate: u32) -> (f32, f32) {
    let t = i as f32 / rate as f32;
    let s = (i / u64::from(rate)) as usize;
    let beat = (i % (u64::from(rate) / 2)) as f32 / rate as f32;
    let click = if beat < 0.03 {
        0.6 * (TAU * 60.0 * beat).sin() * (1.0 - beat / 0.03)
    } else {
        0.0
    };
    let bass = 0.25 * (TAU * [110.0, 147.0][s % 2] * t).sin();
    let mel = 0.15 * (TAU * [440.0, 554.4, 659.3][s % 3] * t).sin();
    (click + bass + mel, click + bass + 0.3 * mel)
}

/// Writes `seconds` of [`frame`] into the ring as fast as the reader drains it, in blocks
/// of 1024 frames, then drops the writer (the input ends).
pub fn feed(mut w: CaptureWriter, rate: u32, seconds: f64) -> JoinHandle<()> {
    std::thread::spawn(move || {
        let total = (seconds * f64::from(rate)) as u64;
        let mut block = vec![0.0f32; 2048];
        let mut i = 0u64;
        while i < total {
            let n = (total - i).min(1024) as usize;
            if w.free_frames() < n {
                std::thread::sleep(Duration::from_micros(200));
                continue;
            }
            for j in 0..n {
                let (l, r) = frame(i + j as u64, rate);
                block[2 * j] = l;
                block[2 * j + 1] = r;
            }
            w.write(&block[..2 * n], 2, |x| x, Duration::ZERO);
            i += n as u64;
        }
    })
}

/// A live configuration (the CLI's live defaults before the live profile): streaming,
/// 25 ms bins, pYIN, the band drums.
pub fn live_config() -> tactus_engine::EngineConfig {
    tactus_engine::EngineConfig {
        mode: tactus_engine::Mode::Streaming,
        bin_ms: 25,
        pitch: tactus_engine::PitchMethod::Pyin,
        drums: tactus_engine::DrumMethod::Bands,
        ..tactus_engine::EngineConfig::default()
    }
}
