//! Shared test helpers: a synthetic stereo mix with known stems, and chunked runners.
#![allow(dead_code)]

use tactus_separate::{Separator, Stem, StemOutput};

/// A small deterministic PRNG (64-bit LCG, top bits), uniform in [-1, 1).
pub struct Lcg(pub u64);

impl Lcg {
    pub fn next(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }
}

/// A stereo mix and its four stems (mono references = (L + R) / 2 of each stem).
pub struct Mix {
    pub left: Vec<f32>,
    pub right: Vec<f32>,
    /// Indexed like `Stem::ALL`: drums, bass, vocals, other.
    pub stems: [Vec<f32>; 4],
    /// (L + R) / 2 of the mix.
    pub mono: Vec<f32>,
}

/// Attack/release envelope of a note of length `dur` at time `t` into it.
fn ar(t: f32, dur: f32, attack: f32, release: f32) -> f32 {
    if t < 0.0 || t >= dur {
        0.0
    } else {
        (t / attack).min(1.0) * ((dur - t) / release).min(1.0)
    }
}

/// Sum of harmonics `h * f0` (amplitude `amp / h`) that stay below `max_hz`, given phase.
fn harmonic(phase: f64, f0: f32, max_hz: f32, max_h: usize, amp: f32) -> f32 {
    let mut y = 0.0;
    for h in 1..=max_h {
        if h as f32 * f0 > max_hz {
            break;
        }
        y += amp / h as f32 * ((h as f64 * phase).sin() as f32);
    }
    y
}

/// The synthetic test song (120 bpm):
/// * drums (centre): a kick thump on every beat (sine swept 120 -> 50 Hz, 120 ms decay),
///   snare noise bursts on the off-beats (50 ms decay), hi-hat ticks every 1/8 (15 ms);
/// * bass (centre): a line of f0 41–98 Hz, one note per beat, partials up to 200 Hz;
/// * vocals (centre): a melody of f0 262–440 Hz, 1 s notes, 5.5 Hz vibrato of ±3 %,
///   6 partials;
/// * other: two chord pads of 4 partials per note in 220–660 Hz (fundamentals), one
///   panned hard left (gains 0.95 / 0.2, 13.5 dB), one right, changing every 2 s.
pub fn synthetic_mix(sr: u32, seconds: f32, seed: u64) -> Mix {
    let n = (sr as f32 * seconds) as usize;
    let fs = sr as f32;
    let mut rng = Lcg(seed);
    let mut drums = vec![0.0f32; n];
    let mut bass = vec![0.0f32; n];
    let mut vocals = vec![0.0f32; n];
    let (mut other_l, mut other_r) = (vec![0.0f32; n], vec![0.0f32; n]);
    let beat = 0.5f32;
    let bass_notes = [41.2f32, 55.0, 61.7, 73.4, 49.0, 82.4, 65.4, 98.0];
    let vocal_notes = [261.6f32, 293.7, 329.6, 392.0, 349.2, 440.0, 392.0, 329.6];
    let chords_l = [[261.6f32, 329.6, 392.0], [293.7, 349.2, 440.0]];
    let chords_r = [[220.0f32, 261.6, 329.6], [392.0, 493.9, 587.3]];
    let (mut pb, mut pv) = (0.0f64, 0.0f64);
    let mut pc = [[0.0f64; 3]; 2];
    for i in 0..n {
        let t = i as f32 / fs;
        // Drums.
        let tb = t % beat;
        let kick_t = tb;
        // Phase of the sweep f(t) = 50 + 70·exp(-t/30 ms), integrated in closed form.
        let kick_phase =
            std::f32::consts::TAU * (50.0 * kick_t + 70.0 * 0.03 * (1.0 - (-kick_t / 0.03).exp()));
        let mut d = 0.8 * (-kick_t / 0.12).exp() * kick_phase.sin();
        let snare_t = (t - beat / 2.0).rem_euclid(beat);
        let noise = rng.next();
        d += 0.4 * (-snare_t / 0.05).exp() * noise;
        let hat_t = t % (beat / 4.0);
        d += 0.15 * (-hat_t / 0.015).exp() * rng.next();
        drums[i] = d;
        // Bass.
        let bi = (t / beat) as usize;
        let f0 = bass_notes[bi % bass_notes.len()];
        pb += std::f64::consts::TAU * f0 as f64 / sr as f64;
        bass[i] = harmonic(pb, f0, 200.0, 8, 0.5) * ar(t - bi as f32 * beat, beat, 0.01, 0.03);
        // Vocals.
        let vi = t as usize;
        let fv = vocal_notes[vi % vocal_notes.len()]
            * (1.0 + 0.03 * (std::f32::consts::TAU * 5.5 * t).sin());
        pv += std::f64::consts::TAU * fv as f64 / sr as f64;
        vocals[i] = harmonic(pv, fv, 20_000.0, 6, 0.3) * ar(t - vi as f32, 1.0, 0.04, 0.05);
        // Other: two pads, changing every 2 s.
        let ci = (t / 2.0) as usize;
        let env = ar(t - 2.0 * ci as f32, 2.0, 0.05, 0.1);
        let (mut yl, mut yr) = (0.0, 0.0);
        for (side, chords) in [chords_l, chords_r].iter().enumerate() {
            let chord = chords[ci % 2];
            let mut y = 0.0;
            for (j, &f) in chord.iter().enumerate() {
                pc[side][j] += std::f64::consts::TAU * f as f64 / sr as f64;
                y += harmonic(pc[side][j], f, 20_000.0, 4, 0.12);
            }
            if side == 0 {
                yl += 0.95 * y * env;
                yr += 0.2 * y * env;
            } else {
                yl += 0.2 * y * env;
                yr += 0.95 * y * env;
            }
        }
        other_l[i] = yl;
        other_r[i] = yr;
    }
    let other: Vec<f32> = other_l
        .iter()
        .zip(&other_r)
        .map(|(l, r)| 0.5 * (l + r))
        .collect();
    let left: Vec<f32> = (0..n)
        .map(|i| drums[i] + bass[i] + vocals[i] + other_l[i])
        .collect();
    let right: Vec<f32> = (0..n)
        .map(|i| drums[i] + bass[i] + vocals[i] + other_r[i])
        .collect();
    let mono = left
        .iter()
        .zip(&right)
        .map(|(l, r)| 0.5 * (l + r))
        .collect();
    Mix {
        left,
        right,
        stems: [drums, bass, vocals, other],
        mono,
    }
}

/// Runs a whole stream through `sep` in chunks whose sizes cycle through `chunks`
/// (0 entries are allowed and feed empty blocks), then finishes.
pub fn run_chunked(
    sep: &mut dyn Separator,
    left: &[f32],
    right: &[f32],
    chunks: &[usize],
) -> StemOutput {
    let mut out = StemOutput::new();
    let mut pos = 0;
    let mut i = 0;
    while pos < left.len() {
        let c = if chunks.is_empty() {
            left.len()
        } else {
            chunks[i % chunks.len()]
        };
        let end = (pos + c).min(left.len());
        sep.process(&left[pos..end], &right[pos..end], &mut out);
        pos = end;
        i += 1;
    }
    sep.finish(&mut out);
    out
}

/// Runs a whole stream through `sep` in one block.
pub fn run_block(sep: &mut dyn Separator, left: &[f32], right: &[f32]) -> StemOutput {
    let mut out = StemOutput::new();
    sep.process(left, right, &mut out);
    sep.finish(&mut out);
    out
}

/// The stem's position in `Stem::ALL`.
pub fn idx(stem: Stem) -> usize {
    Stem::ALL.iter().position(|&s| s == stem).unwrap()
}
