//! The terminal glove view (`tactus live --tui`, `tactus play --tui`): one
//! [`Frame`] and a status, as lines of plain ASCII text.
//!
//! Pure functions only: [`render`] turns a frame and a [`ViewStatus`] into lines,
//! [`redraw`] wraps them in the ANSI escapes that draw them over the previous view, and
//! [`read_frame`] reads the dots back from a screen (what a test captures from a terminal).
//! The caller owns the terminal and the timing.
//!
//! ## Layout
//! Each finger shows its two cells side by side (`c0`, `c1`), each cell as the 2 × 4 dots
//! of a metec P20 braille cell seen from above: left column top to bottom dots 1, 2, 3, 7,
//! right column dots 4, 5, 6, 8 (the numbering of the wire protocol: bit `k` of a cell byte
//! is dot `k + 1`). A raised pin is [`RAISED`] (`O`), a lowered one [`LOWERED`] (`.`). The
//! row labels name the dots of each row:
//!
//! ```text
//! tactus live   12.30 s   link up   latency 17.2 ms (bin end -> sent)
//! input  -23.4 dBFS [############--------]
//! frames 1230  dropped 3  overruns 0
//!          thumb    index    middle   ring     pinky
//!          c0 c1    c0 c1    c0 c1    c0 c1    c0 c1
//! dots 1 4 O. ..    OO OO    .. ..    .. O.    .. ..
//! dots 2 5 .. ..    OO OO    .. ..    .. ..    .. ..
//! dots 3 6 .. ..    OO OO    .. ..    .. ..    .. ..
//! dots 7 8 .. ..    OO OO    .. ..    .. ..    .. ..
//! frame 4000ffff000000000000
//! ```
//!
//! Every line is at most [`WIDTH`] columns of ASCII, so any terminal shows it unchanged.
//!
//! ```
//! use tactus_glove::tui::{read_frame, render, ViewStatus};
//! use tactus_glove::{Finger, Frame};
//!
//! let mut frame = Frame::DOWN;
//! frame.set_cell(Finger::Index, 0, 0xFF); // a kick: all eight dots of the index's cell 0
//! let lines = render(&frame, &ViewStatus::default());
//! assert_eq!(lines[5], "dots 1 4 .. ..    OO ..    .. ..    .. ..    .. ..");
//! assert_eq!(read_frame(&lines), Some(frame));
//! ```

use std::fmt::Write as _;

use crate::glove::{Dot, Finger, Frame, CELLS_PER_FINGER};

/// The glyph of a raised pin.
pub const RAISED: char = 'O';
/// The glyph of a lowered pin.
pub const LOWERED: char = '.';
/// The widest line [`render`] writes, in columns.
pub const WIDTH: usize = 78;

/// Columns before the first finger (the row labels, `"dots 1 4 "`).
const LABEL: usize = 9;
/// Columns per finger: two cells of two dots, a space between, four spaces after.
const FINGER: usize = 9;
/// Row labels: the dots of each row, left column then right.
const ROWS: [&str; 4] = ["dots 1 4 ", "dots 2 5 ", "dots 3 6 ", "dots 7 8 "];

/// The link's state as the view shows it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LinkState {
    /// Not known (nothing sent yet).
    #[default]
    Unknown,
    /// Connected.
    Up,
    /// Lost; the sink is reconnecting.
    Down,
    /// Closed at the end of the session.
    Closed,
}

/// What the view shows besides the dots.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ViewStatus {
    /// Which program: `live` or `play`.
    pub title: String,
    /// The shown frame's time since the stream started, s.
    pub time_s: f64,
    /// The link.
    pub link: LinkState,
    /// Input level, dBFS (`None`: no input, as in `play`).
    pub level_dbfs: Option<f32>,
    /// A latency to show, ms, and what it measures.
    pub latency: Option<(f64, String)>,
    /// Counters, one line of free text (frames, dropped, overruns...).
    pub counters: String,
}

/// The view of `frame` with `status`: the lines of the module docs' layout, without line
/// ends. Each line is ASCII and at most [`WIDTH`] columns.
pub fn render(frame: &Frame, status: &ViewStatus) -> Vec<String> {
    let mut lines = Vec::with_capacity(11);
    let mut head = format!(
        "tactus {}   {:.2} s   link {}",
        if status.title.is_empty() {
            "glove"
        } else {
            &status.title
        },
        status.time_s,
        match status.link {
            LinkState::Unknown => "-",
            LinkState::Up => "up",
            LinkState::Down => "DOWN",
            LinkState::Closed => "closed",
        }
    );
    if let Some((ms, what)) = &status.latency {
        let _ = write!(head, "   latency {ms:.1} ms");
        if !what.is_empty() {
            let _ = write!(head, " ({what})");
        }
    }
    lines.push(head);
    lines.push(match status.level_dbfs {
        Some(db) if db.is_finite() => {
            // 20 steps of 3 dB from -60 dBFS to 0 dBFS.
            let n = ((f64::from(db) + 60.0) / 3.0).clamp(0.0, 20.0) as usize;
            format!(
                "input {db:>6.1} dBFS [{}{}]",
                "#".repeat(n),
                "-".repeat(20 - n)
            )
        }
        Some(_) => "input   -inf dBFS [--------------------]".to_string(),
        None => "input  none".to_string(),
    });
    lines.push(status.counters.clone());
    let mut names = " ".repeat(LABEL);
    let mut cells = " ".repeat(LABEL);
    for finger in Finger::ALL {
        let _ = write!(names, "{:<w$}", finger.name(), w = FINGER);
        let _ = write!(cells, "{:<w$}", "c0 c1", w = FINGER);
    }
    lines.push(names.trim_end().to_string());
    lines.push(cells.trim_end().to_string());
    for (row, label) in ROWS.iter().enumerate() {
        let mut line = String::with_capacity(LABEL + 5 * FINGER);
        line.push_str(label);
        for finger in Finger::ALL {
            for cell in 0..CELLS_PER_FINGER {
                for column in 0..2 {
                    let dot = Dot::at(column, row).expect("2 x 4 grid");
                    line.push(if frame.is_raised(finger, cell, dot) {
                        RAISED
                    } else {
                        LOWERED
                    });
                }
                line.push(' ');
            }
            line.push_str("   ");
        }
        lines.push(line.trim_end().to_string());
    }
    lines.push(format!("frame {}", frame.to_hex()));
    for l in &mut lines {
        // Counters are free text: keep the width promise.
        if l.len() > WIDTH || !l.is_ascii() {
            *l = l
                .chars()
                .map(|c| if c.is_ascii() { c } else { '?' })
                .take(WIDTH)
                .collect();
        }
    }
    lines
}

/// The bytes that draw `lines` in place of a view of `previous` lines drawn just above the
/// cursor (0: the first draw): cursor up, each line then "erase to end of line", a newline.
/// The cursor ends below the view, so whatever is printed afterwards follows it.
pub fn redraw(lines: &[String], previous: usize) -> String {
    let mut s = String::with_capacity(lines.iter().map(|l| l.len() + 4).sum::<usize>() + 8);
    if previous > 0 {
        let _ = write!(s, "\x1b[{previous}A\r");
    }
    for l in lines {
        s.push_str(l);
        s.push_str("\x1b[K\n");
    }
    // A shorter view than the last: clear what is left below.
    if previous > lines.len() {
        s.push_str("\x1b[J");
    }
    s
}

/// Reads the frame back from a screen showing a view (lines as [`render`] wrote them,
/// anywhere among other lines, e.g. a whole terminal captured): the four dot rows after the
/// first line that starts with `dots 1 4`. `None` when there is no complete view.
pub fn read_frame<S: AsRef<str>>(screen: &[S]) -> Option<Frame> {
    let start = screen
        .iter()
        .position(|l| l.as_ref().starts_with(ROWS[0]))?;
    let rows = screen.get(start..start + 4)?;
    let mut frame = Frame::DOWN;
    for (row, line) in rows.iter().enumerate() {
        let line = line.as_ref().as_bytes();
        if !line.starts_with(ROWS[row].as_bytes()) {
            return None;
        }
        for finger in Finger::ALL {
            for cell in 0..CELLS_PER_FINGER {
                let mut byte = frame.cell(finger, cell);
                for column in 0..2 {
                    let at = LABEL + finger.index() * FINGER + cell * 3 + column;
                    match line.get(at).map(|&b| char::from(b)) {
                        Some(RAISED) => byte |= Dot::at(column, row).expect("2 x 4 grid").mask(),
                        Some(LOWERED) => {}
                        _ => return None,
                    }
                }
                frame.set_cell(finger, cell, byte);
            }
        }
    }
    Some(frame)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The oracle, written out by hand from the contract (DESIGN.md, "The glove"): dot
    /// number -> (column, row) in a cell seen from above.
    const POSITION: [(usize, usize); 8] = [
        (0, 0), // dot 1
        (0, 1), // dot 2
        (0, 2), // dot 3
        (1, 0), // dot 4
        (1, 1), // dot 5
        (1, 2), // dot 6
        (0, 3), // dot 7
        (1, 3), // dot 8
    ];

    /// Where the glyph of (finger, cell, bit) is: (line, column) in the rendered view.
    fn place(finger: usize, cell: usize, bit: usize) -> (usize, usize) {
        let (column, row) = POSITION[bit];
        // Line 5 is the first dot row; each finger is 9 columns after the 9-column labels.
        (5 + row, 9 + 9 * finger + 3 * cell + column)
    }

    fn glyphs(lines: &[String]) -> Vec<(usize, usize, char)> {
        let mut v = Vec::new();
        for (i, l) in lines.iter().enumerate().skip(5).take(4) {
            for (j, c) in l.chars().enumerate() {
                if c == RAISED || c == LOWERED {
                    v.push((i, j, c));
                }
            }
        }
        v
    }

    #[test]
    fn every_dot_of_every_finger_is_drawn_where_the_contract_puts_it() {
        for finger in 0..5 {
            for cell in 0..2 {
                for bit in 0..8 {
                    let mut frame = Frame::DOWN;
                    frame.0[finger * 2 + cell] = 1 << bit;
                    let lines = render(&frame, &ViewStatus::default());
                    let g = glyphs(&lines);
                    assert_eq!(g.len(), 80, "80 pins drawn");
                    let raised: Vec<_> = g.iter().filter(|x| x.2 == RAISED).collect();
                    let (line, col) = place(finger, cell, bit);
                    assert_eq!(
                        raised,
                        vec![&(line, col, RAISED)],
                        "finger {finger} cell {cell} dot {}\n{}",
                        bit + 1,
                        lines.join("\n")
                    );
                    assert_eq!(read_frame(&lines), Some(frame));
                }
            }
        }
    }

    #[test]
    fn any_frame_reads_back_and_every_glyph_matches_its_bit() {
        // Seeded LCG: 2000 random frames.
        let mut seed = 0x1234_5678u32;
        for _ in 0..2000 {
            let mut frame = Frame::DOWN;
            for b in &mut frame.0 {
                seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                *b = (seed >> 24) as u8;
            }
            let lines = render(&frame, &ViewStatus::default());
            for finger in 0..5 {
                for cell in 0..2 {
                    for bit in 0..8 {
                        let (line, col) = place(finger, cell, bit);
                        let want = if frame.0[finger * 2 + cell] >> bit & 1 == 1 {
                            RAISED
                        } else {
                            LOWERED
                        };
                        assert_eq!(lines[line].as_bytes()[col] as char, want);
                    }
                }
            }
            assert_eq!(read_frame(&lines), Some(frame));
            assert!(lines.last().unwrap().ends_with(&frame.to_hex()));
        }
    }

    #[test]
    fn the_view_is_found_on_a_whole_screen_and_a_broken_one_is_not_read() {
        let mut frame = Frame::DOWN;
        frame.set_cell(Finger::Pinky, 1, 0b1000_0001);
        let mut screen = vec!["$ tactus live --tui".to_string(), String::new()];
        screen.extend(render(&frame, &ViewStatus::default()));
        screen.push("tactus: something else".into());
        assert_eq!(read_frame(&screen), Some(frame));
        // A truncated view (a terminal too narrow or too short) is not a frame.
        let cut: Vec<String> = screen
            .iter()
            .map(|l| l.chars().take(40).collect())
            .collect();
        assert_eq!(read_frame(&cut), None);
        assert_eq!(read_frame(&screen[..screen.len() - 3]), None);
        assert_eq!(read_frame::<&str>(&[]), None);
    }

    #[test]
    fn status_lines_show_title_time_link_level_latency_and_counters() {
        let st = ViewStatus {
            title: "live".into(),
            time_s: 12.3,
            link: LinkState::Down,
            level_dbfs: Some(-23.4),
            latency: Some((17.25, "bin end -> sent".into())),
            counters: "frames 1230  overruns 0".into(),
        };
        let lines = render(&Frame::DOWN, &st);
        assert_eq!(
            lines[0],
            "tactus live   12.30 s   link DOWN   latency 17.2 ms (bin end -> sent)"
        );
        // -23.4 dBFS: (60 - 23.4) / 3 = 12 steps of 20.
        assert_eq!(lines[1], "input  -23.4 dBFS [############--------]");
        assert_eq!(lines[2], "frames 1230  overruns 0");
        assert_eq!(
            lines[3],
            "         thumb    index    middle   ring     pinky"
        );
        let quiet = render(
            &Frame::DOWN,
            &ViewStatus {
                level_dbfs: Some(f32::NEG_INFINITY),
                ..ViewStatus::default()
            },
        );
        assert_eq!(quiet[1], "input   -inf dBFS [--------------------]");
        assert_eq!(
            render(&Frame::DOWN, &ViewStatus::default())[1],
            "input  none"
        );
        // Long or non-ASCII counters keep the width promise.
        let wide = render(
            &Frame([0xFF; 10]),
            &ViewStatus {
                counters: "é".repeat(200),
                ..ViewStatus::default()
            },
        );
        assert!(wide.iter().all(|l| l.len() <= WIDTH && l.is_ascii()));
    }

    #[test]
    fn redraw_moves_up_over_the_previous_view_and_clears_what_is_left() {
        let a = render(&Frame::DOWN, &ViewStatus::default());
        let first = redraw(&a, 0);
        assert!(!first.replace("\x1b[K", "").contains("\x1b["), "{first:?}");
        assert_eq!(first.matches('\n').count(), a.len());
        let second = redraw(&a, a.len());
        assert!(second.starts_with(&format!("\x1b[{}A\r", a.len())));
        assert!(redraw(&a[..3], a.len()).ends_with("\x1b[J"));
    }
}
