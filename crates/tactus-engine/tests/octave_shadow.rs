//! The mix's bass level range without octave shadows
//! (`docs/decisions/0026-mix-bass-range-without-octave-shadows.md`), through the real bass
//! tracker on audio: a mixture's bass track places its levels in the range of its own pitch
//! without the hops whose octave above sounds within 25 hops and outside held notes (the mix
//! bass recipe's held hops on each side; `docs/decisions/0030-mix-bass-range-from-held-notes.md`) (offline and streaming,
//! against `tactus_dsp`'s range functions replayed on the track's pitch), the short low notes
//! in the test line do move the range without that rule, and a clean bass stem keeps the
//! held-note rule.

use tactus_dsp::discretize::{
    range_quantiles, range_quantiles_held, range_quantiles_kept, Discretizer, RangePrior,
};
use tactus_engine::profile::Profile;
use tactus_engine::recipe::Role;
use tactus_engine::track::{Geometry, PitchTrack};
use tactus_engine::{Mode, PitchMethod};

mod common;
use common::{levels, SR};

fn geo(mode: Mode) -> Geometry {
    common::geo(mode, Profile::Full)
}

/// A plucked bass line E2 G2 A2 D3 E3 (0.25 s notes) for about 8 s; after every E2 a 0.12 s
/// E1, the note an octave under it, as a tracker reports a kick's body under the note.
fn line_with_low_octaves() -> Vec<f32> {
    let sr = SR as f32;
    let mut x = vec![0.0f32; SR as usize / 4];
    let mut ph = 0.0f32;
    let mut note = |x: &mut Vec<f32>, st: f32, dur: f32| {
        let f = 440.0 * ((st - 69.0) / 12.0).exp2();
        let n = (dur * sr) as usize;
        for i in 0..n {
            ph += std::f32::consts::TAU * f / sr;
            let env = 0.4 * (-(i as f32) / (0.5 * sr)).exp();
            x.push(env * (ph.sin() + 0.6 * (2.0 * ph).sin() + 0.3 * (3.0 * ph).sin()));
        }
    };
    for _ in 0..6 {
        for st in [40.0f32, 43.0, 45.0, 50.0, 52.0] {
            note(&mut x, st, 0.25);
            if st == 40.0 {
                note(&mut x, 28.0, 0.12);
            }
        }
    }
    x.extend(std::iter::repeat_n(0.0, SR as usize / 4));
    x
}

fn track(mode: Mode, mixture: bool, register: bool, x: &[f32], chunk: usize) -> PitchTrack {
    let (lo, hi) = tactus_dsp::Stem::Bass.pitch_range_hz().unwrap();
    let mut t = common::pitch_track(geo(mode), Role::Bass, mixture, PitchMethod::Shs, (lo, hi));
    if register {
        t.set_register_prior(common::tuning().bass_register_hz)
            .unwrap();
    }
    for b in x.chunks(chunk) {
        t.process(b);
    }
    t.finish();
    t
}

#[test]
fn a_mixtures_bass_range_leaves_out_its_octave_shadows_offline() {
    let x = line_with_low_octaves();
    let t = track(Mode::Offline, true, false, &x, 4096);
    let voiced = t.f0.iter().filter(|&&f| f > 0.0).count();
    let low = t.f0.iter().filter(|&&f| f > 0.0 && f < 48.0).count();
    assert!(voiced > 400, "the line is tracked: {voiced} voiced hops");
    assert!(
        low * 100 > voiced,
        "the E1 notes are tracked: {low} of {voiced}"
    );
    let kept = range_quantiles_kept(
        &t.f0,
        common::tuning().follow_range_quantile,
        common::tuning().mix_bass_held_hops,
        common::tuning().held_tol_st,
        common::tuning().mix_bass_shadow_hops,
        common::tuning().held_min_share,
        common::tuning().held_min_hops,
    );
    assert_eq!(t.hop_levels, levels(&t.f0, kept));
    // The rule matters here: the plain range reaches the E1 notes and moves the levels.
    let plain = range_quantiles(&t.f0, common::tuning().follow_range_quantile);
    assert!(
        plain.unwrap().0 < 48.0 && kept.unwrap().0 > 75.0,
        "{plain:?} {kept:?}"
    );
    assert_ne!(t.hop_levels, levels(&t.f0, plain));
    // A clean bass stem keeps the held-note rule and no shadow rule.
    let c = track(Mode::Offline, false, false, &x, 4096);
    let held = range_quantiles_held(
        &c.f0,
        common::tuning().follow_range_quantile,
        common::tuning().clean_bass_held_hops,
        common::tuning().held_tol_st,
        common::tuning().held_min_share,
        common::tuning().held_min_hops,
    );
    assert_eq!(c.hop_levels, levels(&c.f0, held));
}

#[test]
fn a_mixtures_streaming_bass_range_leaves_out_its_octave_shadows_hop_by_hop() {
    let x = line_with_low_octaves();
    for register in [false, true] {
        let t = track(Mode::Streaming, true, register, &x, 4096);
        let prior = if register {
            (
                RangePrior::Register(
                    common::tuning().bass_register_hz.0,
                    common::tuning().bass_register_hz.1,
                ),
                common::tuning().register_fade_hops,
            )
        } else {
            (
                RangePrior::Span(common::tuning().bass_prior_span_st),
                common::tuning().follow_prior_fade_hops,
            )
        };
        let oracle = |w: usize| {
            let mut r = common::mix_bass_held_range(prior.0, prior.1, w);
            let d = Discretizer::default();
            t.f0.iter()
                .map(|&f| r.update(f).map_or(0, |range| d.level(f, range)))
                .collect::<Vec<u8>>()
        };
        assert_eq!(
            t.hop_levels,
            oracle(common::tuning().mix_bass_shadow_hops),
            "register {register}"
        );
        assert_ne!(
            t.hop_levels,
            oracle(0),
            "register {register}: the rule matters"
        );
        for chunk in [1, 441, 10_000] {
            let c = track(Mode::Streaming, true, register, &x, chunk);
            assert_eq!(
                c.hop_levels, t.hop_levels,
                "register {register} chunk {chunk}"
            );
            assert_eq!(c.bins, t.bins, "register {register} chunk {chunk}");
        }
    }
}
