//! Note onsets of a melodic stem on audio (`tactus_engine::notes`): a bass line that repeats
//! its notes, through the real pitch track and the note detector, offline and streaming in
//! any chunking, against the notes' known start times.

use tactus_engine::notes::{NoteRole, NoteRule, NoteTrack, PitchNotes};
use tactus_engine::profile::Profile;
use tactus_engine::recipe::Role;
use tactus_engine::{Mode, PitchMethod};

mod common;
use common::{geo, SR};

/// A plucked bass line: 0.3 s of silence, then notes of 0.35 s each (harmonic tone, 5 ms
/// attack, exponential decay with 0.25 s time constant, cut to 25 % by the next pluck), most
/// of them repeats of the note before. Returns the signal and the notes' start times.
fn plucked_line() -> (Vec<f32>, Vec<f64>) {
    let sr = SR as f32;
    let pitches = [98.0f32, 98.0, 98.0, 110.0, 110.0, 98.0, 98.0, 73.4];
    let note = (0.35 * sr) as usize;
    let mut x = vec![0.0f32; (0.3 * sr) as usize];
    let mut starts = Vec::new();
    for &f in &pitches {
        starts.push(x.len() as f64 / SR as f64);
        let mut ph = 0.0f32;
        for i in 0..note {
            let t = i as f32 / sr;
            let env = (t / 0.005).min(1.0) * (-t / 0.25).exp();
            ph += std::f32::consts::TAU * f / sr;
            x.push(0.3 * env * (ph.sin() + 0.5 * (2.0 * ph).sin() + 0.25 * (3.0 * ph).sin()));
        }
    }
    x.extend(std::iter::repeat_n(0.0, (0.4 * sr) as usize));
    (x, starts)
}

/// The bass chain's pitch track and note onsets over `x` in blocks of `chunk`.
fn onsets(mode: Mode, profile: Profile, rule: NoteRule, x: &[f32], chunk: usize) -> Vec<f64> {
    let g = geo(mode, profile);
    let mut p = common::pitch_track(g, Role::Bass, false, PitchMethod::Shs, (35.0, 400.0));
    let mut n = PitchNotes::new(g, &p, rule, NoteRole::default()).unwrap();
    for b in x.chunks(chunk) {
        p.process(b);
        n.update(&p);
    }
    p.finish();
    n.finish(&p);
    NoteTrack::Pitch(n).onset_times()
}

/// A sung-like line for the vocals range: notes of 0.4 s with a 40 ms attack, each after a
/// 60 ms "consonant" (the level dips to a tenth, the pitch stays), most of them repeats.
fn sung_line() -> (Vec<f32>, Vec<f64>) {
    let sr = SR as f32;
    let pitches = [220.0f32, 220.0, 247.0, 247.0, 247.0, 220.0, 196.0, 196.0];
    let note = (0.4 * sr) as usize;
    let dip = (0.06 * sr) as usize;
    let mut x = vec![0.0f32; (0.3 * sr) as usize];
    let mut starts = Vec::new();
    let mut ph = 0.0f32;
    for &f in &pitches {
        starts.push(x.len() as f64 / SR as f64);
        for i in 0..dip + note {
            let env = if i < dip {
                0.1
            } else {
                0.1 + 0.9 * ((i - dip) as f32 / sr / 0.04).min(1.0)
            };
            ph += std::f32::consts::TAU * f / sr;
            x.push(0.2 * env * (ph.sin() + 0.5 * (2.0 * ph).sin() + 0.3 * (3.0 * ph).sin()));
        }
    }
    x.extend(std::iter::repeat_n(0.0, (0.4 * sr) as usize));
    (x, starts)
}

/// The vocals chain on a clean stem (the melody tracker) and its note onsets.
fn lead_onsets(mode: Mode, role: NoteRole, x: &[f32], chunk: usize) -> Vec<f64> {
    let g = geo(mode, Profile::Full);
    let mut p = common::pitch_track(g, Role::Lead, false, PitchMethod::Shs, (80.0, 1000.0));
    let mut n = PitchNotes::new(g, &p, NoteRule::Attack, role).unwrap();
    for b in x.chunks(chunk) {
        p.process(b);
        n.update(&p);
    }
    p.finish();
    n.finish(&p);
    NoteTrack::Pitch(n).onset_times()
}

#[test]
fn a_clean_lead_is_early_not_late_offline_and_streaming_in_any_chunking() {
    let (x, starts) = sung_line();
    let lead = NoteRole {
        plucked_mix: false,
        clean_lead: true,
    };
    let off = lead_onsets(Mode::Offline, lead, &x, x.len());
    assert_eq!(
        hits(&off, &starts, 0.05),
        starts.len(),
        "{off:?} vs {starts:?}"
    );
    assert_eq!(off.len(), starts.len(), "{off:?}");
    // The default role finds the same notes, each at or after the clean lead's onset (the
    // moves only go back, at most 3 hops).
    let plain = lead_onsets(Mode::Offline, NoteRole::default(), &x, x.len());
    assert_eq!(plain.len(), off.len(), "{plain:?} vs {off:?}");
    for (p, o) in plain.iter().zip(&off) {
        assert!(*p >= *o - 1e-9 && *p - *o <= 0.0301, "{plain:?} vs {off:?}");
    }
    // Here every re-attack sits 20–30 ms after its consonant's start: the moves bring the
    // onsets closer to the notes' starts.
    let moved = plain.iter().zip(&off).filter(|(p, o)| **p > **o).count();
    assert!(moved >= starts.len() / 2, "{plain:?} vs {off:?}");
    let err = |v: &[f64]| -> f64 { v.iter().zip(&starts).map(|(a, b)| (a - b).abs()).sum() };
    assert!(
        err(&off) < err(&plain),
        "{plain:?} vs {off:?} vs {starts:?}"
    );
    // Streaming: the same onsets (same hops, same rule), in any chunking.
    let whole = lead_onsets(Mode::Streaming, lead, &x, x.len());
    assert_eq!(whole, off);
    for chunk in [1, 64, 441, 4096] {
        assert_eq!(
            lead_onsets(Mode::Streaming, lead, &x, chunk),
            whole,
            "chunk {chunk}"
        );
    }
}

fn hits(got: &[f64], want: &[f64], tol: f64) -> usize {
    want.iter()
        .filter(|&&w| got.iter().any(|&g| (g - w).abs() <= tol))
        .count()
}

#[test]
fn repeated_plucks_are_notes_offline_and_streaming_in_any_chunking() {
    let (x, starts) = plucked_line();
    let off = onsets(Mode::Offline, Profile::Full, NoteRule::Attack, &x, x.len());
    // Every note within 50 ms (the metric's window), nothing else.
    assert_eq!(
        hits(&off, &starts, 0.05),
        starts.len(),
        "{off:?} vs {starts:?}"
    );
    assert_eq!(off.len(), starts.len(), "{off:?}");
    // The pitch alone finds only the pitch changes (98, 110, 98, 73.4 Hz).
    let pitch = onsets(Mode::Offline, Profile::Full, NoteRule::Pitch, &x, x.len());
    assert!(pitch.len() <= 4, "{pitch:?}");
    let whole = onsets(
        Mode::Streaming,
        Profile::Full,
        NoteRule::Attack,
        &x,
        x.len(),
    );
    assert_eq!(hits(&whole, &starts, 0.05), starts.len(), "{whole:?}");
    for chunk in [1, 64, 97, 441, 4096] {
        let c = onsets(Mode::Streaming, Profile::Full, NoteRule::Attack, &x, chunk);
        assert_eq!(c, whole, "chunk {chunk}");
    }
}

#[test]
fn the_stated_latency_of_each_rule() {
    let g = geo(Mode::Streaming, Profile::Full);
    let p = common::pitch_track(g, Role::Bass, false, PitchMethod::Shs, (35.0, 400.0));
    let hop = p.hop();
    let lat = |profile, rule| {
        let plucked = NoteRole {
            plucked_mix: true,
            clean_lead: false,
        };
        let lead = NoteRole {
            plucked_mix: false,
            clean_lead: true,
        };
        let a = PitchNotes::new(geo(Mode::Streaming, profile), &p, rule, plucked)
            .unwrap()
            .own_latency_samples();
        // A clean lead's moves stay inside the attack search: the same latency.
        let b = PitchNotes::new(geo(Mode::Streaming, profile), &p, rule, lead)
            .unwrap()
            .own_latency_samples();
        assert_eq!(a, b);
        a
    };
    // Pitch: the stability window (4 hops) less one. Attack: the same, plus the 8 hops an
    // onset may still move back to its attack. Live keeps the pitch rule's latency.
    assert_eq!(lat(Profile::Full, NoteRule::Pitch), 3 * hop);
    assert_eq!(lat(Profile::Full, NoteRule::Attack), 11 * hop);
    assert_eq!(lat(Profile::Live, NoteRule::Attack), 3 * hop);
    assert_eq!(lat(Profile::Live, NoteRule::Pitch), 3 * hop);
}

#[test]
fn streaming_decides_no_onset_before_its_stated_latency() {
    // Fed in 64-sample blocks: an onset at time t is in the output only once
    // t + the pitch track's latency + the detector's has been fed.
    let (x, starts) = plucked_line();
    let g = geo(Mode::Streaming, Profile::Full);
    let mut p = common::pitch_track(g, Role::Bass, false, PitchMethod::Shs, (35.0, 400.0));
    let mut n = PitchNotes::new(g, &p, NoteRule::Attack, NoteRole::default()).unwrap();
    let lat = n.latency_samples();
    assert_eq!(lat, p.latency_samples() + n.own_latency_samples());
    let dec = p.decimation();
    let mut fed = 0usize;
    let mut seen = 0usize;
    for b in x.chunks(64) {
        p.process(b);
        n.update(&p);
        fed += b.len();
        let times = n.onset_times();
        for &t in &times[seen..] {
            let at = (t * SR as f64).round() as usize;
            assert!(
                at + lat <= fed + dec,
                "onset {t} s out after {fed} samples, latency {lat}"
            );
        }
        seen = times.len();
    }
    assert!(seen >= starts.len() - 1, "{seen} onsets before the end");
}
