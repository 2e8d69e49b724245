//! `render --plot`: an SVG a researcher can read, after the paper's Figures 5 and 7.
//!
//! * one panel per melodic stem: the pitch contour (semitones) and the tactile level per bin;
//! * one raster per drum band: onsets as ticks over the beat bins they light;
//! * the glove: a piano roll of the 80 dots over time (finger, cell, dot), runs merged.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{bail, Result};
use tactus_glove::{Features, Finger, Pattern};

const W: f64 = 1400.0;
const LEFT: f64 = 110.0;
const RIGHT: f64 = 20.0;
const PITCH_H: f64 = 140.0;
const BAND_H: f64 = 28.0;
const DOT_H: f64 = 4.0;
const GAP: f64 = 26.0;

/// Accepts `.svg`; anything else is a clear error.
pub fn check_extension(path: &Path) -> Result<()> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
    {
        Some(e) if e == "svg" => Ok(()),
        Some(e) if e == "png" => bail!(
            "--plot {}: PNG output is not built in yet; use .svg",
            path.display()
        ),
        _ => bail!("--plot {}: the plot must end in .svg", path.display()),
    }
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Draws the plot.
pub fn render_svg(pattern: &Pattern, f: &Features) -> String {
    let duration = pattern.source.duration_s.max(1e-3);
    let plot_w = W - LEFT - RIGHT;
    let x_of = |t: f64| LEFT + plot_w * (t / duration).clamp(0.0, 1.0);
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
    let bin_s = pattern.bin_ms as f64 / 1000.0;

    // Pitch panels.
    for (stem, hz) in &f.pitch_hz {
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
        let _ = writeln!(
            s,
            r##"<rect x="{LEFT}" y="{y}" width="{plot_w}" height="{PITCH_H}" fill="#fafafa" stroke="#ccc"/>"##
        );
        let _ = writeln!(
            s,
            r#"<text x="8" y="{}" font-size="13">{}</text>"#,
            y + 16.0,
            esc(stem)
        );
        let _ = writeln!(
            s,
            r##"<text x="8" y="{}" fill="#1f77b4">pitch (st)</text>"##,
            y + 32.0
        );
        let _ = writeln!(
            s,
            r##"<text x="8" y="{}" fill="#d62728">level 0–{}</text>"##,
            y + 46.0,
            pattern.levels
        );
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}">{:.0}</text>"#,
            LEFT - 28.0,
            y + 10.0,
            hi
        );
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}">{:.0}</text>"#,
            LEFT - 28.0,
            y + PITCH_H,
            lo
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
        y += PITCH_H + GAP;
    }

    // Band rasters.
    for (band, beats) in &f.beats {
        let _ = writeln!(
            s,
            r##"<rect x="{LEFT}" y="{y}" width="{plot_w}" height="{BAND_H}" fill="#fafafa" stroke="#ccc"/>"##
        );
        let _ = writeln!(
            s,
            r#"<text x="8" y="{}" font-size="12">{}</text>"#,
            y + 18.0,
            esc(band)
        );
        for (k, &b) in beats.iter().enumerate() {
            if b != 0 {
                let (x0, x1) = (x_of(k as f64 * bin_s), x_of((k + 1) as f64 * bin_s));
                let _ = writeln!(
                    s,
                    r##"<rect x="{x0:.1}" y="{y}" width="{:.2}" height="{BAND_H}" fill="#ff7f0e" opacity="0.35"/>"##,
                    (x1 - x0).max(0.5)
                );
            }
        }
        if let Some(on) = f.onsets_s.get(band) {
            let mut d = String::new();
            for &t in on {
                let x = x_of(t);
                let _ = write!(d, "M{x:.1},{:.1} L{x:.1},{:.1} ", y + 3.0, y + BAND_H - 3.0);
            }
            let _ = writeln!(s, r##"<path d="{d}" stroke="#000" stroke-width="1"/>"##);
        }
        y += BAND_H + 6.0;
    }

    // Piano roll of the 80 dots.
    y += GAP - 6.0;
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
            fy + 8.0 * DOT_H + 4.0,
            finger.name()
        );
        let _ = writeln!(
            s,
            r##"<line x1="{LEFT}" y1="{fy}" x2="{}" y2="{fy}" stroke="#999"/>"##,
            W - RIGHT
        );
    }
    let colors = ["#8c564b", "#2ca02c", "#9467bd", "#1f77b4", "#e377c2"];
    for row in 0..80usize {
        let (cell_idx, dot) = (row / 8, row % 8);
        let ry = y + row as f64 * DOT_H;
        let color = colors[cell_idx / 2];
        let mut run: Option<usize> = None;
        for k in 0..=pattern.frames.len() {
            let on = k < pattern.frames.len() && pattern.frames[k].0[cell_idx] & (1 << dot) != 0;
            match (on, run) {
                (true, None) => run = Some(k),
                (false, Some(k0)) => {
                    let (x0, x1) = (x_of(k0 as f64 * bin_s), x_of(k as f64 * bin_s));
                    let _ = writeln!(
                        s,
                        r#"<rect x="{x0:.1}" y="{ry:.1}" width="{:.2}" height="{:.1}" fill="{color}"/>"#,
                        (x1 - x0).max(0.5),
                        DOT_H - 0.8
                    );
                    run = None;
                }
                _ => {}
            }
        }
    }
    y += roll_h + 18.0;
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
    s.push_str("</svg>\n");
    s
}
