//! The lead on its own stem sums 12 harmonics (the clean lead's recipe;
//! `docs/decisions/0025-twelve-harmonics-for-a-clean-lead.md`): a low vowel whose energy sits
//! at its formants is tracked at its fundamental, offline and streaming alike.

use tactus_engine::profile::Profile;
use tactus_engine::recipe::Role;
use tactus_engine::{Mode, PitchMethod};

mod common;
use common::SR;

/// Low sung vowels (123–156 Hz) whose 6th–10th harmonics are 10–12 dB above the first
/// four: 40 harmonics of a −6 dB/octave source through three formants (bandwidth 13 % of
/// the centre), 0.5 s a note, with the truth per sample.
fn low_vowels() -> (Vec<f32>, Vec<f64>) {
    let notes = [130.8, 146.8, 123.5, 155.6, 138.6, 130.8];
    let vowels = [[850.0, 1250.0, 2600.0], [950.0, 1400.0, 2500.0]];
    let n = SR as usize / 2;
    let (mut x, mut truth) = (Vec::new(), Vec::new());
    for (k, &f0) in notes.iter().enumerate() {
        let amps: Vec<f64> = (1..=40)
            .map(|h| {
                let f = h as f64 * f0;
                let g: f64 = vowels[k % 2]
                    .iter()
                    .map(|&fc: &f64| 1.0 / (1.0 + ((f - fc) / (0.13 * fc)).powi(2)))
                    .sum();
                0.05 * g / h as f64
            })
            .collect();
        for i in 0..n {
            let t = i as f64 / SR as f64;
            let s: f64 = amps
                .iter()
                .enumerate()
                .map(|(h, a)| {
                    a * (std::f64::consts::TAU * (h + 1) as f64 * f0 * t + h as f64).sin()
                })
                .sum();
            x.push(s as f32);
            truth.push(f0);
        }
    }
    (x, truth)
}

#[test]
fn a_low_voice_on_its_own_stem_is_tracked_at_its_fundamental() {
    assert_eq!(common::tuning().clean_lead_harmonics, 12);
    let (x, truth) = low_vowels();
    let (lo, hi) = tactus_dsp::Stem::Vocals.pitch_range_hz().unwrap();
    for mode in [Mode::Offline, Mode::Streaming] {
        let geo = common::geo(mode, Profile::Full);
        let mut t = common::pitch_track(geo, Role::Lead, false, PitchMethod::Shs, (lo, hi));
        for b in x.chunks(3000) {
            t.process(b);
        }
        t.finish();
        let hop = t.hop();
        let (mut ok, mut n) = (0, 0);
        for (i, &f) in t.f0.iter().enumerate() {
            // Hops at least 60 ms from a note change (the 70 ms frame straddles it).
            let at = i * hop;
            let span = at.saturating_sub(SR as usize * 6 / 100)..(at + SR as usize * 6 / 100);
            let Some(&want) = truth.get(at) else { continue };
            if span.end > truth.len() || truth[span].iter().any(|&v| v != want) {
                continue;
            }
            n += 1;
            if f > 0.0 && (1200.0 * (f as f64 / want).log2()).abs() <= 50.0 {
                ok += 1;
            }
        }
        assert!(n > 200, "{mode:?}: {n} hops scored");
        let rpa = ok as f64 / n as f64;
        assert!(rpa >= 0.95, "{mode:?}: RPA {rpa:.3} on the low vowels");
    }
}
