//! The glove model: dot numbering, level_dots, Frame accessors and hex.

use proptest::prelude::*;
use tactus_glove::{level_dots, Dot, Finger, Frame, GloveError, HexError, CELLS_PER_FINGER};

/// The contract, written out by hand: (level, dot number) for 8 levels.
const CONTRACT_LEVELS: [(u8, u8); 8] = [
    (1, 7),
    (2, 3),
    (3, 2),
    (4, 1),
    (5, 8),
    (6, 6),
    (7, 5),
    (8, 4),
];

#[test]
fn level_dots_matches_contract_for_8_levels() {
    assert_eq!(level_dots(0, 8), 0, "level 0 raises nothing");
    for (level, dot) in CONTRACT_LEVELS {
        // Bit k of a cell byte is dot k+1.
        assert_eq!(level_dots(level, 8), 1u8 << (dot - 1), "level {level}");
    }
}

#[test]
fn level_dots_climbs_left_column_then_right_column_upwards() {
    // Check the geometry: levels 1-4 in the left column with rows 3,2,1,0; 5-8 right, 3..0.
    for level in 1..=8u8 {
        let mask = level_dots(level, 8);
        assert_eq!(mask.count_ones(), 1);
        let dot = Dot::new(mask.trailing_zeros() as u8 + 1).unwrap();
        let expected_column = if level <= 4 { 0 } else { 1 };
        let expected_row = 3 - ((level as usize - 1) % 4);
        assert_eq!(
            (dot.column(), dot.row()),
            (expected_column, expected_row),
            "level {level}"
        );
    }
}

#[test]
fn level_dots_other_counts_are_monotone_and_span_the_positions() {
    // Position in the climb order for each single-dot mask.
    let order = [7u8, 3, 2, 1, 8, 6, 5, 4];
    let position = |mask: u8| order.iter().position(|&d| 1u8 << (d - 1) == mask).unwrap();
    for levels in 1..=32u8 {
        let mut last = 0;
        for level in 1..=levels {
            let mask = level_dots(level, levels);
            assert_eq!(mask.count_ones(), 1, "levels {levels} level {level}");
            let p = position(mask);
            assert!(p >= last, "not monotone: levels {levels} level {level}");
            last = p;
        }
        assert_eq!(position(level_dots(1, levels)), 0, "lowest level at dot 7");
        if levels > 1 {
            assert_eq!(
                position(level_dots(levels, levels)),
                7,
                "highest level at dot 4"
            );
        }
        assert_eq!(level_dots(0, levels), 0);
        // Levels above the count clamp to the top.
        assert_eq!(
            level_dots(levels.saturating_add(1).max(levels), levels),
            level_dots(levels, levels)
        );
    }
    // 4 levels: round(0, 7/3, 14/3, 7) = positions 0, 2, 5, 7 = dots 7, 2, 6, 4.
    let four: Vec<u8> = (1..=4).map(|l| level_dots(l, 4)).collect();
    assert_eq!(four, vec![1 << 6, 1 << 1, 1 << 5, 1 << 3]);
    assert_eq!(level_dots(3, 0), 0);
}

#[test]
fn dot_numbering_matches_braille() {
    let left: Vec<u8> = (0..4).map(|r| Dot::at(0, r).unwrap().number()).collect();
    let right: Vec<u8> = (0..4).map(|r| Dot::at(1, r).unwrap().number()).collect();
    assert_eq!(left, vec![1, 2, 3, 7]);
    assert_eq!(right, vec![4, 5, 6, 8]);
    assert!(Dot::at(2, 0).is_none() && Dot::at(0, 4).is_none());
    assert!(Dot::new(0).is_none() && Dot::new(9).is_none());
    for d in Dot::ALL {
        assert_eq!(d.mask(), 1 << (d.number() - 1));
        assert_eq!(Dot::at(d.column(), d.row()), Some(d));
    }
    assert_eq!(tactus_glove::dots_mask(&[1, 2, 3, 7]), 0b0100_0111);
}

#[test]
fn finger_names_round_trip_and_cells_are_in_wire_order() {
    for (i, f) in Finger::ALL.into_iter().enumerate() {
        assert_eq!(Finger::from_name(f.name()), Some(f));
        assert_eq!(f.index(), i);
    }
    assert_eq!(Finger::from_name("toe"), None);
    let mut frame = Frame::default();
    frame.set_cell(Finger::Ring, 1, 0xAB);
    assert_eq!(frame.0[7], 0xAB);
    assert_eq!(frame.cell(Finger::Ring, 1), 0xAB);
    assert_eq!(frame.cell(Finger::Ring, 0), 0);
}

#[test]
fn pins_iterate_80_in_finger_cell_dot_order() {
    let mut frame = Frame::default();
    frame.set_cell(Finger::Index, 1, 0b1000_0001); // dots 1 and 8
    let pins: Vec<_> = frame.pins().collect();
    assert_eq!(pins.len(), 80);
    assert_eq!(
        pins.iter().filter(|p| p.raised).count() as u32,
        frame.raised_dots()
    );
    let raised: Vec<usize> = pins
        .iter()
        .enumerate()
        .filter(|(_, p)| p.raised)
        .map(|(i, _)| i)
        .collect();
    // Index finger = finger 1, cell 1 -> pins 24..32; dot 1 at 24, dot 8 at 31.
    assert_eq!(raised, vec![24, 31]);
    assert_eq!(pins[24].finger, Finger::Index);
    assert_eq!(pins[24].cell, 1);
    assert_eq!(pins[31].dot.number(), 8);
    for (i, p) in pins.iter().enumerate() {
        assert_eq!(
            p.finger.index() * 16 + p.cell * 8 + (p.dot.number() as usize - 1),
            i
        );
    }
}

#[test]
fn hex_known_values_and_errors() {
    let f = Frame([0, 1, 0x10, 0xff, 0xab, 0, 0, 0, 0, 0x7f]);
    assert_eq!(f.to_hex(), "000110ffab000000007f");
    assert_eq!(Frame::from_hex("000110FFAB000000007F").unwrap(), f);
    let err = |s: &str| match Frame::from_hex(s) {
        Err(GloveError::Hex(e)) => e,
        other => panic!("expected hex error for {s:?}, got {other:?}"),
    };
    assert_eq!(err("000"), HexError::OddLength { chars: 3 });
    assert_eq!(
        err("000000000000000000"),
        HexError::WrongLength { bytes: 9 }
    );
    assert_eq!(
        err("0000000000000000000000"),
        HexError::WrongLength { bytes: 11 }
    );
    assert_eq!(err(""), HexError::WrongLength { bytes: 0 });
    assert_eq!(
        err("00000000000000000g00"),
        HexError::NotHex {
            position: 17,
            character: 'g'
        }
    );
    assert_eq!(
        err("é0000000000000000000"),
        HexError::NotHex {
            position: 0,
            character: 'é'
        }
    );
    assert_eq!(
        err("+1000000000000000000"),
        HexError::NotHex {
            position: 0,
            character: '+'
        }
    );
}

#[test]
#[should_panic(expected = "out of range")]
fn cell_index_2_panics_as_documented() {
    let _ = Frame::default().cell(Finger::Thumb, CELLS_PER_FINGER);
}

proptest! {
    #[test]
    fn hex_round_trip(bytes in any::<[u8; 10]>()) {
        let f = Frame(bytes);
        let h = f.to_hex();
        prop_assert_eq!(h.len(), 20);
        prop_assert!(h.chars().all(|c| c.is_ascii_digit() || ('a'..='f').contains(&c)));
        prop_assert_eq!(Frame::from_hex(&h).unwrap(), f);
        prop_assert_eq!(f.raised_dots(), bytes.iter().map(|b| b.count_ones()).sum::<u32>());
    }

    #[test]
    fn from_hex_never_panics(s in ".{0,30}") {
        let _ = Frame::from_hex(&s);
    }
}
