//! The pattern and features as a figure (`render --plot`), after the paper's Figures 5 and 7.
//!
//! * one panel per melodic stem: the pitch contour (on a semitone scale, labelled with note
//!   names and Hz) and the tactile level per bin (0 at the bottom to the top level);
//! * one raster per drum band: onsets as ticks over the beat bins they light;
//! * the glove: a piano roll of the 80 dots over time (finger, cell, dot), runs merged, each
//!   finger's two cells labelled with what the map shows on them;
//! * a key under the time axis saying what each mark means.
//!
//! The figure is drawn as SVG ([`render_svg`]); the `tactus` binary writes it as is or
//! rasterises it to PNG.
//!
//! Layout (SVG units = PNG pixels; `tests/cli.rs` checks the PNG against it): width 1400, plots
//! from x = 110 to 1380; title at y = 22; pitch panels 140 high from y = 40, one every 166;
//! band rasters 28 high, one every 34; then 20 more and the piano roll, 80 rows of 4 (row =
//! 8 × cell index + dot index, cells thumb 0, thumb 1, index 0, ...), each dot drawn 3.2 high
//! from the top of its row; a bin `k` spans `[k, k+1) × bin / duration` of the plot width;
//! the time axis 18 below the roll and the key's three lines 20, 35 and 50 below it.
//! Every run of raised dots of one row is one subpath of that row's single `<path>`, so the
//! element count stays small for any song length (usvg refuses more than 10⁶ elements).

use std::fmt::Write as _;

use crate::map::CellSource;
use crate::{Features, Finger, Pattern};

const W: f64 = 1400.0;
const LEFT: f64 = 110.0;
const RIGHT: f64 = 20.0;
const PITCH_H: f64 = 140.0;
const BAND_H: f64 = 28.0;
const DOT_H: f64 = 4.0;
const GAP: f64 = 26.0;

/// A panel's frame (`h` high at `y`, the plot's width) and its label at the left margin,
/// `label_dy` below the top in `font_size`.
fn panel(s: &mut String, y: f64, plot_w: f64, h: f64, label: &str, label_dy: f64, font_size: u32) {
    let _ = writeln!(
        s,
        r##"<rect x="{LEFT}" y="{y}" width="{plot_w}" height="{h}" fill="#fafafa" stroke="#ccc"/>"##
    );
    let _ = writeln!(
        s,
        r#"<text x="8" y="{}" font-size="{font_size}">{}</text>"#,
        y + label_dy,
        esc(label)
    );
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Names of the twelve pitch classes, C first.
const NOTE_NAMES: [&str; 12] = [
    "C", "C#", "D", "D#", "E", "F", "F#", "G", "G#", "A", "A#", "B",
];

/// The note name of MIDI semitone `st` (A4 = 69) and its frequency in Hz (`A2`, `110 Hz`).
fn note_and_hz(st: f64) -> (String, String) {
    let n = st.round() as i64;
    let hz = 440.0 * ((n as f64 - 69.0) / 12.0).exp2();
    (
        format!(
            "{}{}",
            NOTE_NAMES[n.rem_euclid(12) as usize],
            n.div_euclid(12) - 1
        ),
        format!("{hz:.0} Hz"),
    )
}

/// What a cell shows, in a few words for the piano roll's margin.
fn cell_words(source: CellSource) -> String {
    match source {
        CellSource::Off => "nothing".into(),
        CellSource::PitchLevel(stem) => format!("{} level", stem.name()),
        CellSource::NoteOnsets { stem, .. } => format!("{} onsets", stem.name()),
        CellSource::BandOnsets { band, .. } => band.name().into(),
    }
}

/// Time to x: the plot's width spans the song.
struct TimeAxis {
    duration: f64,
    plot_w: f64,
}

impl TimeAxis {
    fn x(&self, t: f64) -> f64 {
        LEFT + self.plot_w * (t / self.duration).clamp(0.0, 1.0)
    }
}

/// Draws the plot.
pub fn render_svg(pattern: &Pattern, f: &Features) -> String {
    let duration = pattern.source.duration_s.max(1e-3);
    let plot_w = W - LEFT - RIGHT;
    let axis = TimeAxis { duration, plot_w };
    let n_pitch = f.pitch_hz.len() as f64;
    let n_bands = f.beats.len() as f64;
    let roll_h = 80.0 * DOT_H;
    let height = 60.0 + n_pitch * (PITCH_H + GAP) + n_bands * (BAND_H + 6.0) + GAP + roll_h + 50.0;
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{height:.0}" viewBox="0 0 {W} {height:.0}" font-family="sans-serif" font-size="11">"#
    );
    let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{LEFT}" y="22" font-size="15">{} — {:.1} s, {} bins of {} ms, {} levels</text>"#,
        esc(&pattern.source.path),
        duration,
        pattern.frames.len(),
        pattern.bin_ms,
        pattern.levels
    );
    let mut y = 40.0;
    for (stem, hz) in &f.pitch_hz {
        pitch_panel(&mut s, &axis, y, stem, hz, pattern, f);
        y += PITCH_H + GAP;
    }
    let bin_s = pattern.bin_ms as f64 / 1000.0;
    for (band, beats) in &f.beats {
        band_raster(&mut s, &axis, y, band, beats, f.onsets_s.get(band), bin_s);
        y += BAND_H + 6.0;
    }
    y += GAP - 6.0;
    piano_roll(&mut s, &axis, y, pattern);
    y += roll_h + 18.0;
    time_labels(&mut s, &axis, y);
    key(&mut s, y, pattern.levels);
    s.push_str("</svg>\n");
    s
}

/// One melodic stem's panel at `y`: its pitch contour (semitones) and its level per bin.
fn pitch_panel(
    s: &mut String,
    axis: &TimeAxis,
    y: f64,
    stem: &str,
    hz: &[f32],
    pattern: &Pattern,
    f: &Features,
) {
    let (plot_w, bin_s) = (axis.plot_w, pattern.bin_ms as f64 / 1000.0);
    let x_of = |t: f64| axis.x(t);
    let voiced: Vec<f64> = hz
        .iter()
        .filter(|&&v| v > 0.0)
        .map(|&v| 69.0 + 12.0 * (v as f64 / 440.0).log2())
        .collect();
    let (lo, hi) = voiced
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    let (lo, hi) = if voiced.is_empty() {
        (40.0, 80.0)
    } else {
        (lo.floor() - 1.0, hi.ceil() + 1.0)
    };
    let y_of = |st: f64| y + PITCH_H - PITCH_H * (st - lo) / (hi - lo).max(1.0);
    panel(s, y, plot_w, PITCH_H, stem, 16.0, 13);
    let _ = writeln!(
        s,
        r##"<text x="8" y="{}" fill="#1f77b4">pitch</text>"##,
        y + 32.0
    );
    let _ = writeln!(
        s,
        r##"<text x="8" y="{}" fill="#d62728">level</text>"##,
        y + 46.0
    );
    pitch_axis(s, y, lo, hi, &y_of);
    // The level scale at the right edge: 0 at the bottom, the top level at the top.
    let _ = writeln!(
        s,
        r##"<text x="{}" y="{}" font-size="10" fill="#d62728">{}</text>"##,
        W - RIGHT + 3.0,
        y + 10.0,
        pattern.levels
    );
    let _ = writeln!(
        s,
        r##"<text x="{}" y="{}" font-size="10" fill="#d62728">0</text>"##,
        W - RIGHT + 3.0,
        y + PITCH_H - 2.0
    );
    // levels as a step line scaled to the panel
    if let Some(levels) = f.levels.get(stem) {
        let mut d = String::new();
        let lv_y = |l: u8| y + PITCH_H - PITCH_H * l as f64 / pattern.levels.max(1) as f64;
        for (k, &l) in levels.iter().enumerate() {
            let (x0, x1) = (x_of(k as f64 * bin_s), x_of((k + 1) as f64 * bin_s));
            let _ = write!(
                d,
                "{}{x0:.1},{:.1} L{x1:.1},{:.1} ",
                if k == 0 { "M" } else { "L" },
                lv_y(l),
                lv_y(l)
            );
        }
        let _ = writeln!(
            s,
            r##"<path d="{d}" fill="none" stroke="#d62728" stroke-width="1" opacity="0.7"/>"##
        );
    }
    // pitch contour as short segments between consecutive voiced hops
    let mut d = String::new();
    let mut prev = false;
    for (i, &v) in hz.iter().enumerate() {
        if v > 0.0 {
            let st = 69.0 + 12.0 * (v as f64 / 440.0).log2();
            let _ = write!(
                d,
                "{}{:.1},{:.1} ",
                if prev { "L" } else { "M" },
                x_of(i as f64 * f.hop_s),
                y_of(st)
            );
            prev = true;
        } else {
            prev = false;
        }
    }
    let _ = writeln!(
        s,
        r##"<path d="{d}" fill="none" stroke="#1f77b4" stroke-width="1.2"/>"##
    );
}

/// The pitch axis of a panel at `y` spanning semitones `lo..hi`, at the left of the plot: its
/// two ends as note names over Hz, and every C between them as one label and a faint line
/// across.
fn pitch_axis(s: &mut String, y: f64, lo: f64, hi: f64, y_of: &dyn Fn(f64) -> f64) {
    let label = |s: &mut String, at: f64, text: &str| {
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{at:.1}" font-size="10" text-anchor="end">{text}</text>"#,
            LEFT - 4.0
        );
    };
    let (note, hz) = note_and_hz(hi);
    label(s, y + 10.0, &note);
    label(s, y + 21.0, &hz);
    let (note, hz) = note_and_hz(lo);
    label(s, y + PITCH_H - 11.0, &hz);
    label(s, y + PITCH_H, &note);
    let mut d = String::new();
    let first = (lo / 12.0).floor() as i64 * 12 + 12;
    for c in (first..hi.ceil() as i64).step_by(12) {
        let cy = y_of(c as f64);
        let _ = write!(d, "M{LEFT},{cy:.1}H{} ", W - RIGHT);
        // Labelled where it does not crowd the ends' labels.
        if cy > y + 32.0 && cy < y + PITCH_H - 24.0 {
            let (note, hz) = note_and_hz(c as f64);
            label(s, cy + 3.5, &format!("{note} {hz}"));
        }
    }
    if !d.is_empty() {
        let _ = writeln!(
            s,
            r##"<path d="{d}" stroke="#e4e4e4" stroke-dasharray="4 3"/>"##
        );
    }
}

/// One drum band's raster at `y`: its beat bins as bands, its onsets as ticks.
fn band_raster(
    s: &mut String,
    axis: &TimeAxis,
    y: f64,
    band: &str,
    beats: &[u8],
    onsets: Option<&Vec<f64>>,
    bin_s: f64,
) {
    let plot_w = axis.plot_w;
    let x_of = |t: f64| axis.x(t);
    panel(s, y, plot_w, BAND_H, band, 18.0, 12);
    let mut d = String::new();
    for (k, &b) in beats.iter().enumerate() {
        if b != 0 {
            let (x0, x1) = (x_of(k as f64 * bin_s), x_of((k + 1) as f64 * bin_s));
            let w = (x1 - x0).max(0.5);
            let _ = write!(d, "M{x0:.1},{y}h{w:.2}v{BAND_H}h{:.2}z", -w);
        }
    }
    if !d.is_empty() {
        let _ = writeln!(s, r##"<path d="{d}" fill="#ff7f0e" fill-opacity="0.35"/>"##);
    }
    if let Some(on) = onsets {
        let mut d = String::new();
        for &t in on {
            let x = x_of(t);
            let _ = write!(d, "M{x:.1},{:.1} L{x:.1},{:.1} ", y + 3.0, y + BAND_H - 3.0);
        }
        let _ = writeln!(s, r##"<path d="{d}" stroke="black" stroke-width="1"/>"##);
    }
}

/// The piano roll of the 80 dots at `y`, with its heading above.
fn piano_roll(s: &mut String, axis: &TimeAxis, y: f64, pattern: &Pattern) {
    let (plot_w, bin_s, roll_h) = (axis.plot_w, pattern.bin_ms as f64 / 1000.0, 80.0 * DOT_H);
    let x_of = |t: f64| axis.x(t);
    let _ = writeln!(
        s,
        r#"<text x="{LEFT}" y="{}" font-size="13">glove pins (finger / cell / dot 1–8)</text>"#,
        y - 6.0
    );
    let _ = writeln!(
        s,
        r##"<rect x="{LEFT}" y="{y}" width="{plot_w}" height="{roll_h}" fill="#fafafa" stroke="#ccc"/>"##
    );
    for (fi, finger) in Finger::ALL.iter().enumerate() {
        let fy = y + fi as f64 * 16.0 * DOT_H;
        let _ = writeln!(
            s,
            r#"<text x="8" y="{}">{}</text>"#,
            fy + 12.0,
            finger.name()
        );
        // Which cell is which: cell 0 the upper eight rows, cell 1 the lower eight.
        for cell in 0..2 {
            let _ = writeln!(
                s,
                r#"<text x="14" y="{}" font-size="10" fill="dimgray">{cell}: {}</text>"#,
                fy + 8.0 * DOT_H * cell as f64 + if cell == 0 { 26.0 } else { 22.0 },
                esc(&cell_words(pattern.map.get(*finger, cell)))
            );
        }
        let _ = writeln!(
            s,
            r##"<line x1="{LEFT}" y1="{fy}" x2="{}" y2="{fy}" stroke="rgb(153,153,153)"/>"##,
            W - RIGHT
        );
    }
    let colors = ["#8c564b", "#2ca02c", "#9467bd", "#1f77b4", "#e377c2"];
    for row in 0..80usize {
        let (cell_idx, dot) = (row / 8, row % 8);
        let ry = y + row as f64 * DOT_H;
        let color = colors[cell_idx / 2];
        let mut d = String::new();
        let mut run: Option<usize> = None;
        for k in 0..=pattern.frames.len() {
            let on = k < pattern.frames.len() && pattern.frames[k].0[cell_idx] & (1 << dot) != 0;
            match (on, run) {
                (true, None) => run = Some(k),
                (false, Some(k0)) => {
                    let (x0, x1) = (x_of(k0 as f64 * bin_s), x_of(k as f64 * bin_s));
                    let w = (x1 - x0).max(0.5);
                    let _ = write!(d, "M{x0:.1},{ry:.1}h{w:.2}v{:.1}h{:.2}z", DOT_H - 0.8, -w);
                    run = None;
                }
                _ => {}
            }
        }
        if !d.is_empty() {
            let _ = writeln!(s, r#"<path d="{d}" fill="{color}"/>"#);
        }
    }
}

/// The key under the time axis (at `y`): what the marks of each part of the figure mean.
fn key(s: &mut String, y: f64, levels: u8) {
    let lines = [
        format!(
            "Pitch panels: blue line = the stem's pitch (axis in note names and Hz); red steps = its \
             tactile level per bin, 0 (no dot: silent or unvoiced) at the bottom to {levels} (the \
             highest dot) at the top."
        ),
        "Drum rows: black tick = an onset detected in that band or class; orange band = a bin in \
         which its cell raises its dots."
            .to_string(),
        "Glove pins: one row per dot (1–8, top to bottom) of each cell; cell 0 is a finger's \
         upper eight rows, cell 1 its lower eight; a bar = the dot raised for those bins."
            .to_string(),
    ];
    for (i, line) in lines.iter().enumerate() {
        let _ = writeln!(
            s,
            r#"<text x="8" y="{}" fill="dimgray">{}</text>"#,
            y + 20.0 + 15.0 * i as f64,
            esc(line)
        );
    }
}

/// The time axis's labels at `y`: every 1, 2, 5, ... s, at most about 12 of them.
fn time_labels(s: &mut String, axis: &TimeAxis, y: f64) {
    let duration = axis.duration;
    let x_of = |t: f64| axis.x(t);
    // time axis
    let step = [1.0, 2.0, 5.0, 10.0, 15.0, 30.0, 60.0]
        .into_iter()
        .find(|st| duration / st <= 12.0)
        .unwrap_or(120.0);
    let mut t = 0.0;
    while t <= duration + 1e-9 {
        let _ = writeln!(
            s,
            r#"<text x="{:.1}" y="{y}" text-anchor="middle">{t:.0} s</text>"#,
            x_of(t)
        );
        t += step;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_sample::sample;
    use crate::{Frame, GloveMap, SourceInfo};
    use std::collections::BTreeMap;

    /// `bins` bins of 100 ms; the index finger's cell 0 (byte 2) has every dot raised in even
    /// bins, so each of its 8 rows has a run every other bin; the kick beats likewise.
    fn alternating(bins: usize) -> (Pattern, Features) {
        let frames = (0..bins)
            .map(|k| {
                let mut f = Frame::DOWN;
                if k % 2 == 0 {
                    f.0[2] = 0xFF;
                }
                f
            })
            .collect();
        let pattern = Pattern {
            source: SourceInfo {
                path: "long.wav".into(),
                sha256: "0".repeat(64),
                duration_s: bins as f64 * 0.1,
                sample_rate: 44_100,
            },
            bin_ms: 100,
            levels: 8,
            map: GloveMap::default(),
            frames,
        };
        let mut beats = BTreeMap::new();
        beats.insert(
            "kick".to_string(),
            (0..bins).map(|k| (k % 2 == 0) as u8).collect(),
        );
        let features = Features {
            hop_s: 0.01,
            bin_s: 0.1,
            pitch_hz: BTreeMap::new(),
            levels: BTreeMap::new(),
            onsets_s: BTreeMap::new(),
            beats,
        };
        (pattern, features)
    }

    /// The plot, byte for byte: it changes only on purpose (the plot is not pinned by the
    /// render tests, which hash the pattern and features files).
    #[test]
    fn the_plot_is_the_pinned_one() {
        let (p, f) = sample();
        let hash = crate::sha256_hex(render_svg(&p, &f).as_bytes()).unwrap();
        assert_eq!(
            hash,
            "a174205a7e1137adfaaf2a45207363ec3bb782892a1fefc6863487e99d2ecc2e"
        );
    }

    /// Elements other than text (the time axis has more labels for a longer song).
    fn elements(svg: &str) -> usize {
        svg.matches('<').count() - svg.matches("</").count() - svg.matches("<text").count()
    }

    #[test]
    fn element_count_does_not_grow_with_the_song() {
        let (p, f) = alternating(20);
        let short = render_svg(&p, &f);
        // One hour: 18 000 runs in each of 8 rows and in the kick raster.
        let (p, f) = alternating(36_000);
        let long = render_svg(&p, &f);
        assert_eq!(elements(&short), elements(&long));
        assert!(elements(&long) < 30, "{}", elements(&long));
        let runs = long.matches("zM").count() + long.matches("z\"").count();
        assert_eq!(runs, 9 * 18_000, "one subpath per run");
    }

    #[test]
    fn an_hour_long_plot_has_the_layout_size() {
        // The binary rasterises at one pixel per unit (tests/cli.rs checks the PNG itself).
        let (p, f) = alternating(36_000);
        let svg = render_svg(&p, &f);
        let height = (60.0 + 34.0 + GAP + 80.0 * DOT_H + 50.0) as u32;
        let head = format!("width=\"1400\" height=\"{height}\"");
        assert!(svg.contains(&head), "{}", &svg[..200]);
    }
}
