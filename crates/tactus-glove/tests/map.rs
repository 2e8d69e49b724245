//! The feature-to-pin map: default = contract, TOML/JSON round trips, needs(), errors,
//! rendering against an obvious per-cell oracle.

use proptest::prelude::*;
use tactus_glove::map::{ALL_DOTS, DRUMS_ONLY_MAP_TOML, MELODY_MAP_TOML};
use tactus_glove::{Band, BinFeatures, CellSource, Finger, GloveError, GloveMap, Needs, Stem};

fn pitch(stem: Stem) -> CellSource {
    CellSource::PitchLevel(stem)
}
fn notes(stem: Stem) -> CellSource {
    CellSource::NoteOnsets {
        stem,
        dots: ALL_DOTS,
    }
}
fn band(band: Band) -> CellSource {
    CellSource::BandOnsets {
        band,
        dots: ALL_DOTS,
    }
}

/// docs/design.md's table, typed in by hand.
fn contract_table() -> [[CellSource; 2]; 5] {
    [
        [pitch(Stem::Bass), notes(Stem::Bass)],
        [band(Band::Kick), band(Band::Snare)],
        [band(Band::Toms), band(Band::Cymbals)],
        [pitch(Stem::Vocals), notes(Stem::Vocals)],
        [pitch(Stem::Other), notes(Stem::Other)],
    ]
}

#[test]
fn default_map_is_the_contract_table() {
    let map = GloveMap::default();
    assert_eq!(map.cells, contract_table());
    let from_file =
        GloveMap::from_path(concat!(env!("CARGO_MANIFEST_DIR"), "/maps/default.toml")).unwrap();
    assert_eq!(from_file, map);
}

#[test]
fn shipped_example_maps_parse() {
    let drums = GloveMap::from_toml_str(DRUMS_ONLY_MAP_TOML).unwrap();
    assert_eq!(
        drums.get(Finger::Thumb, 0),
        CellSource::NoteOnsets {
            stem: Stem::Drums,
            dots: 0b0100_0111
        }
    );
    assert_eq!(drums.get(Finger::Ring, 0), CellSource::Off);
    let melody = GloveMap::from_toml_str(MELODY_MAP_TOML).unwrap();
    assert_eq!(
        melody.get(Finger::Ring, 0),
        CellSource::BandOnsets {
            band: Band::Kick,
            dots: 0b1100_0000
        }
    );
    assert_eq!(melody.needs().bands, vec![Band::Kick]);
}

#[test]
fn needs_and_stems() {
    let map = GloveMap::default();
    assert_eq!(
        map.needs(),
        Needs {
            pitch: vec![Stem::Bass, Stem::Vocals, Stem::Other],
            note_onsets: vec![Stem::Bass, Stem::Vocals, Stem::Other],
            bands: Band::ALL.to_vec(),
        }
    );
    assert_eq!(map.stems(), Stem::ALL.to_vec());

    let drums = GloveMap::from_toml_str(DRUMS_ONLY_MAP_TOML).unwrap();
    assert_eq!(
        drums.needs(),
        Needs {
            pitch: vec![],
            note_onsets: vec![Stem::Drums],
            bands: Band::ALL.to_vec()
        }
    );
    assert_eq!(drums.stems(), vec![Stem::Drums]);

    let only_bass = GloveMap::from_toml_str("[pinky]\ncell1 = { pitch = \"bass\" }\n").unwrap();
    assert_eq!(only_bass.stems(), vec![Stem::Bass]);
    assert_eq!(GloveMap::off().stems(), Vec::<Stem>::new());
    assert_eq!(GloveMap::from_toml_str("").unwrap(), GloveMap::off());
}

#[test]
fn toml_and_json_round_trip() {
    for text in [
        tactus_glove::map::DEFAULT_MAP_TOML,
        DRUMS_ONLY_MAP_TOML,
        MELODY_MAP_TOML,
    ] {
        let map = GloveMap::from_toml_str(text).unwrap();
        let again = GloveMap::from_toml_str(&map.to_toml_string()).unwrap();
        assert_eq!(again, map);
        let json = serde_json::to_string(&map).unwrap();
        assert_eq!(serde_json::from_str::<GloveMap>(&json).unwrap(), map);
    }
    let json = serde_json::to_value(GloveMap::default()).unwrap();
    assert_eq!(json["thumb"]["cell0"]["pitch"], "bass");
    assert_eq!(json["index"]["cell1"]["onsets"], "snare");
    assert!(
        json["index"]["cell1"].get("dots").is_none(),
        "all 8 dots is the default, not written"
    );
}

fn map_error(text: &str) -> (String, String, String) {
    match GloveMap::from_toml_str(text) {
        Err(GloveError::Map {
            finger,
            cell,
            reason,
        }) => (finger.to_string(), cell.to_string(), reason),
        other => panic!("expected a map error for {text:?}, got {other:?}"),
    }
}

#[test]
fn bad_cells_give_clear_errors() {
    let (finger, cell, reason) = map_error("[ring]\ncell1 = { pitch = \"voclas\" }");
    assert_eq!((finger.as_str(), cell.as_str()), ("ring", "cell1"));
    assert!(
        reason.contains("`pitch`") && reason.contains("\"voclas\""),
        "{reason}"
    );
    let full = GloveMap::from_toml_str("[ring]\ncell1 = { pitch = \"voclas\" }")
        .unwrap_err()
        .to_string();
    assert!(
        full.starts_with("map: ring.cell1: `pitch`: unknown stem \"voclas\""),
        "{full}"
    );

    let (_, _, reason) = map_error("[index]\ncell0 = { onsets = \"kik\" }");
    assert!(reason.contains("unknown stem or band \"kik\""), "{reason}");
    let (_, _, reason) = map_error("[index]\ncell0 = { pitch = \"drums\" }");
    assert!(reason.contains("no pitch"), "{reason}");
    let (_, _, reason) = map_error("[index]\ncell0 = { pitch = \"bass\", onsets = \"bass\" }");
    assert!(reason.contains("only one"), "{reason}");
    let (_, _, reason) = map_error("[index]\ncell0 = { onsets = \"kick\", dots = [9] }");
    assert!(reason.contains("9 is not a braille dot"), "{reason}");
    let (_, _, reason) = map_error("[index]\ncell0 = { onsets = \"kick\", dots = [] }");
    assert!(reason.contains("empty"), "{reason}");
    let (_, _, reason) = map_error("[index]\ncell0 = { pitch = \"bass\", dots = [1] }");
    assert!(reason.contains("not allowed with `pitch`"), "{reason}");
}

#[test]
fn unknown_keys_are_syntax_errors_naming_the_key() {
    for (text, key) in [
        ("[thum]\ncell0 = { pitch = \"bass\" }", "thum"),
        ("[thumb]\ncell2 = { pitch = \"bass\" }", "cell2"),
        ("[thumb]\ncell0 = { pich = \"bass\" }", "pich"),
    ] {
        match GloveMap::from_toml_str(text) {
            Err(GloveError::MapSyntax(msg)) => {
                assert!(msg.contains(key), "{msg}");
                assert!(!msg.contains('\n'), "one line: {msg}");
            }
            other => panic!("expected syntax error for {text:?}, got {other:?}"),
        }
    }
    assert!(matches!(
        GloveMap::from_toml_str("[thumb"),
        Err(GloveError::MapSyntax(_))
    ));
    // Embedded in JSON, validation applies too.
    let err =
        serde_json::from_str::<GloveMap>(r#"{"thumb":{"cell0":{"pitch":"bas"}}}"#).unwrap_err();
    assert!(err.to_string().contains("thumb.cell0"), "{err}");
}

#[test]
fn set_validates() {
    let mut map = GloveMap::off();
    assert!(map
        .set(Finger::Pinky, 1, CellSource::PitchLevel(Stem::Drums))
        .is_err());
    assert!(map
        .set(
            Finger::Pinky,
            1,
            CellSource::BandOnsets {
                band: Band::Toms,
                dots: 0
            }
        )
        .is_err());
    map.set(
        Finger::Pinky,
        1,
        CellSource::BandOnsets {
            band: Band::Toms,
            dots: 3,
        },
    )
    .unwrap();
    assert_eq!(map.needs().bands, vec![Band::Toms]);
}

/// The obvious oracle: look up each cell's source and compute its byte by the contract.
fn render_oracle(map: &GloveMap, f: &BinFeatures, levels: u8) -> [u8; 10] {
    let order = [7u8, 3, 2, 1, 8, 6, 5, 4];
    let mut out = [0u8; 10];
    for finger in Finger::ALL {
        for cell in 0..2 {
            out[finger.index() * 2 + cell] = match map.get(finger, cell) {
                CellSource::Off => 0,
                CellSource::PitchLevel(s) => {
                    let l = f.level[Stem::ALL.iter().position(|x| *x == s).unwrap()];
                    if l == 0 || levels != 8 {
                        tactus_glove::level_dots(l, levels)
                    } else {
                        1 << (order[l.min(8) as usize - 1] - 1)
                    }
                }
                CellSource::NoteOnsets { stem, dots } => {
                    if f.note_onset[Stem::ALL.iter().position(|x| *x == stem).unwrap()] {
                        dots
                    } else {
                        0
                    }
                }
                CellSource::BandOnsets { band, dots } => {
                    if f.band_beat[Band::ALL.iter().position(|x| *x == band).unwrap()] {
                        dots
                    } else {
                        0
                    }
                }
            };
        }
    }
    out
}

#[test]
fn render_default_map_example() {
    let map = GloveMap::default();
    let mut f = BinFeatures::default();
    f.level[1] = 1; // bass level 1 -> dot 7
    f.level[2] = 8; // vocals level 8 -> dot 4
    f.note_onset[3] = true; // other note onset
    f.band_beat[3] = true; // cymbals
    let frame = map.render(&f, 8);
    assert_eq!(frame.0, [0x40, 0, 0, 0, 0, 0xff, 0x08, 0, 0, 0xff]);
    assert_eq!(map.render(&BinFeatures::default(), 8).raised_dots(), 0);
}

proptest! {
    #[test]
    fn render_matches_oracle(
        level in any::<[u8; 4]>().prop_map(|a| a.map(|x| x % 10)),
        note_onset in any::<[bool; 4]>(),
        band_beat in any::<[bool; 4]>(),
        which in 0usize..3,
    ) {
        let map = match which {
            0 => GloveMap::default(),
            1 => GloveMap::from_toml_str(DRUMS_ONLY_MAP_TOML).unwrap(),
            _ => GloveMap::from_toml_str(MELODY_MAP_TOML).unwrap(),
        };
        let f = BinFeatures { level, note_onset, band_beat };
        prop_assert_eq!(map.render(&f, 8).0, render_oracle(&map, &f, 8));
    }
}
