//! The per-band drum truth of the committed fixtures (`band_onsets`, written by
//! `corpus/generate.py`): membership re-derived here from the committed per-note band
//! table and the 10 dB rule, and both truths scored through `evaluate`.
use std::collections::BTreeMap;
use std::path::PathBuf;

use serde_json::Value;
use tactus_dsp::Band;
use tactus_eval::{evaluate, FeaturesLike, Truth};

fn fixtures() -> Vec<(Truth, Value)> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../corpus/fixtures");
    let mut songs: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path().join("truth.json"))
        .filter(|p| p.exists())
        .collect();
    songs.sort();
    assert!(songs.len() >= 2);
    songs
        .iter()
        .map(|p| {
            let text = std::fs::read_to_string(p).unwrap();
            (
                Truth::from_json_str(&text).unwrap(),
                serde_json::from_str(&text).unwrap(),
            )
        })
        .collect()
}

#[test]
fn band_truth_follows_the_per_note_table() {
    for (t, raw) in fixtures() {
        let table = raw["band_db_by_note"].as_object().expect("band table");
        let bands = t.band_onsets.as_ref().expect("band_onsets");
        for band in Band::ALL {
            // Oracle: every per-instrument hit whose note is within 10 dB of its loudest
            // band in `band`, in time order.
            let mut want: Vec<(f64, u8)> = t
                .onsets
                .values()
                .flatten()
                .filter(|h| {
                    let db = table[&h.note.to_string()][band.name()].as_f64().unwrap();
                    db >= -10.0
                })
                .map(|h| (h.time_s, h.note))
                .collect();
            want.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let got: Vec<(f64, u8)> = bands[band.name()]
                .iter()
                .map(|h| (h.time_s, h.note))
                .collect();
            assert_eq!(got, want, "{} {}", t.song, band.name());
        }
        // Every note's loudest band is at 0 dB, so every hit is in at least one band.
        let total: usize = t.onsets.values().map(Vec::len).sum();
        let mut times = BTreeMap::new();
        for h in bands.values().flatten() {
            times.insert((h.time_s.to_bits(), h.note), ());
        }
        assert_eq!(times.len(), total, "{}", t.song);
    }
}

#[test]
fn evaluate_scores_both_truths() {
    for (t, _) in fixtures() {
        // Estimates equal to the per-band truth: band F = 1, and the per-instrument F is
        // below 1 wherever the two truths differ.
        let mut f = FeaturesLike {
            hop_s: t.hop_s,
            bin_s: 0.1,
            ..Default::default()
        };
        for band in Band::ALL {
            f.onsets_s
                .insert(band.name().into(), t.band_onset_times(band).unwrap());
        }
        let r = evaluate(&f, &t);
        for (row, band) in r.bands.iter().zip(Band::ALL) {
            let band_ref = t.band_onset_times(band).unwrap();
            let inst_ref = t.onset_times(band);
            assert_eq!(row.band_truth_onsets, Some(band_ref.len()));
            if !band_ref.is_empty() {
                assert_eq!(row.band_f_measure, Some(1.0), "{} {}", t.song, row.band);
            }
            if band_ref != inst_ref {
                assert!(row.f_measure.unwrap() < 1.0, "{} {}", t.song, row.band);
            }
        }
        assert!(r.to_markdown().contains("per band"));
        // A truth file without band_onsets leaves the band columns empty.
        let mut old = t.clone();
        old.band_onsets = None;
        let r = evaluate(&f, &old);
        assert!(r.bands.iter().all(|b| b.band_f_measure.is_none()));
    }
}
