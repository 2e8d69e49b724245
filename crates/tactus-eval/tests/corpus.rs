//! The committed corpus fixtures (`corpus/fixtures/*/truth.json`) read back, checked for
//! internal consistency, and scored through `evaluate` with features built from the truth:
//! perfect features must score perfectly, and known degradations must score as predicted.
use std::path::PathBuf;

use tactus_dsp::{Band, Stem};
use tactus_eval::levels::{bin_pitch, discretize};
use tactus_eval::{evaluate, FeaturesLike, Report, Truth};

fn fixtures() -> Vec<Truth> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../corpus/fixtures");
    let mut songs: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("corpus/fixtures exists")
        .map(|e| e.unwrap().path().join("truth.json"))
        .filter(|p| p.exists())
        .collect();
    songs.sort();
    assert!(
        songs.len() >= 2,
        "expected at least 2 fixture songs in {dir:?}"
    );
    songs
        .iter()
        .map(|p| Truth::from_json_str(&std::fs::read_to_string(p).unwrap()).expect("valid truth"))
        .collect()
}

/// Features that say exactly what the truth says.
fn perfect_features(t: &Truth) -> FeaturesLike {
    let mut f = FeaturesLike {
        hop_s: t.hop_s,
        bin_s: 0.1,
        ..Default::default()
    };
    for stem in Stem::MELODIC {
        let f0 = t.f0(stem).unwrap().to_vec();
        let levels = discretize(&bin_pitch(&f0, t.hop_s, 0.1).unwrap(), 8).unwrap();
        f.pitch_hz.insert(stem.name().into(), f0);
        f.levels.insert(stem.name().into(), levels);
    }
    for band in Band::ALL {
        f.onsets_s.insert(band.name().into(), t.onset_times(band));
    }
    f
}

#[test]
fn truth_files_are_consistent() {
    for t in fixtures() {
        assert_eq!(t.sample_rate, 44100);
        let frames = (t.duration_s / t.hop_s - 1e-9).ceil() as usize;
        // per stem: length, pitch range, and presence of notes
        for (stem, lo, hi) in [
            (Stem::Vocals, 200.0, 1400.0),
            (Stem::Bass, 41.2, 400.0),
            (Stem::Other, 100.0, 1000.0),
        ] {
            let f0 = t.f0(stem).expect("stem present");
            assert_eq!(f0.len(), frames, "{} {}", t.song, stem.name());
            let voiced: Vec<f64> = f0.iter().copied().filter(|&x| x > 0.0).collect();
            assert!(
                voiced.len() > frames / 2,
                "{} {} mostly silent",
                t.song,
                stem.name()
            );
            // bass is folded to E1 = 41.20 Hz at the lowest; vocal bends stay within ±0.75 st
            assert!(
                voiced.iter().all(|&x| x >= lo - 0.01 && x <= hi),
                "{} {}",
                t.song,
                stem.name()
            );
        }
        // the vocals carry vibrato: many distinct values, not just equal-tempered notes
        let vocals = t.f0(Stem::Vocals).unwrap();
        let off_grid = vocals
            .iter()
            .filter(|&&x| x > 0.0)
            .filter(|&&x| {
                let st = 69.0 + 12.0 * (x / 440.0).log2();
                (st - st.round()).abs() > 0.05
            })
            .count();
        assert!(off_grid > 100, "{}: only {off_grid} bent frames", t.song);
        for band in Band::ALL {
            let hits = &t.onsets[band.name()];
            assert!(!hits.is_empty(), "{} {}", t.song, band.name());
            assert!(hits.windows(2).all(|w| w[0].time_s <= w[1].time_s));
            assert!(hits
                .iter()
                .all(|h| h.time_s >= 0.0 && h.time_s < t.duration_s));
        }
        // ghost notes exist (velocity 33 snares) next to the backbeat (100)
        let snare = &t.onsets["snare"];
        assert!(snare.iter().any(|h| h.velocity == 33) && snare.iter().any(|h| h.velocity == 100));
    }
}

#[test]
fn perfect_features_score_perfectly() {
    for t in fixtures() {
        let r = evaluate(&perfect_features(&t), &t);
        assert_eq!(r.stems.len(), 3);
        for s in &r.stems {
            assert_eq!(s.rpa, Some(1.0), "{} {}", t.song, s.stem);
            assert_eq!(s.rca, Some(1.0));
            assert_eq!(s.voicing_recall, Some(1.0));
            assert_eq!(s.voicing_false_alarm, Some(0.0));
            assert_eq!(s.level_exact, Some(1.0));
            // Hz vs 8 semitone levels: the paper's discretization error alone. Each level
            // spans (range/8) semitones, so for these ≤ 1.5-octave lines the normalized
            // contours differ by well under 0.25; MAE > 0 because Hz and levels differ.
            let mae = s.paper_mae.unwrap();
            let dtw = s.paper_dtw.unwrap();
            assert!(mae > 0.0 && mae < 0.25, "{} {} MAE {mae}", t.song, s.stem);
            assert!(dtw <= mae + 1e-12, "DTW {dtw} > MAE {mae}");
        }
        for b in &r.bands {
            assert_eq!(b.f_measure, Some(1.0), "{} {}", t.song, b.band);
            assert_eq!(b.paper_rhythm_accuracy, Some(1.0));
        }
    }
}

#[test]
fn degradations_score_as_predicted() {
    for t in fixtures() {
        let mut f = perfect_features(&t);
        // a semitone up: 100 cents, outside the 50-cent tolerance for pitch and chroma
        let semitone = 2f64.powf(1.0 / 12.0);
        f.pitch_hz
            .get_mut("vocals")
            .unwrap()
            .iter_mut()
            .for_each(|x| *x *= semitone);
        // an octave up: pitch wrong everywhere, chroma right everywhere
        f.pitch_hz
            .get_mut("bass")
            .unwrap()
            .iter_mut()
            .for_each(|x| *x *= 2.0);
        // onsets 60 ms late: the nearest hits (16ths at ≤ 140 bpm are ≥ 107 ms apart) are
        // all more than 50 ms away, so nothing matches
        f.onsets_s
            .values_mut()
            .for_each(|v| v.iter_mut().for_each(|x| *x += 0.06));
        let r = evaluate(&f, &t);
        let row = |n: &str| r.stems.iter().find(|s| s.stem == n).unwrap();
        assert_eq!(row("vocals").rpa, Some(0.0));
        assert_eq!(row("vocals").rca, Some(0.0));
        assert_eq!(row("vocals").voicing_recall, Some(1.0));
        assert_eq!(row("bass").rpa, Some(0.0));
        assert_eq!(row("bass").rca, Some(1.0));
        for b in &r.bands {
            assert_eq!(b.f_measure, Some(0.0), "{} {}", t.song, b.band);
            // rhythm accuracy from a slow oracle in integer microseconds: a bin holds a
            // beat when any onset falls in [k·100 ms, (k+1)·100 ms)
            let band = Band::from_name(&b.band).unwrap();
            let us = |x: f64| (x * 1e6).round() as i64;
            let truth_t: Vec<i64> = t.onset_times(band).into_iter().map(us).collect();
            let est_t: Vec<i64> = f.onsets_s[band.name()].iter().map(|&x| us(x)).collect();
            let n = (us(t.duration_s) + 99_999) / 100_000;
            let beat = |ts: &[i64], k: i64| {
                ts.iter()
                    .any(|&x| x >= k * 100_000 && x < (k + 1) * 100_000)
            };
            let agree = (0..n)
                .filter(|&k| beat(&truth_t, k) == beat(&est_t, k))
                .count();
            let want = agree as f64 / n as f64;
            let got = b.paper_rhythm_accuracy.unwrap();
            assert!(
                (got - want).abs() < 1e-12,
                "{} {}: {got} vs oracle {want}",
                t.song,
                b.band
            );
            if !truth_t.is_empty() {
                assert!(
                    got < 1.0,
                    "{} {}: a 60 ms delay must move some beat",
                    t.song,
                    b.band
                );
            }
        }
    }
}

#[test]
fn features_json_and_report_round_trip() {
    let t = &fixtures()[0];
    let f = perfect_features(t);
    // a features file as `render --features` writes it, with keys the reader must ignore
    let mut v = serde_json::to_value(&f).unwrap();
    v["format"] = "tactus-features".into();
    v["beats"] = serde_json::json!({});
    v["extra"] = serde_json::json!({"anything": [1, 2, 3]});
    let parsed = FeaturesLike::from_json_str(&v.to_string()).unwrap();
    assert_eq!(parsed, f);
    assert!(FeaturesLike::from_json_str(r#"{"hop_s": 0, "bin_s": 0.1}"#).is_err());
    assert!(Truth::from_json_str(
        r#"{"format":"x","version":1,"sample_rate":1,"duration_s":1,"hop_s":0.01}"#
    )
    .is_err());

    let mut r = evaluate(&parsed, t);
    r.set_sdr(Stem::Vocals, 12.5);
    let md = r.to_markdown();
    assert!(md.contains("| vocals |") && md.contains("| kick |") && md.contains("12.5000"));
    let back: Report = serde_json::from_str(&r.to_json()).unwrap();
    assert_eq!(back, r);
    println!("{md}");
}
