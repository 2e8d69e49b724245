//! A pitch track moved earlier ([`PitchTrack::set_advance_hops`], what the engine does for the
//! spectral separator's bass and vocals): the advanced track is the plain one shifted by
//! exactly its hops (checked against that obvious oracle), it states the shift as latency
//! (checked with a step fed in small blocks: no hop is decided before its stated latency
//! has arrived, to within one decimated sample, and the step's first voiced hop is decided within one hop of it), streaming
//! is chunk-invariant, and the engine turns it on only where it belongs.

use tactus_engine::profile::{self, Profile};
use tactus_engine::recipe::Role;
use tactus_engine::track::Geometry;
use tactus_engine::{Engine, EngineConfig, Mode, PitchMethod, SeparatorChoice};

mod common;
use common::SR;

fn geo(mode: Mode) -> Geometry {
    common::geo(mode, Profile::Full)
}

/// 0.5 s of silence, then a voice-like harmonic tone stepping 220 → 330 → 262 Hz (0.6 s
/// each), then 0.4 s of silence.
fn steps() -> Vec<f32> {
    let sr = SR as f32;
    let mut x = vec![0.0f32; SR as usize / 2];
    let mut ph = 0.0f32;
    for f in [220.0f32, 330.0, 262.0] {
        for _ in 0..(0.6 * sr) as usize {
            ph += std::f32::consts::TAU * f / sr;
            x.push(0.3 * (ph.sin() + 0.5 * (2.0 * ph).sin() + 0.3 * (3.0 * ph).sin()));
        }
    }
    x.extend(std::iter::repeat_n(0.0, (0.4 * sr) as usize));
    x
}

/// Runs a vocals-range SHS track over `x` in blocks of `chunk`; returns its f0 per hop.
fn track(mode: Mode, advance: usize, x: &[f32], chunk: usize) -> (Vec<f32>, usize, usize) {
    let mut t = common::pitch_track(
        geo(mode),
        Role::Lead,
        true,
        PitchMethod::Shs,
        (70.0, 1400.0),
    );
    t.set_advance_hops(advance);
    for b in x.chunks(chunk) {
        t.process(b);
    }
    t.finish();
    (t.f0.clone(), t.latency_samples(), t.hop())
}

/// The oracle: the plain track without its first `k` hops, padded unvoiced at the end.
fn shifted(f: &[f32], k: usize) -> Vec<f32> {
    let mut out: Vec<f32> = f[k.min(f.len())..].to_vec();
    out.resize(f.len(), 0.0);
    out
}

#[test]
fn an_advanced_track_is_the_plain_one_shifted_by_its_hops() {
    let x = steps();
    let (plain, lat0, hop) = track(Mode::Offline, 0, &x, x.len());
    for k in [1, common::tuning().spectral_pitch_advance_hops, 7] {
        let (adv, lat, _) = track(Mode::Offline, k, &x, x.len());
        // Offline the gate, the fences and the range see the same values (the padding is
        // unvoiced and below the gate), so the shift is exact.
        assert_eq!(adv, shifted(&plain, k), "advance {k}");
        assert_eq!(lat, lat0 + k * hop, "advance {k}: latency");
    }
    // The step is found at all: the plain track voices the tone and not the silence.
    let first = plain.iter().position(|&f| f > 0.0).unwrap();
    let onset_hop = (SR as usize / 2) / hop;
    assert!(
        first.abs_diff(onset_hop) <= 10,
        "first voiced hop {first} vs {onset_hop}"
    );
}

#[test]
fn streaming_advanced_track_is_chunk_invariant_and_shifted() {
    let x = steps();
    let k = common::tuning().spectral_pitch_advance_hops;
    let (whole, _, _) = track(Mode::Streaming, k, &x, x.len());
    for chunk in [1, 97, 441, 4096] {
        let (c, _, _) = track(Mode::Streaming, k, &x, chunk);
        assert_eq!(c, whole, "chunk {chunk}");
    }
    // The streaming statistics run over the shifted sequence: the voiced step moves by
    // exactly k hops (its first voiced hop and its pitches).
    let (plain, _, _) = track(Mode::Streaming, 0, &x, x.len());
    let fa = whole.iter().position(|&f| f > 0.0).unwrap();
    let fp = plain.iter().position(|&f| f > 0.0).unwrap();
    assert_eq!(fa + k, fp);
    assert_eq!(&whole[fa..fa + 50], &plain[fp..fp + 50]);
}

#[test]
fn an_advanced_track_decides_nothing_before_its_stated_latency() {
    // A step fed in blocks of 64 samples: after `fed` samples, every decided hop `i`
    // satisfies `i·hop + latency ≤ fed` (nothing is decided early), and the step's first
    // voiced hop is decided within one hop and one block of its stated latency.
    let x = steps();
    let k = common::tuning().spectral_pitch_advance_hops;
    let mut t = common::pitch_track(
        geo(Mode::Streaming),
        Role::Lead,
        true,
        PitchMethod::Shs,
        (70.0, 1400.0),
    );
    t.set_advance_hops(k);
    let (hop, lat) = (t.hop(), t.latency_samples());
    // The tracker counts decimated samples: its decisions move in steps of `dec` engine
    // samples, so the stated latency holds to within one such step.
    let dec = t.decimation();
    let mut fed = 0;
    let mut first_seen = None;
    for b in x.chunks(64) {
        t.process(b);
        fed += b.len();
        let n = t.f0.len();
        if n > 0 {
            assert!(
                (n - 1) * hop + lat < fed + dec,
                "hop {} decided at {fed} (latency {lat})",
                n - 1
            );
        }
        if first_seen.is_none() {
            if let Some(i) = t.f0.iter().position(|&f| f > 0.0) {
                first_seen = Some((i, fed));
            }
        }
    }
    let (i, at) = first_seen.expect("the step is voiced");
    assert!(
        at <= i * hop + lat + hop + 64,
        "hop {i} decided at {at}, stated latency {lat}"
    );
}

#[test]
fn the_engine_advances_only_the_spectral_separators_tracks_and_not_live() {
    // The pitch group's tracker stage in the latency report: the spectral separator's
    // tracks state 3 hops (10 ms each) more than the same tracks on the mix itself
    // (`none`), plus the learned bass salience's look-ahead; the live profile adds no advance.
    let tracker = |separator, profile| {
        let e = Engine::new(EngineConfig {
            separator,
            profile,
            pitch: PitchMethod::default(),
            ..EngineConfig::default()
        })
        .unwrap();
        let paths = e.latency_paths();
        let (_, pitch) = paths.iter().find(|(g, _)| g == "pitch").unwrap();
        let (name, l) = pitch
            .iter()
            .find(|(n, _)| n.contains(" pitch "))
            .unwrap()
            .clone();
        (name, l)
    };
    let hop = SR as usize / 100;
    let (name, spectral) = tracker(SeparatorChoice::Spectral, Profile::Full);
    let (_, none) = tracker(SeparatorChoice::None, Profile::Full);
    // The spectral separator's bass is also the learned salience, whose network looks
    // `future` hops ahead (tactus_dsp::bassnet); on the mix itself it is the harmonic sum.
    let future = tactus_dsp::bassnet::BassNet::embedded().future();
    assert_eq!(
        spectral,
        none + (common::tuning().spectral_pitch_advance_hops + future) * hop,
        "{name}"
    );
    assert!(name.contains("separator's note lag"), "{name}");
    // Live, the spectral separator's bass is the live model (no look-ahead): it states half
    // its frame and its Viterbi lag, and the separator's note lag adds nothing.
    let (live_name, live_spectral) = tracker(SeparatorChoice::Spectral, Profile::Live);
    let half_frame = (profile::LIVE_BASS_NET_FRAME_S * f64::from(SR) / 2.0).round() as usize;
    assert_eq!(
        live_spectral,
        half_frame + profile::LIVE_BASS_LAG_HOPS * hop,
        "{live_name}"
    );
    assert!(!live_name.contains("separator's note lag"), "{live_name}");
    // On the mix itself (no separator) the live bass is YIN, with no advance either.
    let (none_name, live_none) = tracker(SeparatorChoice::None, Profile::Live);
    assert!(!none_name.contains("separator's note lag"), "{none_name}");
    assert!(live_none < live_spectral, "{none_name}");
}
