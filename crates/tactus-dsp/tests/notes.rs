//! Note onsets from a pitch track and the stem's level (`tactus_dsp::notes`, the `attack`
//! rule): re-attacks inside a held pitch, onsets moved back to their attack, the minimum
//! interval and dropouts that resume a note. The streaming detector is checked against a
//! slow whole-track oracle written from the module docs (plain arrays, no ring buffers),
//! on seeded random tracks and on musical cases with known answers.

use tactus_dsp::notes::{
    note_onsets_offline, note_onsets_offline_guided, note_onsets_offline_level, NoteConfig,
    NoteOnsets, RISE_AHEAD_HOPS, RISE_BEHIND_HOPS,
};
use tactus_dsp::{hz_to_semitones, semitones_to_hz};
use tactus_testkit::Rng;

#[global_allocator]
static A: tactus_testkit::Counting = tactus_testkit::Counting;

/// The rule as the module docs state it, on whole arrays.
fn oracle(f0: &[f32], db: &[f32], c: NoteConfig) -> Vec<bool> {
    oracle_guided(f0, db, &[], c)
}

/// The rule as the module docs state it, with a guide pitch per hop (rule 6).
fn oracle_guided(f0: &[f32], db: &[f32], guide: &[f32], c: NoteConfig) -> Vec<bool> {
    let n = f0.len();
    let semis = |f: &f32| (f.is_finite() && *f > 0.0).then(|| hz_to_semitones(*f));
    let st: Vec<Option<f32>> = f0.iter().map(semis).collect();
    let gst: Vec<Option<f32>> = (0..n).map(|i| guide.get(i).and_then(semis)).collect();
    let lv = |h: isize| -> Option<f32> {
        if h < 0 || h as usize >= n {
            return None;
        }
        db.get(h as usize).copied().filter(|v| v.is_finite())
    };
    let step = |h: isize| -> Option<f32> { Some(lv(h)? - lv(h - 1)?) };
    let rise = |h: isize| -> Option<f32> {
        let mut lo = f32::INFINITY;
        for b in h - RISE_BEHIND_HOPS as isize..h {
            lo = lo.min(lv(b)?);
        }
        let mut hi = f32::NEG_INFINITY;
        for a in h..=h + RISE_AHEAD_HOPS as isize {
            hi = hi.max(lv(a)?);
        }
        Some(hi - lo)
    };
    // The steepest positive step of hops h − 1 ..= h + RISE_AHEAD_HOPS (ties: the earliest).
    let steepest = |h: isize| -> bool {
        let Some(s) = step(h) else { return false };
        if s <= 0.0 || step(h - 1).is_some_and(|p| s <= p) {
            return false;
        }
        (h + 1..=h + RISE_AHEAD_HOPS as isize).all(|a| step(a).is_none_or(|t| s >= t))
    };
    // The foot of the rise attacking at h, decided at hop j: the hop before the run of
    // rising steps that ends at h, at most `backtrack_hops` back, not before
    // j − attack_back_hops nor within the minimum interval of the last onset.
    let foot = |h: usize, j: usize, last: Option<usize>| -> usize {
        if c.backtrack_hops == 0 || c.attack_move_hops.is_some() {
            return h;
        }
        let mut lo = j
            .saturating_sub(c.attack_back_hops)
            .max(h.saturating_sub(c.backtrack_hops));
        if let Some(l) = last {
            lo = lo.max(l + c.min_ioi_hops.max(1));
        }
        // Candidates from h down to lo: the first hop x−1 whose step into it is not a rise.
        let mut x = h;
        while x > lo && x >= 2 && step(x as isize - 1).is_some_and(|s| s > 0.0) {
            x -= 1;
        }
        if x > lo {
            x - 1
        } else {
            x
        }
    };
    let mut out = vec![false; n];
    let mut cur: Option<f32> = None;
    let mut ended: Option<f32> = None;
    let mut unv = usize::MAX / 2;
    let mut last: Option<usize> = None;
    let spaced =
        |last: Option<usize>, h: usize| last.is_none_or(|l| h >= l + c.min_ioi_hops.max(1));
    for j in 0..n {
        let Some(x) = st[j] else {
            unv = unv.saturating_add(1);
            if unv > c.gap_hops && cur.is_some() {
                ended = cur.take();
            }
            continue;
        };
        let gap = unv;
        unv = 0;
        // The stability window: `stable_hops` voiced hops within the tolerance of their median.
        let med = if j + c.stable_hops <= n {
            let w: Option<Vec<f32>> = st[j..j + c.stable_hops].iter().copied().collect();
            w.and_then(|mut w| {
                w.sort_by(f32::total_cmp);
                let m = w[(w.len() - 1) / 2];
                w.iter()
                    .all(|v| (v - m).abs() <= c.tolerance_st)
                    .then_some(m)
            })
        } else {
            None
        };
        let pitch_onset = med.is_some() && cur.is_none_or(|c0| (x - c0).abs() >= c.jump_st);
        if let Some(m) = med.filter(|_| pitch_onset) {
            let resumed = cur.is_none()
                && c.resume_hops > 0
                && c.attack_back_hops > 0
                && gap <= c.resume_hops
                && ended.is_some_and(|p| (m - p).abs() < c.jump_st);
            // Rule 5: a change of note (a note was current) must be attacked.
            let resumed =
                resumed || (c.pitch_needs_attack && c.attack_back_hops > 0 && cur.is_some());
            cur = Some(m);
            if c.attack_back_hops > 0 {
                let from = j.saturating_sub(c.attack_back_hops);
                if last.is_some_and(|l| l >= from) {
                    continue;
                }
                // The steepest attack in the window before the pitch settled (a limited move
                // judges every hop of it, and checks the interval where the onset lands).
                let limit = c.attack_move_hops.map(|m| m.min(c.attack_back_hops));
                let mut best: Option<(usize, f32)> = None;
                for h in from..j {
                    let hi = h as isize;
                    if (limit.is_some() || spaced(last, h))
                        && rise(hi).is_some_and(|r| r >= c.attack_db)
                        && steepest(hi)
                    {
                        let s = step(hi).unwrap();
                        if best.is_none_or(|(_, b)| s > b) {
                            best = Some((h, s));
                        }
                    }
                }
                if let Some((h, _)) = best {
                    let h = match limit {
                        // At most `m` hops back towards the attack; at j if that is too close.
                        Some(m) => {
                            let p = h.max(j.saturating_sub(m));
                            if spaced(last, p) {
                                Some(p)
                            } else {
                                spaced(last, j).then_some(j)
                            }
                        }
                        None => Some(foot(h, j, last)),
                    };
                    if let Some(h) = h {
                        out[h] = true;
                        last = Some(h);
                    }
                    continue;
                }
                if resumed {
                    continue;
                }
            }
            if spaced(last, j) {
                // Rule 6: back over the run of hops before j whose guide holds the new note,
                // at most guide_back_hops and attack_back_hops, not within the interval.
                if c.guide_back_hops > 0 && c.attack_move_hops.is_none() {
                    let mut lo = j
                        .saturating_sub(c.attack_back_hops)
                        .max(j.saturating_sub(c.guide_back_hops));
                    if let Some(l) = last {
                        lo = lo.max(l + c.min_ioi_hops.max(1));
                    }
                    let mut h = j;
                    while h > lo && gst[h - 1].is_some_and(|g| (g - m).abs() <= c.tolerance_st) {
                        h -= 1;
                    }
                    if h < j {
                        out[h] = true;
                        last = Some(h);
                        continue;
                    }
                }
                // No attack: the pitch onset moves `pitch_back_hops` back, not before the
                // attack window nor within the minimum interval.
                let mut h = j;
                if c.pitch_back_hops > 0 && c.attack_move_hops.is_none() {
                    h = j
                        .saturating_sub(c.pitch_back_hops)
                        .max(j.saturating_sub(c.attack_back_hops));
                    if let Some(l) = last {
                        h = h.max(l + c.min_ioi_hops.max(1));
                    }
                }
                out[h] = true;
                last = Some(h);
            }
            continue;
        }
        if let (Some(m), Some(c0)) = (med, cur) {
            cur = Some(c0 + 0.03 * (m - c0));
        }
        if c.reattack_db > 0.0 {
            if let Some(c0) = cur {
                let ji = j as isize;
                if (x - c0).abs() < c.jump_st
                    && spaced(last, j)
                    && last.is_none_or(|l| j >= l + c.reattack_min_hops)
                    && rise(ji).is_some_and(|r| r >= c.reattack_db)
                    && steepest(ji)
                {
                    let h = foot(j, j, last);
                    out[h] = true;
                    last = Some(h);
                }
            }
        }
    }
    out
}

/// Streaming, one hop at a time: checks the stated latency and returns the flags.
fn streamed(f0: &[f32], db: &[f32], c: NoteConfig) -> Vec<bool> {
    streamed_guided(f0, db, &vec![f32::NAN; f0.len()], c)
}

/// Streaming with a guide pitch, one hop at a time: checks the stated latency.
fn streamed_guided(f0: &[f32], db: &[f32], guide: &[f32], c: NoteConfig) -> Vec<bool> {
    let mut d = NoteOnsets::new(c).unwrap();
    let lat = d.latency_hops();
    let mut got = Vec::new();
    for (i, &f) in f0.iter().enumerate() {
        d.push_guided(f, db[i], guide[i], &mut |j, o| {
            assert_eq!(j + lat, i, "hop {j} emitted at hop {i}, latency {lat}");
            assert_eq!(j, got.len());
            got.push(o);
        });
    }
    d.finish(&mut |j, o| {
        assert_eq!(j, got.len());
        got.push(o);
    });
    got
}

/// A guide for a random track: its pitch `lead` hops earlier (an aligned pitch changes
/// before the decoded one), off by a semitone now and then, unvoiced now and then.
fn random_guide(f0: &[f32], seed: u64, lead: usize) -> Vec<f32> {
    let mut r = Rng::new(seed ^ 0x9e37);
    let n = f0.len();
    (0..n)
        .map(|i| {
            let u = (r.next_f32() + 1.0) * 0.5;
            let f = f0[(i + lead).min(n - 1)];
            if u < 0.03 {
                0.0
            } else if u < 0.08 {
                f * 2f32.powf(1.0 / 12.0)
            } else {
                f
            }
        })
        .collect()
}

/// A random track: notes (often repeated) with attacks and decays, dropouts, gaps, glides,
/// level wobble; unknown levels now and then.
fn random_track(seed: u64, n: usize) -> (Vec<f32>, Vec<f32>) {
    let mut r = Rng::new(seed);
    let mut u = move || (r.next_f32() + 1.0) * 0.5;
    let (mut f0, mut db) = (Vec::new(), Vec::new());
    let mut pitch = 45.0f32;
    while f0.len() < n {
        let len = 3 + (u() * 40.0) as usize;
        if u() < 0.5 {
            pitch += ((u() - 0.5) * 10.0).round();
        }
        let peak = -40.0 + u() * 35.0;
        let glide = u() < 0.2;
        for i in 0..len {
            let p = if glide && i < 4 {
                pitch - 2.0 + i as f32 * 0.5
            } else {
                pitch
            };
            let p = p + (u() - 0.5) * 0.3;
            let drop = u() < 0.04;
            f0.push(if drop { 0.0 } else { semitones_to_hz(p) });
            let env = peak - 0.4 * i as f32 + (u() - 0.5) * 3.0;
            db.push(if u() < 0.02 { f32::NAN } else { env });
        }
        let gap = if u() < 0.6 { 0 } else { (u() * 12.0) as usize };
        for _ in 0..gap {
            f0.push(0.0);
            db.push(-70.0 + u() * 10.0);
        }
    }
    f0.truncate(n);
    db.truncate(n);
    (f0, db)
}

fn configs() -> Vec<NoteConfig> {
    let d = NoteConfig::default();
    vec![
        d,
        NoteConfig::pitch_only(),
        NoteConfig {
            attack_back_hops: 0,
            resume_hops: 0,
            ..d
        },
        NoteConfig {
            stable_hops: 6,
            min_ioi_hops: 0,
            attack_back_hops: 16,
            ..d
        },
        NoteConfig {
            reattack_db: 0.0,
            resume_hops: 30,
            ..d
        },
        NoteConfig {
            stable_hops: 1,
            reattack_db: 2.0,
            attack_db: 1.0,
            ..d
        },
        NoteConfig {
            pitch_needs_attack: true,
            ..d
        },
        // The clean lead's moves (tactus-engine's `NoteRole::clean_lead`).
        NoteConfig {
            backtrack_hops: 3,
            pitch_back_hops: 2,
            reattack_min_hops: 25,
            ..d
        },
        NoteConfig {
            reattack_min_hops: 12,
            ..d
        },
        NoteConfig {
            backtrack_hops: 16,
            pitch_back_hops: 16,
            min_ioi_hops: 0,
            ..d
        },
        NoteConfig {
            backtrack_hops: 5,
            pitch_back_hops: 3,
            attack_back_hops: 2,
            ..d
        },
        // Limited moves (the live profile's: in place), with the moves they switch off.
        NoteConfig {
            pitch_needs_attack: true,
            attack_move_hops: Some(0),
            ..d
        },
        NoteConfig {
            attack_move_hops: Some(2),
            backtrack_hops: 3,
            pitch_back_hops: 2,
            guide_back_hops: 4,
            ..d
        },
        NoteConfig {
            pitch_needs_attack: true,
            attack_move_hops: Some(30),
            min_ioi_hops: 0,
            ..d
        },
    ]
}

#[test]
fn streaming_equals_the_slow_oracle_on_random_tracks() {
    for c in configs() {
        let mut onsets = 0;
        for seed in 0..12u64 {
            let n = 50 + (seed as usize * 97) % 900;
            let (f0, db) = random_track(seed, n);
            let want = oracle(&f0, &db, c);
            let got = streamed(&f0, &db, c);
            assert_eq!(got.len(), n);
            let diff: Vec<usize> = (0..n).filter(|&i| got[i] != want[i]).collect();
            assert!(
                diff.is_empty(),
                "config {c:?} seed {seed}: differs at hops {diff:?}"
            );
            assert_eq!(note_onsets_offline_level(&f0, &db, c).unwrap(), want);
            onsets += want.iter().filter(|&&o| o).count();
        }
        // Onsets happen: the comparison is not between two empty tracks.
        assert!(onsets >= 60, "{c:?}: {onsets} onsets");
    }
}

#[test]
fn guided_onsets_equal_the_slow_oracle_on_random_tracks() {
    let d = NoteConfig::default();
    let lead = NoteConfig {
        backtrack_hops: 3,
        pitch_back_hops: 2,
        reattack_min_hops: 25,
        ..d
    };
    let cfgs = [
        // The engine's clean lead (`CLEAN_LEAD_GUIDE_BACK_HOPS`).
        NoteConfig {
            guide_back_hops: 5,
            ..lead
        },
        NoteConfig {
            guide_back_hops: 16,
            attack_back_hops: 16,
            min_ioi_hops: 0,
            ..lead
        },
        NoteConfig {
            guide_back_hops: 8,
            attack_back_hops: 3,
            ..d
        },
        // A limited move switches the guide off.
        NoteConfig {
            guide_back_hops: 5,
            attack_move_hops: Some(2),
            ..lead
        },
    ];
    for c in cfgs {
        let mut moved = 0;
        for seed in 0..12u64 {
            let n = 50 + (seed as usize * 97) % 900;
            let (f0, db) = random_track(seed, n);
            // A flat level too, where no attack is ever found and rule 6 does all the work.
            let flat = vec![-20.0f32; n];
            for (lv, k) in [(&db, 4usize), (&flat, 6)] {
                let guide = random_guide(&f0, seed, k);
                let want = oracle_guided(&f0, lv, &guide, c);
                let got = streamed_guided(&f0, lv, &guide, c);
                let diff: Vec<usize> = (0..n).filter(|&i| got[i] != want[i]).collect();
                assert!(diff.is_empty(), "{c:?} seed {seed}: differs at {diff:?}");
                assert_eq!(
                    note_onsets_offline_guided(&f0, lv, &guide, c).unwrap(),
                    want
                );
                // Without the guide the rule changes nothing.
                assert_eq!(
                    note_onsets_offline_guided(&f0, lv, &[], c).unwrap(),
                    oracle(&f0, lv, c)
                );
                let plain = oracle(&f0, lv, c);
                moved += (0..n).filter(|&i| want[i] && !plain[i]).count();
            }
        }
        // The guide moves onsets (the comparison is not between unchanged tracks), unless a
        // limited move switches it off.
        if c.attack_move_hops.is_some() {
            assert_eq!(moved, 0, "{c:?}");
        } else {
            assert!(moved >= 30, "{c:?}: {moved} onsets moved");
        }
    }
}

#[test]
fn a_cross_fade_without_an_attack_starts_where_the_guide_changes() {
    // Two held notes, a flat level (a choir patch's cross-fade), the decoded pitch changing
    // at hop 60 and the aligned guide at hop 54.
    let (a, b) = (semitones_to_hz(60.0), semitones_to_hz(62.0));
    let f0: Vec<f32> = (0..120).map(|i| if i < 60 { a } else { b }).collect();
    let guide: Vec<f32> = (0..120).map(|i| if i < 54 { a } else { b }).collect();
    let db = vec![-20.0f32; 120];
    let lead = NoteConfig {
        backtrack_hops: 3,
        pitch_back_hops: 2,
        reattack_min_hops: 25,
        ..NoteConfig::default()
    };
    let at = |c: NoteConfig, g: &[f32]| -> Vec<usize> {
        let o = note_onsets_offline_guided(&f0, &db, g, c).unwrap();
        (0..o.len()).filter(|&i| o[i]).collect()
    };
    // Off: the pitch onset at 60 moves `pitch_back_hops` back.
    assert_eq!(at(lead, &guide), vec![0, 58]);
    // On: back to the guide's change, at most `guide_back_hops`.
    let on = |k| NoteConfig {
        guide_back_hops: k,
        ..lead
    };
    assert_eq!(at(on(8), &guide), vec![0, 54]);
    assert_eq!(at(on(5), &guide), vec![0, 55]);
    // A guide that changes with the decoded pitch, or none, leaves the old placement.
    assert_eq!(at(on(5), &f0), vec![0, 58]);
    assert_eq!(at(on(5), &[]), vec![0, 58]);
    // An attack found by rule 2 wins over the guide.
    let mut attacked = db.clone();
    for (i, v) in attacked.iter_mut().enumerate().skip(57) {
        *v = if i < 58 { -32.0 } else { -14.0 };
    }
    attacked[56] = -30.0;
    let o = note_onsets_offline_guided(&f0, &attacked, &guide, on(5)).unwrap();
    let got: Vec<usize> = (0..o.len()).filter(|&i| o[i]).collect();
    assert_eq!(
        got,
        vec![0, 57],
        "the foot of the attack's rise (57), not the guide's 55"
    );
}

#[test]
fn without_a_level_the_attack_rule_never_invents_onsets() {
    // No level: no re-attacks, no attack found; a resumed note stays one note.
    let (f0, _) = random_track(7, 800);
    let nan = vec![f32::NAN; f0.len()];
    let c = NoteConfig::default();
    assert_eq!(streamed(&f0, &nan, c), oracle(&f0, &nan, c));
    let with = note_onsets_offline(&f0, c).unwrap();
    let pitch = note_onsets_offline(&f0, NoteConfig::pitch_only()).unwrap();
    for i in 0..f0.len() {
        assert!(
            !with[i] || pitch[i],
            "hop {i}: an onset the pitch rule does not have"
        );
    }
}

/// Repeated plucks of one pitch: each note attacks (+20 dB within a hop) and decays,
/// with `gap` hops of release between notes during which the tracker still reports the
/// pitch (as a bass tracker bridging a short gap does).
fn plucks(notes: usize, len: usize, pitch_st: f32) -> (Vec<f32>, Vec<f32>, Vec<usize>) {
    let (mut f0, mut db, mut starts) = (Vec::new(), Vec::new(), Vec::new());
    for k in 0..notes {
        starts.push(f0.len());
        for i in 0..len {
            // 1 cent of jitter and a 2 dB tremolo: must not start notes.
            let p = pitch_st + 0.01 * ((i * 7 + k) % 3) as f32;
            f0.push(semitones_to_hz(p));
            let tremolo = 1.0 * (i as f32 * 0.9).sin();
            db.push(if i == 0 {
                -38.0
            } else {
                -18.0 - 0.5 * i as f32 + tremolo
            });
        }
    }
    (f0, db, starts)
}

#[test]
fn repeated_notes_of_one_pitch_each_start_a_note() {
    let (f0, db, starts) = plucks(8, 30, 40.0);
    let on = note_onsets_offline_level(&f0, &db, NoteConfig::default()).unwrap();
    let got: Vec<usize> = (0..f0.len()).filter(|&i| on[i]).collect();
    assert_eq!(got.len(), starts.len(), "onsets {got:?}, notes {starts:?}");
    for (g, s) in got.iter().zip(&starts) {
        assert!(g.abs_diff(*s) <= 1, "onset {g} for the note at {s}");
    }
    // The pitch alone sees one note.
    let pitch = note_onsets_offline(&f0, NoteConfig::pitch_only()).unwrap();
    assert_eq!(pitch.iter().filter(|&&o| o).count(), 1);
    // Plucks closer than the minimum interval merge: 8 hops apart, interval 10.
    let (f0, db, _) = plucks(6, 8, 40.0);
    let on = note_onsets_offline_level(&f0, &db, NoteConfig::default()).unwrap();
    let got: Vec<usize> = (0..f0.len()).filter(|&i| on[i]).collect();
    assert!(got.windows(2).all(|w| w[1] - w[0] >= 10), "{got:?}");
}

#[test]
fn a_pitch_onset_moves_back_to_its_attack() {
    // A note at 57, then a new attack at hop 40 (after a dip at 39) while the old pitch rings on for 5 hops
    // (a release or reverb tail), then the new pitch 60 from hop 45.
    let mut f0 = Vec::new();
    let mut db = Vec::new();
    for i in 0..80 {
        f0.push(semitones_to_hz(if i < 45 { 57.0 } else { 60.0 }));
        db.push(match i {
            0..=38 => -15.0 - 0.3 * i as f32,
            39 => -22.0,
            _ => -12.0 - 0.2 * (i - 40) as f32,
        });
    }
    let on = note_onsets_offline_level(&f0, &db, NoteConfig::default()).unwrap();
    let got: Vec<usize> = (0..f0.len()).filter(|&i| on[i]).collect();
    assert_eq!(got, vec![0, 40], "the new note starts at its attack");
    let pitch = note_onsets_offline(&f0, NoteConfig::pitch_only()).unwrap();
    let got: Vec<usize> = (0..f0.len()).filter(|&i| pitch[i]).collect();
    assert_eq!(got, vec![0, 45], "the pitch rule waits for the pitch");
    // A legato change without an attack stays where the pitch settles.
    let flat: Vec<f32> = (0..80).map(|i| -15.0 - 0.1 * i as f32).collect();
    let on = note_onsets_offline_level(&f0, &flat, NoteConfig::default()).unwrap();
    let got: Vec<usize> = (0..f0.len()).filter(|&i| on[i]).collect();
    assert_eq!(got, vec![0, 45]);
    // Unless changes must be attacked (a bass in a mixture): then it is no new note, while
    // the attacked change still is.
    let plucked = NoteConfig {
        pitch_needs_attack: true,
        ..NoteConfig::default()
    };
    let on = note_onsets_offline_level(&f0, &flat, plucked).unwrap();
    assert_eq!((0..80).filter(|&i| on[i]).collect::<Vec<_>>(), vec![0]);
    let on = note_onsets_offline_level(&f0, &db, plucked).unwrap();
    assert_eq!((0..80).filter(|&i| on[i]).collect::<Vec<_>>(), vec![0, 40]);
}

#[test]
fn an_attack_judged_in_place_adds_no_latency_and_keeps_the_settled_hop() {
    // The live profile's rule: the attack search keeps or drops a change of note but does
    // not move it, so the detector's latency is the stability window's alone.
    let d = NoteConfig::default();
    let live = NoteConfig {
        pitch_needs_attack: true,
        attack_move_hops: Some(0),
        ..d
    };
    let det = NoteOnsets::new(live).unwrap();
    assert_eq!(det.latency_hops(), (d.stable_hops - 1).max(RISE_AHEAD_HOPS));
    // A note, a second one plucked softly at hop 30 (a 5 dB rise: an attack, not a
    // re-attack) whose pitch the tracker reads from hop 32, then a change of pitch at hop 60
    // with no attack (a chord tone the tracker took).
    let f0: Vec<f32> = (0..90)
        .map(|i| {
            semitones_to_hz(if i < 32 {
                45.0
            } else if i < 60 {
                50.0
            } else {
                52.0
            })
        })
        .collect();
    let mut db: Vec<f32> = (0..90)
        .map(|i| {
            if i < 30 {
                -20.0 - 0.3 * i as f32
            } else {
                -20.0 - 0.3 * (i - 30) as f32
            }
        })
        .collect();
    for v in &mut db[27..30] {
        *v = -25.0;
    }
    let onsets = |c: NoteConfig| -> Vec<usize> {
        let got = streamed(&f0, &db, c);
        assert_eq!(oracle(&f0, &db, c), got, "{c:?}");
        (0..got.len()).filter(|&i| got[i]).collect()
    };
    // In place: the second note where its pitch settled, the unattacked change dropped.
    assert_eq!(onsets(live), vec![0, 32]);
    // One hop of move, and the full move back to the attack.
    let moved = |m| NoteConfig {
        attack_move_hops: m,
        ..live
    };
    assert_eq!(onsets(moved(Some(1))), vec![0, 31]);
    assert_eq!(onsets(moved(None)), vec![0, 30]);
}

#[test]
fn a_clean_lead_starts_at_the_foot_of_the_rise() {
    // A syllable sung on the previous note's pitch: the level dips for the consonant
    // (hops 40–44, lowest at 44) and the vowel rises over hops 45–47, steepest at 46.
    let f0: Vec<f32> = vec![semitones_to_hz(64.0); 90];
    let mut db: Vec<f32> = (0..90).map(|i| -20.0 - 0.05 * i as f32).collect();
    for (i, v) in [-23.0, -26.0, -28.0, -30.0, -31.0, -28.0, -22.0, -20.0]
        .iter()
        .enumerate()
    {
        db[40 + i] = *v;
    }
    let on = |c| -> Vec<usize> {
        let o = note_onsets_offline_level(&f0, &db, c).unwrap();
        (0..90).filter(|&i| o[i]).collect()
    };
    let d = NoteConfig::default();
    assert_eq!(on(d), vec![0, 46], "the re-attack at its steepest step");
    let lead = NoteConfig {
        backtrack_hops: 3,
        pitch_back_hops: 2,
        ..d
    };
    assert_eq!(on(lead), vec![0, 44], "moved back to the level's low point");
    // At most `backtrack_hops` back: with 1, one hop.
    assert_eq!(
        on(NoteConfig {
            backtrack_hops: 1,
            ..lead
        }),
        vec![0, 45]
    );
    // A legato change of note (no attack) moves `pitch_back_hops` back from where the pitch
    // settles (hop 45), never before the first note or inside the minimum interval.
    let mut f0 = f0.clone();
    for v in &mut f0[45..] {
        *v = semitones_to_hz(67.0);
    }
    let flat: Vec<f32> = (0..90).map(|i| -15.0 - 0.1 * i as f32).collect();
    let o = note_onsets_offline_level(&f0, &flat, lead).unwrap();
    assert_eq!((0..90).filter(|&i| o[i]).collect::<Vec<_>>(), vec![0, 43]);
    let o = note_onsets_offline_level(&f0, &flat, d).unwrap();
    assert_eq!((0..90).filter(|&i| o[i]).collect::<Vec<_>>(), vec![0, 45]);
}

#[test]
fn a_dropout_that_resumes_the_note_is_not_a_new_note() {
    // A held note whose track drops out for 5 hops (the gate, a chord tone), level falling.
    let mut f0: Vec<f32> = vec![semitones_to_hz(52.0); 100];
    for v in &mut f0[40..45] {
        *v = 0.0;
    }
    let db: Vec<f32> = (0..100).map(|i| -20.0 - 0.2 * i as f32).collect();
    let on = note_onsets_offline_level(&f0, &db, NoteConfig::default()).unwrap();
    let got: Vec<usize> = (0..f0.len()).filter(|&i| on[i]).collect();
    assert_eq!(got, vec![0]);
    // The pitch rule starts a note after any gap longer than 2 hops.
    let pitch = note_onsets_offline(&f0, NoteConfig::pitch_only()).unwrap();
    assert_eq!(
        (0..100).filter(|&i| pitch[i]).collect::<Vec<_>>(),
        vec![0, 45]
    );
    // With an attack after the dropout it is a new note (a re-struck string), at the attack.
    let mut db2 = db.clone();
    for (i, v) in db2.iter_mut().enumerate().skip(44) {
        *v = -10.0 - 0.2 * (i - 44) as f32;
    }
    let on = note_onsets_offline_level(&f0, &db2, NoteConfig::default()).unwrap();
    assert_eq!((0..100).filter(|&i| on[i]).collect::<Vec<_>>(), vec![0, 44]);
    // A long rest ends the note: the same pitch after it is a new note, attack or not.
    let mut f0 = f0.clone();
    for v in &mut f0[40..60] {
        *v = 0.0;
    }
    let on = note_onsets_offline_level(&f0, &db, NoteConfig::default()).unwrap();
    assert_eq!((0..100).filter(|&i| on[i]).collect::<Vec<_>>(), vec![0, 60]);
}

#[test]
fn latency_reset_and_no_allocation() {
    let (f0, db) = random_track(3, 600);
    for c in configs() {
        let mut d = NoteOnsets::new(c).unwrap();
        let ahead = if c.reattack_db > 0.0 {
            (c.stable_hops - 1).max(RISE_AHEAD_HOPS)
        } else {
            c.stable_hops - 1
        };
        let back = c.attack_back_hops;
        let moves = c.attack_move_hops.map_or(back, |m| m.min(back));
        assert_eq!(d.latency_hops(), ahead + moves, "{c:?}");
        let mut first = Vec::new();
        for i in 0..f0.len() {
            d.push_level(f0[i], db[i], &mut |_, o| first.push(o));
        }
        d.finish(&mut |_, o| first.push(o));
        d.reset();
        let mut again = Vec::with_capacity(f0.len());
        let allocs = tactus_testkit::allocations_during(|| {
            for i in 0..f0.len() {
                d.push_level(f0[i], db[i], &mut |_, o| again.push(o));
            }
            d.finish(&mut |_, o| again.push(o));
        });
        assert_eq!(again, first, "reset reproduces the output");
        assert_eq!(allocs, 0, "push and finish allocate nothing");
    }
    // The pitch rule keeps its latency.
    assert_eq!(
        NoteOnsets::new(NoteConfig::pitch_only())
            .unwrap()
            .latency_hops(),
        3
    );
}

#[test]
fn bad_configs_are_refused() {
    let d = NoteConfig::default();
    for bad in [
        NoteConfig {
            reattack_db: -1.0,
            ..d
        },
        NoteConfig {
            reattack_db: f32::NAN,
            ..d
        },
        NoteConfig {
            attack_db: f32::INFINITY,
            ..d
        },
        NoteConfig {
            backtrack_hops: 17,
            ..NoteConfig::default()
        },
        NoteConfig {
            pitch_back_hops: 17,
            ..NoteConfig::default()
        },
        NoteConfig {
            attack_back_hops: 17,
            ..d
        },
        NoteConfig {
            stable_hops: 0,
            ..d
        },
    ] {
        assert!(NoteOnsets::new(bad).is_err(), "{bad:?}");
    }
}
