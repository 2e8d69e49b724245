//! Table 3 fidelity from a glove actuation log: an oracle log (every frame, or only the
//! changes, exactly as the emulator writes them) scores MAE 0, DTW 0, rhythm 1 against its
//! pattern; a one-bin shift and a dropped packet give hand-computed values; the level→dot
//! table reads back every level; 25 ms frames group into 100 ms bins by hand.
use tactus_dsp::{Band, Stem};
use tactus_eval::glove_log::{
    beats_to_paper_bins, decode_frames, frames_from_log, glove_fidelity, levels_to_paper_bins,
    parse_actuation_log, LoggedFrame, PAPER_BIN_S,
};
use tactus_eval::FeaturesLike;
use tactus_glove::{BinFeatures, Frame, GloveMap, Pattern, SourceInfo};

/// Bass levels and kick beats of the hand-computed cases, one per 100 ms bin.
const BASS: [u8; 6] = [0, 8, 8, 4, 4, 0];
const KICK: [bool; 6] = [true, false, false, true, false, false];

fn pattern(bass: &[u8], kick: &[bool], bin_ms: u32) -> Pattern {
    let map = GloveMap::default();
    let frames = bass
        .iter()
        .zip(kick)
        .map(|(&l, &k)| {
            let mut f = BinFeatures::default();
            f.level[Stem::Bass as usize] = l;
            f.band_beat[Band::Kick as usize] = k;
            map.render(&f, 8)
        })
        .collect();
    Pattern {
        source: SourceInfo {
            path: "test".into(),
            sha256: "0".repeat(64),
            duration_s: bass.len() as f64 * f64::from(bin_ms) / 1000.0,
            sample_rate: 44_100,
        },
        bin_ms,
        levels: 8,
        map,
        frames,
    }
}

/// One log line per frame at `(k + shift)·bin`, skipping the frames in `drop`.
fn log_of(p: &Pattern, shift: u64, drop: &[usize]) -> Vec<LoggedFrame> {
    p.frames
        .iter()
        .enumerate()
        .filter(|(k, _)| !drop.contains(k))
        .map(|(k, f)| LoggedFrame {
            time_ms: (k as u64 + shift) * u64::from(p.bin_ms),
            frame: *f,
            all_down: false,
        })
        .collect()
}

/// The emulator's log: a line only when the state changes, then all-down.
fn emulator_log_text(p: &Pattern) -> String {
    let mut s = String::new();
    let mut last = Frame::DOWN;
    for (k, f) in p.frames.iter().enumerate() {
        if *f != last {
            s.push_str(&format!(
                "{{\"arrival_ms\":{}.5,\"seq\":{},\"time_ms\":{},\"type\":\"pins\",\"frame\":\"{}\",\"raised\":[],\"lowered\":[],\"settled_ms\":1.0}}\n",
                k * 100, k, k as u32 * p.bin_ms, f.to_hex()
            ));
            last = *f;
        }
    }
    let t = (p.frames.len() as u32 - 1) * p.bin_ms;
    s.push_str(&format!(
        "{{\"arrival_ms\":9.0,\"seq\":99,\"time_ms\":{t},\"type\":\"all_down\",\"frame\":\"00000000000000000000\",\"raised\":[],\"lowered\":[],\"settled_ms\":59.0}}\n"
    ));
    s
}

#[test]
fn oracle_log_scores_zero_error_against_its_pattern() {
    let p = pattern(&BASS, &KICK, 100);
    for log in [
        log_of(&p, 0, &[]),
        parse_actuation_log(&emulator_log_text(&p)).unwrap(),
    ] {
        let r = glove_fidelity(&log, &p, None, PAPER_BIN_S).unwrap();
        assert_eq!(r.frames_matching, 6);
        assert_eq!(r.undecodable, 0);
        let bass = r.stems.iter().find(|s| s.stem == "bass").unwrap();
        assert_eq!((bass.mae_vs_pattern, bass.dtw_vs_pattern), (0.0, 0.0));
        for b in &r.bands {
            assert_eq!(b.rhythm_vs_pattern, 1.0, "{}", b.band);
        }
        assert_eq!(r.table3_vs_pattern(), (Some(0.0), Some(0.0), Some(1.0)));
        assert_eq!(r.table3_vs_audio(), (None, None, None));
    }
}

#[test]
fn one_bin_late_log_gives_hand_computed_values() {
    let p = pattern(&BASS, &KICK, 100);
    let r = glove_fidelity(&log_of(&p, 1, &[]), &p, None, PAPER_BIN_S).unwrap();
    let bass = r.stems.iter().find(|s| s.stem == "bass").unwrap();
    // Levels [0,8,8,4,4,0] replayed one bin late: [0,0,8,8,4,4]. Min–max normalized:
    // y = [0,1,1,.5,.5,0], ŷ = [0,0,1,1,.5,.5]; |y − ŷ| = [0,1,0,.5,0,.5]: MAE = 2/6.
    assert!((bass.mae_vs_pattern - 2.0 / 6.0).abs() < 1e-12);
    // DTW: the only unavoidable cost is the end pair (0 vs .5); the tie rule's path is
    // (0,0) (0,1) (1,2) (2,3) (3,4) (4,4) (5,5): K = 7, cost 0.5 (brute-force checked).
    assert!((bass.dtw_vs_pattern - 0.5 / 7.0).abs() < 1e-12);
    // Kick [1,0,0,1,0,0] vs [0,1,0,0,1,0]: equal in bins 2 and 5 → 2/6.
    let kick = r.bands.iter().find(|b| b.band == "kick").unwrap();
    assert!((kick.rhythm_vs_pattern - 2.0 / 6.0).abs() < 1e-12);
    // Bands without beats stay silent on both sides.
    let toms = r.bands.iter().find(|b| b.band == "toms").unwrap();
    assert_eq!(toms.rhythm_vs_pattern, 1.0);
    assert_eq!(r.frames_matching, 1); // only bin 2 equals its predecessor
}

#[test]
fn dropped_packet_holds_the_previous_state() {
    let p = pattern(&BASS, &KICK, 100);
    let r = glove_fidelity(&log_of(&p, 0, &[3]), &p, None, PAPER_BIN_S).unwrap();
    let bass = r.stems.iter().find(|s| s.stem == "bass").unwrap();
    // Bin 3 (level 4 + kick) lost: bin 2's state (level 8, no kick) is held.
    // y = [0,1,1,.5,.5,0], ŷ = [0,1,1,1,.5,0]: MAE = .5/6; DTW warps the held value
    // away: path (0,0) (1,1) (1,2) (2,3) (3,4) (4,4) (5,5), cost 0.
    assert!((bass.mae_vs_pattern - 0.5 / 6.0).abs() < 1e-12);
    assert_eq!(bass.dtw_vs_pattern, 0.0);
    let kick = r.bands.iter().find(|b| b.band == "kick").unwrap();
    assert!((kick.rhythm_vs_pattern - 5.0 / 6.0).abs() < 1e-12);
    assert_eq!(r.frames_matching, 5);
}

#[test]
fn scores_against_audio_features() {
    let p = pattern(&BASS, &KICK, 100);
    // Audio pitch per 10 ms hop: 0 Hz, then 200 Hz, 200, 100, 100, 0 (10 hops per bin);
    // onsets at 0.05 s and 0.35 s (bins 0 and 3).
    let mut pitch = Vec::new();
    for hz in [0.0, 200.0, 200.0, 100.0, 100.0, 0.0] {
        pitch.extend(std::iter::repeat_n(hz, 10));
    }
    let mut f = FeaturesLike {
        hop_s: 0.01,
        bin_s: 0.1,
        ..Default::default()
    };
    f.pitch_hz.insert("bass".into(), pitch);
    f.onsets_s.insert("kick".into(), vec![0.05, 0.35]);
    for b in ["snare", "toms", "cymbals"] {
        f.onsets_s.insert(b.into(), vec![]);
    }
    let r = glove_fidelity(&log_of(&p, 0, &[]), &p, Some(&f), PAPER_BIN_S).unwrap();
    let bass = r.stems.iter().find(|s| s.stem == "bass").unwrap();
    // Audio normalized: [0,1,1,.5,.5,0]; levels [0,8,8,4,4,0] normalized the same: 0.
    assert_eq!(bass.mae_vs_audio, Some(0.0));
    assert_eq!(bass.pattern_mae_vs_audio, Some(0.0));
    let kick = r.bands.iter().find(|b| b.band == "kick").unwrap();
    assert_eq!(kick.rhythm_vs_audio, Some(1.0));
    // One bin late: the log is off, the pattern (the floor) is not.
    let r = glove_fidelity(&log_of(&p, 1, &[]), &p, Some(&f), PAPER_BIN_S).unwrap();
    let bass = r.stems.iter().find(|s| s.stem == "bass").unwrap();
    assert!((bass.mae_vs_audio.unwrap() - 2.0 / 6.0).abs() < 1e-12);
    assert_eq!(bass.pattern_mae_vs_audio, Some(0.0));
    assert!((r.table3_vs_audio().2.unwrap() - (2.0 / 6.0 + 3.0) / 4.0).abs() < 1e-12);
}

#[test]
fn every_level_reads_back_through_the_dot_table() {
    let levels: Vec<u8> = (0..=8).collect();
    let p = pattern(&levels, &[false; 9], 100);
    let t = decode_frames(&p.frames, &p.map, 8);
    assert_eq!(t.levels[&Stem::Bass], levels);
    assert_eq!(t.undecodable, 0);
    // Two dots in a pitch cell are no level.
    let mut f = p.frames[3];
    f.0[0] |= p.frames[5].0[0];
    let t = decode_frames(&[f], &p.map, 8);
    assert_eq!((t.levels[&Stem::Bass][0], t.undecodable), (0, 1));
}

#[test]
fn quarter_bins_group_into_paper_bins() {
    // 25 ms levels: bin 0 = [3,3,5,5] → lower median 3; bin 1 = [0,0,0,6] → unvoiced
    // (1 voiced of 4 < half); bin 2 = [0,7,7,0] → 7.
    let lv = [3, 3, 5, 5, 0, 0, 0, 6, 0, 7, 7, 0];
    assert_eq!(
        levels_to_paper_bins(&lv, 0.025, 0.1).unwrap(),
        vec![3.0, 0.0, 7.0]
    );
    let bt = [
        false, false, true, false, false, false, false, false, true, true, false, false,
    ];
    assert_eq!(
        beats_to_paper_bins(&bt, 0.025, 0.1).unwrap(),
        vec![true, false, true]
    );
}

#[test]
fn log_parsing_unwraps_time_and_places_all_down_after_the_last_frame() {
    let f1 = "01000000000000000000";
    let text = format!(
        "{{\"time_ms\":65400,\"type\":\"pins\",\"frame\":\"{f1}\"}}\n\n{{\"time_ms\":40,\"type\":\"pins\",\"frame\":\"02000000000000000000\"}}\n{{\"time_ms\":40,\"type\":\"all_down\",\"frame\":\"02000000000000000000\"}}\n"
    );
    let log = parse_actuation_log(&text).unwrap();
    assert_eq!(log[1].time_ms, 65_536 + 40);
    assert!(log[2].all_down && log[2].frame == Frame::DOWN);
    // bins of 100 ms: 654 → f1, 655 (65.576 s) → second frame, 656 → all down
    let frames = frames_from_log(&log, 100, 657).unwrap();
    assert_eq!(frames[653], Frame::DOWN);
    assert_eq!(frames[654].0[0], 1);
    assert_eq!(frames[655].0[0], 2);
    assert_eq!(frames[656], Frame::DOWN);
    assert!(parse_actuation_log("{\"time_ms\":1,\"type\":\"pins\",\"frame\":\"zz\"}").is_err());
    assert!(parse_actuation_log("{\"time_ms\":70000,\"frame\":\"00000000000000000000\"}").is_err());
    assert!(parse_actuation_log("not json").is_err());
}
