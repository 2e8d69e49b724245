//! The mix's learned bass: the bottom of its level range comes from the hops the learned
//! tracker is sure of (`docs/decisions/0039-mix-bass-range-bottom-from-sure-hops.md`), through the real learned tracker on audio, against `tactus_dsp`'s range
//! functions replayed on the track's pitch and confidence. A kick-like thump in the line's
//! gaps is tracked as a held low pitch the tracker is unsure of: the held-note range reaches
//! it, the narrowed one stops a semitone under the line. Streaming narrows the same way once
//! the sure hops hold a range (`docs/decisions/0040-streaming-ranges-narrowed-to-sure-hops.md`), and the
//! harmonic-sum bass has no confidence rule.

use tactus_dsp::discretize::{
    narrow_range, range_quantiles_kept, range_quantiles_kept_or_sure, Discretizer, RangePrior,
};
use tactus_engine::profile::Profile;
use tactus_engine::recipe::Role;
use tactus_engine::track::PitchTrack;
use tactus_engine::{Mode, PitchMethod};

mod common;
use common::{levels, SR};

/// A plucked bass line E2 G2 A2 C3 D3 (0.3 s notes, no two an octave apart, so that the
/// octave-shadow rule keeps the line), sixteen times (the narrowing needs 300 sure held
/// hops, `HELD_MIN_HOPS`); after every A2 a 0.3 s thump, a sine gliding down to 55 Hz (A1)
/// and decaying in 0.1 s, as a kick's body sounds in the bass band. Its pitch, MIDI 33–34, is no octave under a note of the line, so the
/// octave-shadow rule keeps it.
fn line_with_thumps() -> Vec<f32> {
    let sr = SR as f32;
    let mut x = vec![0.0f32; SR as usize / 4];
    let mut ph = 0.0f32;
    for _ in 0..16 {
        for st in [40.0f32, 43.0, 45.0, 48.0, 50.0] {
            let f = 440.0 * ((st - 69.0) / 12.0).exp2();
            for i in 0..(0.3 * sr) as usize {
                ph += std::f32::consts::TAU * f / sr;
                let env = 0.4 * (-(i as f32) / (0.5 * sr)).exp();
                x.push(env * (ph.sin() + 0.6 * (2.0 * ph).sin() + 0.3 * (3.0 * ph).sin()));
            }
            if st == 45.0 {
                let mut kp = 0.0f32;
                for i in 0..(0.3 * sr) as usize {
                    let fk = 55.0 * (1.0 + 0.5 * (-(i as f32) / (0.02 * sr)).exp());
                    kp += std::f32::consts::TAU * fk / sr;
                    x.push(0.8 * (-(i as f32) / (0.1 * sr)).exp() * kp.sin());
                }
            }
        }
    }
    x
}

/// The mix bass's track with `method` over `x`, fed in `chunk`s, without the plain guard
/// (docs/decisions/0051-plain-guard.md): this synthetic line is a plain tone that YIN would
/// take where the learned tracker is silent, and these tests are about the learned
/// tracker's confidence.
fn track(method: PitchMethod, mode: Mode, x: &[f32], chunk: usize) -> PitchTrack {
    let (lo, hi) = tactus_dsp::Stem::Bass.pitch_range_hz().unwrap();
    let geo = common::geo(mode, Profile::Full);
    let mut t = common::pitch_track_unguarded(geo, Role::Bass, true, method, (lo, hi));
    for b in x.chunks(chunk) {
        t.process(b);
    }
    t.finish();
    t
}

fn st(f: f32) -> f32 {
    69.0 + 12.0 * (f / 440.0).log2()
}

#[test]
fn offline_the_mix_bass_range_bottom_comes_from_its_sure_hops() {
    let x = line_with_thumps();
    let t = track(PitchMethod::Learned, Mode::Offline, &x, 4096);
    let conf = t.pitch_confidence();
    assert_eq!(conf.len(), t.f0.len());
    // The thumps are tracked under the line and the tracker is unsure of them; it is sure
    // of two thirds of the line.
    let (mut low, mut low_unsure, mut line, mut line_sure) = (0, 0, 0, 0);
    for (&f, &c) in t.f0.iter().zip(conf) {
        if f <= 0.0 {
            continue;
        }
        if st(f) < 38.5 {
            low += 1;
            low_unsure += usize::from(c < common::tuning().mix_bass_sure);
        } else {
            line += 1;
            line_sure += usize::from(c >= common::tuning().mix_bass_sure);
        }
    }
    assert!(
        low >= 80 && low_unsure == low,
        "{low_unsure} of {low} thump hops unsure"
    );
    assert!(
        line_sure * 3 >= line * 2,
        "{line_sure} of {line} line hops sure"
    );
    let sure: Vec<bool> = conf
        .iter()
        .map(|&c| c >= common::tuning().mix_bass_sure)
        .collect();
    let kept = |sure: &[bool]| {
        range_quantiles_kept_or_sure(
            &t.f0,
            &[],
            sure,
            common::tuning().follow_range_quantile,
            common::tuning().mix_bass_held_hops,
            common::tuning().held_tol_st,
            common::tuning().mix_bass_shadow_hops,
            common::tuning().held_min_share,
            common::tuning().held_min_hops,
        )
    };
    let range = kept(&[]);
    let narrowed = narrow_range(
        range,
        kept(&sure),
        common::tuning().mix_bass_sure_margin_st,
        f32::INFINITY,
    );
    assert_eq!(t.hop_levels, levels(&t.f0, narrowed));
    // The rule matters here: the held-note range reaches the thumps, the narrowed one stops
    // a semitone under E2 (MIDI 40), and the top is the line's own.
    let (a, b) = (range.unwrap(), narrowed.unwrap());
    assert!(st(a.0) < 35.0, "held notes from {}", st(a.0));
    assert!((st(b.0) - 39.0).abs() < 0.3, "narrowed from {}", st(b.0));
    assert_eq!(a.1, b.1);
    assert_ne!(t.hop_levels, levels(&t.f0, range));
}

#[test]
fn streaming_the_bottom_is_narrowed_once_the_sure_hops_hold_and_the_harmonic_sum_keeps_the_old_rule(
) {
    let x = line_with_thumps();
    // Streaming: the held-note range without shadows hop by hop and the same range of the
    // sure hops (the tracker's confidence is the same offline and streaming); once the
    // latter holds, the bottom is raised to a semitone under it.
    let conf = track(PitchMethod::Learned, Mode::Offline, &x, 4096)
        .pitch_confidence()
        .to_vec();
    let s = track(PitchMethod::Learned, Mode::Streaming, &x, 4096);
    assert_eq!(conf.len(), s.f0.len());
    let replay = |narrow: bool| {
        let range = || {
            common::mix_bass_held_range(
                RangePrior::Span(common::tuning().bass_prior_span_st),
                common::tuning().follow_prior_fade_hops,
                common::tuning().mix_bass_shadow_hops,
            )
        };
        let (mut r, mut rs) = (range(), range());
        let d = Discretizer::default();
        s.f0.iter()
            .zip(&conf)
            .map(|(&f, &c)| {
                let a = r.update(f);
                let b = rs.update_sure(f, false, c >= common::tuning().mix_bass_sure);
                let range = if narrow && rs.holds() {
                    narrow_range(
                        a,
                        b,
                        common::tuning().mix_bass_sure_margin_st,
                        f32::INFINITY,
                    )
                } else {
                    a
                };
                range.map_or(0, |range| d.level(f, range))
            })
            .collect::<Vec<u8>>()
    };
    let want = replay(true);
    assert_eq!(s.hop_levels, want);
    assert_ne!(want, replay(false), "the rule matters streaming");
    for chunk in [441, 10_000] {
        let c = track(PitchMethod::Learned, Mode::Streaming, &x, chunk);
        assert_eq!(c.hop_levels, want, "chunk {chunk}");
    }
    // The harmonic-sum bass keeps no confidence and the held-note range.
    let h = track(PitchMethod::Shs, Mode::Offline, &x, 4096);
    assert!(h.pitch_confidence().is_empty());
    let range = range_quantiles_kept(
        &h.f0,
        common::tuning().follow_range_quantile,
        common::tuning().mix_bass_held_hops,
        common::tuning().held_tol_st,
        common::tuning().mix_bass_shadow_hops,
        common::tuning().held_min_share,
        common::tuning().held_min_hops,
    );
    assert_eq!(h.hop_levels, levels(&h.f0, range));
}
