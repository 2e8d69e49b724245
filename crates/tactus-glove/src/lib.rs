//! # tactus-glove: the glove model, the pin map, the wire protocol and the file formats
//!
//! The haptic glove of the paper (Electronics 2025, 14(18), 3658) has 80 piezo pins: five
//! fingers, two 8-dot braille cells per finger. This crate describes that hardware and
//! everything that talks about it, with no DSP and no I/O beyond reading and writing files:
//!
//! | module | what |
//! |---|---|
//! | [`glove`] | [`Finger`], [`Dot`], the 10-byte [`Frame`], [`level_dots`] |
//! | [`map`] | [`GloveMap`]: which feature each cell shows (TOML), what it [`needs`](GloveMap::needs), [`render`](GloveMap::render) |
//! | [`protocol`] | wire protocol v1: 16-byte [`Packet`]s, [`crc8`], the resynchronising [`Decoder`] |
//! | [`pattern`] | the pattern file v1 (JSON): a song's frames |
//! | [`features`] | the features file (JSON): pitch, levels, onsets, beats |
//! | [`export`] | CSV (one row per bin, one column per dot) and Apple AHAP exports |
//! | [`html`] | the browser preview page ([`html::render_page`]) |
//! | [`atomic`] | [`write_atomic`]: every output file is replaced atomically |
//! | [`tui`] | the terminal glove view: a frame and a status as lines of text, and back |
//!
//! ## Tutorial
//!
//! A map decides what the engine computes and how one bin's features become pins:
//!
//! ```
//! use tactus_glove::{Band, BinFeatures, Decoder, Finger, GloveMap, Packet, Stem};
//!
//! // The default map (maps/default.toml): bass on the thumb, drums on index and middle, ...
//! let map = GloveMap::default();
//! assert_eq!(map.needs().pitch, vec![Stem::Bass, Stem::Vocals, Stem::Other]);
//!
//! // A drums-only map needs only the drum stem: no pitch tracking runs.
//! let drums = GloveMap::from_toml_str(r#"
//!     [index]
//!     cell0 = { onsets = "kick" }
//!     cell1 = { onsets = "snare", dots = [1, 4] }
//! "#).unwrap();
//! assert_eq!(drums.stems(), vec![Stem::Drums]);
//!
//! // One 100 ms bin: the bass is at level 5 of 8 and the kick hits.
//! let mut bin = BinFeatures::default();
//! bin.level[Stem::Bass as usize] = 5;
//! bin.band_beat[Band::Kick as usize] = true;
//! let frame = map.render(&bin, 8);
//! assert_eq!(frame.cell(Finger::Thumb, 0), 0b1000_0000); // level 5 = dot 8
//! assert_eq!(frame.cell(Finger::Index, 0), 0xFF);        // kick: all 8 dots
//! assert_eq!(frame.raised_dots(), 9);
//! assert_eq!(frame.to_hex(), "8000ff00000000000000"); // 10 cell bytes, thumb first
//!
//! // Send it: 16 bytes on the wire, decoded on the glove's side.
//! let bytes = Packet::pins(0, 100, frame).encode();
//! let mut decoder = Decoder::new();
//! let mut got = Vec::new();
//! decoder.push(&bytes, &mut |p| got.push(p));
//! assert_eq!(got, vec![Packet::pins(0, 100, frame)]);
//! ```
//!
//! Files: [`Pattern`] (`render -o`), [`Features`] (`render --features`) and maps are
//! validated on read with errors that name the key, finger/cell or frame index
//! ([`GloveError`]).
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod atomic;
mod error;
pub mod export;
pub mod features;
pub mod glove;
pub mod html;
mod json;
pub mod map;
pub mod pattern;
pub mod plot;
#[cfg(feature = "png")]
pub mod png;
pub mod protocol;
#[cfg(test)]
mod test_sample;
pub mod tui;

pub use atomic::{write_atomic, OutputError, OutputSet};
pub use error::GloveError;
pub use features::Features;
pub use glove::{
    dots_mask, level_dots, Dot, Finger, Frame, HexError, Pin, CELLS, CELLS_PER_FINGER,
    DOTS_PER_CELL, PINS, PIN_RISE_MS,
};
pub use map::{BinFeatures, CellSource, GloveMap, Needs, BUILTIN_MAPS};
pub use pattern::{sha256_file, sha256_hex, Pattern, SourceInfo};
pub use protocol::{crc8, Decoder, DecoderStats, Packet, PacketType, SYNC};
pub use tactus_dsp::{Band, Stem};
