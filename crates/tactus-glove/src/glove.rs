//! The glove: fingers, braille cells, dots and the 10-byte [`Frame`] (docs/design.md, "The glove").
//!
//! The paper's glove (Electronics 2025, 14(18), 3658, §2) carries one pair of 8-dot piezo
//! braille cells on each finger: 5 fingers × 2 cells × 8 dots = 80 pins. Tactus describes
//! the state of every pin with one byte per cell, fingers in the order thumb, index, middle,
//! ring, pinky, cell 0 before cell 1, so a whole glove is 10 bytes.
//!
//! Dots use the 8-dot braille numbering: the left column holds dots 1, 2, 3, 7 from top to
//! bottom, the right column dots 4, 5, 6, 8. Bit `k` of a cell byte (`k = 0..7`) is dot
//! `k + 1`.
//!
//! A pitch **level** raises exactly one dot ([`level_dots`]): with 8 levels, levels 1–4 climb
//! the left column (dots 7, 3, 2, 1) and levels 5–8 climb the right column (dots 8, 6, 5, 4),
//! "upwards, rightwards, upwards"; level 0 raises nothing.
//!
//! Nothing here allocates; there is no latency (a frame is a state, not a process).

use std::fmt;

use crate::GloveError;

/// Braille cells on each finger.
pub const CELLS_PER_FINGER: usize = 2;
/// Braille cells on the glove (and bytes in a [`Frame`]).
pub const CELLS: usize = 10;
/// Dots (pins) in one cell.
pub const DOTS_PER_CELL: usize = 8;
/// Pins on the glove.
pub const PINS: usize = CELLS * DOTS_PER_CELL;
/// Time for a commanded pin to reach "up", in ms: the paper's 50 ms dot rising time.
/// Frames are sent this much early (plus the link's latency) so a pin is up when its sound
/// plays.
pub const PIN_RISE_MS: u32 = 50;

/// A finger of the glove, in wire order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Finger {
    /// First finger; cells 0–1 of the frame.
    Thumb,
    /// Cells 2–3.
    Index,
    /// Cells 4–5.
    Middle,
    /// Cells 6–7.
    Ring,
    /// Cells 8–9.
    Pinky,
}

impl Finger {
    /// All fingers in wire order.
    pub const ALL: [Finger; 5] = [
        Finger::Thumb,
        Finger::Index,
        Finger::Middle,
        Finger::Ring,
        Finger::Pinky,
    ];

    /// Lower-case name used in map files.
    pub fn name(self) -> &'static str {
        match self {
            Finger::Thumb => "thumb",
            Finger::Index => "index",
            Finger::Middle => "middle",
            Finger::Ring => "ring",
            Finger::Pinky => "pinky",
        }
    }

    /// Parses a lower-case name.
    pub fn from_name(s: &str) -> Option<Finger> {
        Finger::ALL.into_iter().find(|f| f.name() == s)
    }

    /// Position of the finger in wire order (0 = thumb).
    pub fn index(self) -> usize {
        self as usize
    }
}

impl fmt::Display for Finger {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One dot of an 8-dot braille cell, numbered 1–8 as in braille.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Dot(u8);

impl Dot {
    /// All dots in numerical order 1..=8 (= bit order of a cell byte).
    pub const ALL: [Dot; 8] = [
        Dot(1),
        Dot(2),
        Dot(3),
        Dot(4),
        Dot(5),
        Dot(6),
        Dot(7),
        Dot(8),
    ];

    /// The dot with braille number `number` (1–8); `None` otherwise.
    pub fn new(number: u8) -> Option<Dot> {
        (1..=8).contains(&number).then_some(Dot(number))
    }

    /// The dot at `column` (0 = left, 1 = right) and `row` (0 = top .. 3 = bottom);
    /// `None` outside the 2 × 4 grid.
    pub fn at(column: usize, row: usize) -> Option<Dot> {
        const GRID: [[u8; 4]; 2] = [[1, 2, 3, 7], [4, 5, 6, 8]];
        GRID.get(column)?.get(row).map(|&n| Dot(n))
    }

    /// Braille number, 1–8.
    pub fn number(self) -> u8 {
        self.0
    }

    /// The cell-byte mask of this dot: bit `number - 1`.
    pub fn mask(self) -> u8 {
        1 << (self.0 - 1)
    }

    /// Column: 0 = left (dots 1, 2, 3, 7), 1 = right (dots 4, 5, 6, 8).
    pub fn column(self) -> usize {
        match self.0 {
            1 | 2 | 3 | 7 => 0,
            _ => 1,
        }
    }

    /// Row from the top, 0–3.
    pub fn row(self) -> usize {
        match self.0 {
            1 | 4 => 0,
            2 | 5 => 1,
            3 | 6 => 2,
            _ => 3,
        }
    }
}

impl fmt::Display for Dot {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "dot {}", self.0)
    }
}

/// Builds a cell byte from braille dot numbers; numbers outside 1–8 are ignored.
pub fn dots_mask(numbers: &[u8]) -> u8 {
    numbers
        .iter()
        .filter_map(|&n| Dot::new(n))
        .fold(0, |m, d| m | d.mask())
}

/// The dots of a pitch level, lowest to highest: left column bottom to top, then the right
/// column bottom to top (docs/design.md: "upwards, rightwards, upwards").
pub const LEVEL_DOTS: [u8; 8] = [7, 3, 2, 1, 8, 6, 5, 4];

/// The cell byte that shows pitch `level` out of `levels`: exactly one raised dot, or none
/// for level 0.
///
/// * `levels == 8` (the default): level `L` raises dot `LEVEL_DOTS[L - 1]`, i.e. levels 1–4
///   raise dots 7, 3, 2, 1 and levels 5–8 raise dots 8, 6, 5, 4 (the contract).
/// * Other level counts spread levels 1..=`levels` evenly over those 8 positions, lowest
///   level on the lowest position and highest level on the highest:
///   position = round((L − 1) · 7 / (levels − 1)), half rounding up. With more than 8
///   levels neighbouring levels share a dot; with 1 level, level 1 raises dot 7.
/// * `level > levels` is treated as `levels`; `levels == 0` raises nothing.
pub fn level_dots(level: u8, levels: u8) -> u8 {
    if level == 0 || levels == 0 {
        return 0;
    }
    let level = level.min(levels) as u32;
    let position = if levels == 1 {
        0
    } else {
        let span = levels as u32 - 1;
        // round((level - 1) * 7 / span), halves up, in integers.
        ((level - 1) * 7 * 2 + span) / (2 * span)
    };
    Dot(LEVEL_DOTS[position as usize]).mask()
}

/// The state of all 80 pins: one byte per cell, cells in wire order
/// (thumb cell 0, thumb cell 1, index cell 0, …, pinky cell 1).
#[derive(Clone, Copy, Default, PartialEq, Eq, Hash, Debug)]
pub struct Frame(pub [u8; CELLS]);

/// One pin of the glove, as yielded by [`Frame::pins`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Pin {
    /// The finger carrying the pin.
    pub finger: Finger,
    /// Cell on that finger, 0 or 1.
    pub cell: usize,
    /// The dot within the cell.
    pub dot: Dot,
    /// Whether the pin is raised.
    pub raised: bool,
}

impl Frame {
    /// All pins down.
    pub const DOWN: Frame = Frame([0; CELLS]);

    /// Index of a finger's cell in the 10 bytes.
    ///
    /// # Panics
    /// If `cell >= CELLS_PER_FINGER`.
    pub fn cell_index(finger: Finger, cell: usize) -> usize {
        assert!(cell < CELLS_PER_FINGER, "cell {cell} out of range 0..2");
        finger.index() * CELLS_PER_FINGER + cell
    }

    /// The byte of `finger`'s `cell`.
    ///
    /// # Panics
    /// If `cell >= CELLS_PER_FINGER`.
    pub fn cell(&self, finger: Finger, cell: usize) -> u8 {
        self.0[Self::cell_index(finger, cell)]
    }

    /// Sets the byte of `finger`'s `cell`.
    ///
    /// # Panics
    /// If `cell >= CELLS_PER_FINGER`.
    pub fn set_cell(&mut self, finger: Finger, cell: usize, dots: u8) {
        self.0[Self::cell_index(finger, cell)] = dots;
    }

    /// Whether one pin is raised.
    ///
    /// # Panics
    /// If `cell >= CELLS_PER_FINGER`.
    pub fn is_raised(&self, finger: Finger, cell: usize, dot: Dot) -> bool {
        self.cell(finger, cell) & dot.mask() != 0
    }

    /// How many of the 80 pins are raised.
    pub fn raised_dots(&self) -> u32 {
        self.0.iter().map(|b| b.count_ones()).sum()
    }

    /// The 80 pins in a fixed order: finger (thumb first), cell (0 first), dot (1..=8).
    pub fn pins(&self) -> impl Iterator<Item = Pin> + '_ {
        Finger::ALL.into_iter().flat_map(move |finger| {
            (0..CELLS_PER_FINGER).flat_map(move |cell| {
                let byte = self.cell(finger, cell);
                Dot::ALL.into_iter().map(move |dot| Pin {
                    finger,
                    cell,
                    dot,
                    raised: byte & dot.mask() != 0,
                })
            })
        })
    }

    /// The 10 bytes as 20 lower-case hex characters (the pattern file's frame format).
    pub fn to_hex(&self) -> String {
        const DIGITS: &[u8; 16] = b"0123456789abcdef";
        let mut s = String::with_capacity(2 * CELLS);
        for &b in &self.0 {
            s.push(DIGITS[(b >> 4) as usize] as char);
            s.push(DIGITS[(b & 15) as usize] as char);
        }
        s
    }

    /// Parses 20 hex characters (either case). Errors name the problem: a length other
    /// than 20 (counting characters, so a 9-byte frame reports 18), or the position of the
    /// first character that is not a hex digit.
    pub fn from_hex(s: &str) -> Result<Frame, GloveError> {
        let chars = s.chars().count();
        if let Some((position, character)) =
            s.chars().enumerate().find(|(_, c)| !c.is_ascii_hexdigit())
        {
            return Err(GloveError::Hex(HexError::NotHex {
                position,
                character,
            }));
        }
        if chars & 1 == 1 {
            return Err(GloveError::Hex(HexError::OddLength { chars }));
        }
        if chars != 2 * CELLS {
            return Err(GloveError::Hex(HexError::WrongLength { bytes: chars / 2 }));
        }
        let bytes = s.as_bytes();
        let mut frame = Frame::DOWN;
        for (i, out) in frame.0.iter_mut().enumerate() {
            let hi = hex_value(bytes[2 * i]);
            let lo = hex_value(bytes[2 * i + 1]);
            *out = (hi << 4) | lo;
        }
        Ok(frame)
    }
}

/// Value of an ASCII hex digit already checked with `is_ascii_hexdigit`.
fn hex_value(c: u8) -> u8 {
    match c {
        b'0'..=b'9' => c - b'0',
        b'a'..=b'f' => c - b'a' + 10,
        _ => c - b'A' + 10,
    }
}

/// What is wrong with a hex frame.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum HexError {
    /// An odd number of hex digits.
    #[error("odd number of hex digits ({chars}); a frame is 20 hex digits = 10 cell bytes")]
    OddLength {
        /// Characters found.
        chars: usize,
    },
    /// An even number of digits, but not 10 bytes.
    #[error("{bytes} bytes instead of 10 (a frame is 20 hex digits = 10 cell bytes)")]
    WrongLength {
        /// Bytes found.
        bytes: usize,
    },
    /// A character that is not a hex digit.
    #[error("character {character:?} at position {position} is not a hex digit")]
    NotHex {
        /// Character index (0-based).
        position: usize,
        /// The offending character.
        character: char,
    },
}
