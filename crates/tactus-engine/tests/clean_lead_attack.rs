//! A lead on its own stem (`docs/decisions/0035-clean-lead-note-changes-at-the-attack.md`): the
//! harmonic-sum tracker reports a late note change from the foot of the attack
//! (`tactus_dsp::shs` step 9, `CLEAN_LEAD_ATTACK_RISE_DB`), the levels and the pattern read
//! that pitch, and the note onsets read the decoded pitch before the alignment
//! (`PitchTrack::note_f0`), offline and streaming, for any chunking. A lead on a band of the
//! mix is left alone.

use tactus_engine::notes::{NoteRole, PitchNotes};
use tactus_engine::profile::Profile;
use tactus_engine::recipe::Role;
use tactus_engine::track::PitchTrack;
use tactus_engine::{Mode, NoteRule, PitchMethod};

mod common;
use common::SR;

/// A choir-like lead: each note's harmonics fade in over 100 ms while the previous note's
/// release rings on (time constant 0.3 s). The truth: each note from its start.
fn choir_lead(midi: &[f64], note_s: f64) -> (Vec<f32>, Vec<f64>) {
    let sr = SR as f64;
    let per = (note_s * sr) as usize;
    let n = per * midi.len() + per / 2;
    let (mut x, mut truth) = (vec![0f32; n], vec![0f64; n]);
    for (k, &m) in midi.iter().enumerate() {
        let f = 440.0 * ((m - 69.0) / 12.0f64).exp2();
        for i in 0..n - k * per {
            let t = i as f64 / sr;
            let env = if i < per {
                (t / 0.1).min(1.0)
            } else {
                (-(t - note_s) / 0.3).exp()
            };
            let mut s = 0.0;
            for h in 1..=10 {
                s += (std::f64::consts::TAU * f * h as f64 * t + h as f64).sin() / h as f64;
            }
            x[k * per + i] += (0.1 * env * s) as f32;
        }
        truth[k * per..(k + 1) * per].fill(f);
    }
    (x, truth)
}

fn track(mode: Mode, mixture: bool, x: &[f32], chunk: usize) -> (PitchTrack, Vec<bool>) {
    let (lo, hi) = tactus_dsp::Stem::Vocals.pitch_range_hz().unwrap();
    let geo = common::geo(mode, Profile::Full);
    let mut t = common::pitch_track(geo, Role::Lead, mixture, PitchMethod::Shs, (lo, hi));
    let role = NoteRole {
        plucked_mix: false,
        clean_lead: !mixture,
    };
    let mut notes = PitchNotes::new(geo, &t, NoteRule::Attack, role).unwrap();
    for b in x.chunks(chunk) {
        t.process(b);
        notes.update(&t);
    }
    t.finish();
    notes.update(&t);
    notes.finish(&t);
    (t, notes.beats.onsets.clone())
}

#[test]
fn a_clean_leads_late_changes_move_to_the_attack_and_its_onsets_read_the_decoded_pitch() {
    let (x, truth) = choir_lead(&[67.0, 69.0, 65.0, 72.0, 67.0, 74.0, 71.0, 76.0], 0.5);
    for mode in [Mode::Offline, Mode::Streaming] {
        let (t, onsets) = track(mode, false, &x, 4096);
        let (f0, dec) = (&t.f0, t.note_f0());
        assert_eq!(f0.len(), dec.len());
        let hop = t.hop();
        let right = |f: &[f32]| {
            f.iter()
                .enumerate()
                .filter(|&(i, &v)| {
                    let tr = truth.get(i * hop).copied().unwrap_or(0.0);
                    tr > 0.0 && v > 0.0 && (1200.0 * (v as f64 / tr).log2()).abs() <= 50.0
                })
                .count()
        };
        let (a, d) = (right(f0), right(dec));
        assert!(
            a >= d + 20,
            "{mode:?}: {a} right hops aligned against {d} decoded"
        );
        // Only the pitch moves: where the two differ, both are voiced.
        let moved = f0.iter().zip(dec).filter(|(p, q)| p != q).count();
        assert!(moved >= 20, "{mode:?}: {moved} hops moved");
        assert!(f0
            .iter()
            .zip(dec)
            .all(|(p, q)| p == q || (*p > 0.0 && *q > 0.0)));
        // Note onsets read the decoded pitch: the detector by hand over it gives them
        // exactly, and over the aligned pitch it would not.
        let cfg = NoteRule::Attack.config(
            Profile::Full,
            NoteRole {
                plucked_mix: false,
                clean_lead: true,
            },
        );
        let want = tactus_dsp::notes::note_onsets_offline_level(dec, &t.level_db, cfg).unwrap();
        assert_eq!(onsets, want, "{mode:?}: onsets of the decoded pitch");
        let other = tactus_dsp::notes::note_onsets_offline_level(f0, &t.level_db, cfg).unwrap();
        assert_ne!(
            other, want,
            "{mode:?}: the aligned pitch gives other onsets here"
        );
        // The aligned pitch is the guide of rule 6 (`NoteConfig::guide_back_hops`, off in
        // the engine: its held-out gain stayed under the adoption bar); turned on by hand, it moves
        // this cross-fading lead's onsets towards the notes' starts.
        assert_eq!(t.note_guide(), &f0[..]);
        let guided = tactus_dsp::notes::NoteConfig {
            guide_back_hops: 5,
            ..cfg
        };
        let g =
            tactus_dsp::notes::note_onsets_offline_guided(dec, &t.level_db, f0, guided).unwrap();
        let err = |o: &[bool]| -> usize {
            let per = (0.5 * SR as f64) as usize;
            (0..o.len())
                .filter(|&i| o[i])
                .map(|i| {
                    let s = i * hop;
                    let k = (s + per / 2) / per;
                    s.abs_diff(k * per)
                })
                .sum()
        };
        assert_ne!(g, want, "{mode:?}: the guide moves onsets here");
        assert_eq!(
            g.iter().filter(|&&o| o).count(),
            want.iter().filter(|&&o| o).count()
        );
        assert!(
            err(&g) < err(&want),
            "{mode:?}: guided onsets {} samples off in all, decoded {}",
            err(&g),
            err(&want)
        );
        if mode == Mode::Streaming {
            for chunk in [1, 441, 10_000] {
                let (c, o) = track(mode, false, &x, chunk);
                assert_eq!(c.f0, t.f0, "chunk {chunk}");
                assert_eq!(c.note_f0(), t.note_f0(), "chunk {chunk}");
                assert_eq!(o, onsets, "chunk {chunk}");
                assert_eq!(c.bins, t.bins, "chunk {chunk}");
            }
        }
    }
    // A band of the mix keeps one pitch.
    let (m, _) = track(Mode::Offline, true, &x, 4096);
    assert_eq!(m.note_f0(), &m.f0[..]);
    assert!(m.note_guide().is_empty());
}
