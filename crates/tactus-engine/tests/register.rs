//! The register prior of a bass or lead stem's streaming range ([`PitchTrack::set_register_prior`],
//! `docs/decisions/0022-streaming-levels-from-a-register-prior.md`), through the real bass tracker on audio:
//! the streaming levels are the discretizer's levels of the track's own pitch within
//! `tactus_dsp`'s register-padded held range (the oracle, hop by hop), they differ from the
//! span prior's on a line that opens on its lowest note, they are chunk-invariant, and the
//! offline output does not change.

use tactus_dsp::discretize::{Discretizer, HeldRange, RangePrior};
use tactus_engine::profile::Profile;
use tactus_engine::recipe::Role;
use tactus_engine::track::{Geometry, PitchTrack};
use tactus_engine::{Mode, PitchMethod};

mod common;
use common::SR;

fn geo(mode: Mode) -> Geometry {
    common::geo(mode, Profile::Full)
}

/// A plucked-bass-like line that opens on its lowest note and climbs later, as many bass
/// lines do: E2 G2 A2 (two bars' worth, 0.25 s notes), then up to E3 and G3.
fn climbing_line() -> Vec<f32> {
    let sr = SR as f32;
    let mut x = vec![0.0f32; SR as usize / 4];
    let mut ph = 0.0f32;
    let notes = [
        40.0f32, 43.0, 45.0, 40.0, 43.0, 45.0, 40.0, 43.0, 45.0, 40.0, 43.0, 45.0,
    ]
    .into_iter()
    .chain([52.0, 55.0, 52.0, 45.0, 40.0, 55.0, 52.0, 40.0]);
    for st in notes {
        let f = 440.0 * ((st - 69.0) / 12.0).exp2();
        let n = (0.25 * sr) as usize;
        for i in 0..n {
            ph += std::f32::consts::TAU * f / sr;
            let env = 0.4 * (-(i as f32) / (0.4 * sr)).exp();
            x.push(env * (ph.sin() + 0.6 * (2.0 * ph).sin() + 0.3 * (3.0 * ph).sin()));
        }
    }
    x.extend(std::iter::repeat_n(0.0, SR as usize / 4));
    x
}

/// A clean bass track over `x` in blocks of `chunk`, with the register prior or not.
fn track(mode: Mode, register: bool, x: &[f32], chunk: usize) -> PitchTrack {
    let (lo, hi) = tactus_dsp::Stem::Bass.pitch_range_hz().unwrap();
    let mut t = common::pitch_track(geo(mode), Role::Bass, false, PitchMethod::Shs, (lo, hi));
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
fn streaming_levels_are_the_register_padded_range_levels_of_the_tracks_own_pitch() {
    let x = climbing_line();
    let t = track(Mode::Streaming, true, &x, 4096);
    // The oracle: the track's own pitch (after gate and fences), hop by hop through the
    // register-padded held range and the discretizer.
    let mut r = HeldRange::with_prior(
        RangePrior::Register(
            common::tuning().bass_register_hz.0,
            common::tuning().bass_register_hz.1,
        ),
        common::tuning().register_fade_hops,
        common::tuning().follow_range_quantile,
        common::tuning().clean_bass_held_hops,
        common::tuning().held_tol_st,
        common::tuning().held_min_share,
        common::tuning().held_min_hops,
    )
    .unwrap();
    let d = Discretizer::default();
    let want: Vec<u8> =
        t.f0.iter()
            .map(|&f| r.update(f).map_or(0, |range| d.level(f, range)))
            .collect();
    assert_eq!(t.hop_levels, want);
    let voiced = t.f0.iter().filter(|&&f| f > 0.0).count();
    assert!(voiced > 400, "the line is tracked: {voiced} voiced hops");
    // The first phrase (E2 G2 A2) sits at the bottom of the levels: its E2 hops never reach
    // the middle level, where the span prior centres them.
    let span = track(Mode::Streaming, false, &x, 4096);
    let first_e2: Vec<usize> = (0..t.f0.len())
        .filter(|&i| (t.f0[i] - 82.4).abs() < 2.0)
        .take(20)
        .collect();
    assert!(first_e2.len() == 20, "E2 is tracked");
    for &i in &first_e2 {
        assert!(t.hop_levels[i] <= 3, "hop {i}: level {}", t.hop_levels[i]);
        assert!(
            span.hop_levels[i] >= 4,
            "hop {i}: span level {}",
            span.hop_levels[i]
        );
    }
}

#[test]
fn register_prior_streaming_is_chunk_invariant_and_offline_is_unchanged() {
    let x = climbing_line();
    let whole = track(Mode::Streaming, true, &x, x.len());
    for chunk in [1, 100, 441, 4097] {
        let c = track(Mode::Streaming, true, &x, chunk);
        assert_eq!(c.hop_levels, whole.hop_levels, "chunk {chunk}");
        assert_eq!(c.bins, whole.bins, "chunk {chunk}");
    }
    let a = track(Mode::Offline, true, &x, 4096);
    let b = track(Mode::Offline, false, &x, 4096);
    assert_eq!(a.hop_levels, b.hop_levels);
    assert_eq!(a.bins, b.bins);
    assert_eq!(a.f0, b.f0);
    // A register that is not one is refused.
    let (lo, hi) = tactus_dsp::Stem::Bass.pitch_range_hz().unwrap();
    let mut t = common::pitch_track(
        geo(Mode::Streaming),
        Role::Bass,
        false,
        PitchMethod::Shs,
        (lo, hi),
    );
    assert!(t.set_register_prior((300.0, 40.0)).is_err());
    assert!(t.set_register_prior((0.0, 40.0)).is_err());
}
