//! The browser preview (`render --html PAGE.html`, docs/design.md "Files", browser preview, a contract):
//! one self-contained HTML page that plays the song and animates the glove in sync with it.
//!
//! [`render_page`] takes a [`Pattern`], its [`Features`] and the bytes of the song file and
//! returns the page as a string. Nothing on the page refers to the network: the CSS and the
//! script (`assets/preview.css`, `assets/preview.js`, built in) are inline, the pattern and a compact copy of the features are a JSON island, and
//! the song is the source file's own bytes as base64 (decoded into a `blob:` URL at load), so
//! the page weighs about 4/3 of the song file plus the features (see [`HtmlPage`]).
//!
//! The page, for people:
//! * the glove: five fingers × two braille cells × eight dots, laid out as on the back of a
//!   right hand (thumb on the left, cell 0 at the finger tip); dots in the 8-dot braille
//!   numbering of the contract (left column 1, 2, 3, 7 top to bottom; right column
//!   4, 5, 6, 8); a raised dot is filled with its feature's colour;
//! * the map's legend (which finger and cell shows what) with a checkbox per stem or drum
//!   class that mutes its cells;
//! * pitch contours and onset rasters from the features, scrolling under a fixed playhead,
//!   each row named in a gutter of its own (each pitch lane with its range in note names);
//!   the lanes fill the column beside the glove, and the legend sits under the glove;
//! * keyboard: space plays or pauses, ← / → seek 5 s.
//!
//! The page, for tools (the contract):
//! * every dot is an element with `data-finger` (thumb..pinky), `data-cell` (0/1) and
//!   `data-dot` (1..8), and carries the class `up` while raised;
//! * `PAGE.html#t=SECONDS` seeks there and pauses. The shown frame is computed from the
//!   hash's time directly, so it is right even when the audio cannot load.
//!   Extra hash keys: `play` starts playing (browsers may need a gesture or
//!   `--autoplay-policy=no-user-gesture-required`), `mute=kick,bass` mutes those features.
//! * the element `#glove` carries `data-t` (the time shown, seconds) and `data-frame` (the
//!   frame index shown, −1 past the end); `#status` carries `data-audio` (`loading`,
//!   `ready`, `error`) and `data-clock` (`audio` or `wall`).
//!
//! Timing: each animation frame (`requestAnimationFrame`) reads `audio.currentTime` while
//! the song plays and shows frame `floor(t / bin_s)`, the frame covering
//! `[i * bin_ms, (i + 1) * bin_ms)` of the pattern file; past the last frame every dot is
//! down. When the audio cannot be played (a codec the browser lacks) the page falls back
//! to the wall clock and says so.

use std::fmt::Write as _;

use serde_json::{json, Map, Value};

use crate::glove::{level_dots, Dot, Finger, CELLS_PER_FINGER};
use crate::map::CellSource;
use crate::{Features, Pattern};

/// A rendered page.
#[derive(Debug, Clone)]
pub struct HtmlPage {
    /// The page.
    pub html: String,
    /// Bytes of embedded audio (the source file's size; the page holds 4/3 of it as base64).
    pub audio_bytes: usize,
    /// What the audio was recognised as.
    pub audio: AudioKind,
}

/// The page for a song file: its own bytes embedded (checked against the pattern's SHA-256,
/// so the page plays what was rendered) with the pattern and features, titled with its path.
///
/// Errors: the file cannot be read ([`GloveError::InFile`]), or it is not the file the
/// pattern was rendered from ([`GloveError::SongChanged`]).
pub fn page_for_song(
    song: &std::path::Path,
    pattern: &Pattern,
    features: &Features,
) -> Result<HtmlPage, crate::GloveError> {
    let in_file = |e: crate::GloveError| crate::GloveError::InFile {
        path: song.to_path_buf(),
        source: Box::new(e),
    };
    let audio = std::fs::read(song).map_err(|e| in_file(e.into()))?;
    if crate::sha256_hex(&audio[..]).map_err(|e| in_file(e.into()))? != pattern.source.sha256 {
        return Err(crate::GloveError::SongChanged(song.to_path_buf()));
    }
    Ok(render_page(
        pattern,
        features,
        &audio,
        &song.display().to_string(),
    ))
}

/// What an audio file's first bytes say, and whether browsers play it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AudioKind {
    /// MIME type given to the browser (e.g. `audio/ogg`).
    pub mime: &'static str,
    /// Short description (e.g. `Ogg/Vorbis`).
    pub name: String,
    /// `Some(reason)` when Chromium-based browsers are not expected to play it.
    pub unplayable: Option<String>,
}

/// Recognises the audio container (and, where it matters, the codec) from a file's bytes.
/// Chromium plays WAV (PCM or float), MP3, Ogg (Vorbis, Opus, FLAC), FLAC, AAC (ADTS or
/// MP4); anything else is reported in [`AudioKind::unplayable`].
pub fn audio_kind(bytes: &[u8]) -> AudioKind {
    let ok = |mime, name: &str| AudioKind {
        mime,
        name: name.into(),
        unplayable: None,
    };
    let bad = |mime, name: &str, why: String| AudioKind {
        mime,
        name: name.into(),
        unplayable: Some(why),
    };
    let head = |n: usize| bytes.get(..n).unwrap_or(&[]);
    if head(4) == b"RIFF" && bytes.get(8..12) == Some(b"WAVE") {
        return match wav_format_tag(bytes) {
            Some(1) | Some(3) => ok("audio/wav", "WAV"),
            Some(tag) => bad(
                "audio/wav",
                "WAV",
                format!("WAV with format tag 0x{tag:04x} (not PCM or float, e.g. ADPCM)"),
            ),
            None => bad(
                "audio/wav",
                "WAV",
                "WAV without a readable fmt chunk".into(),
            ),
        };
    }
    if head(4) == b"fLaC" {
        return ok("audio/flac", "FLAC");
    }
    if head(4) == b"OggS" {
        let first = bytes.get(28..40).unwrap_or(&[]);
        return if first.starts_with(b"\x01vorbis") {
            ok("audio/ogg", "Ogg/Vorbis")
        } else if first.starts_with(b"OpusHead") {
            ok("audio/ogg", "Ogg/Opus")
        } else if first.starts_with(b"\x7fFLAC") {
            ok("audio/ogg", "Ogg/FLAC")
        } else {
            bad(
                "audio/ogg",
                "Ogg",
                "an Ogg stream that is not Vorbis, Opus or FLAC (e.g. Speex)".into(),
            )
        };
    }
    if bytes.get(4..8) == Some(b"ftyp") {
        let scan = &bytes[..bytes.len().min(1 << 20)];
        if scan.windows(4).any(|w| w == b"alac") {
            return bad(
                "audio/mp4",
                "MP4/ALAC",
                "Apple Lossless in MP4 (Chromium plays AAC in MP4, not ALAC)".into(),
            );
        }
        return ok("audio/mp4", "MP4/AAC");
    }
    if head(3) == b"ID3" {
        return ok("audio/mpeg", "MP3");
    }
    if bytes.len() >= 2 && bytes[0] == 0xFF {
        let b1 = bytes[1];
        if b1 & 0xF6 == 0xF0 {
            return ok("audio/aac", "AAC (ADTS)");
        }
        if b1 & 0xE0 == 0xE0 && (b1 >> 1) & 3 != 0 {
            return ok("audio/mpeg", "MPEG audio");
        }
    }
    bad(
        "application/octet-stream",
        "unknown",
        "a container this page cannot recognise".into(),
    )
}

/// The WAV `fmt ` chunk's format tag (the sub-format's for WAVE_FORMAT_EXTENSIBLE).
fn wav_format_tag(bytes: &[u8]) -> Option<u16> {
    let mut pos = 12usize;
    while pos + 8 <= bytes.len() {
        let id = &bytes[pos..pos + 4];
        let size = u32::from_le_bytes(bytes[pos + 4..pos + 8].try_into().ok()?) as usize;
        let body = pos + 8;
        if id == b"fmt " {
            let tag = u16::from_le_bytes(bytes.get(body..body + 2)?.try_into().ok()?);
            if tag == 0xFFFE {
                // WAVE_FORMAT_EXTENSIBLE: the GUID's first two bytes are the real tag.
                return Some(u16::from_le_bytes(
                    bytes.get(body + 24..body + 26)?.try_into().ok()?,
                ));
            }
            return Some(tag);
        }
        pos = body.checked_add(size)?.checked_add(size & 1)?;
    }
    None
}

/// Standard base64 (RFC 4648, with padding).
pub fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        s.push(A[(n >> 18) as usize & 63] as char);
        s.push(A[(n >> 12) as usize & 63] as char);
        s.push(if chunk.len() > 1 {
            A[(n >> 6) as usize & 63] as char
        } else {
            '='
        });
        s.push(if chunk.len() > 2 {
            A[n as usize & 63] as char
        } else {
            '='
        });
    }
    s
}

fn escape_html(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// The feature a cell shows, as the name its mute checkbox uses (a stem or a drum class).
/// A cell's group (`off` when it shows nothing), its colour and its description (escaped).
fn cell_look(
    pattern: &Pattern,
    finger: Finger,
    cell: usize,
) -> (&'static str, &'static str, String) {
    let source = pattern.map.get(finger, cell);
    let group = group_of(source).unwrap_or("off");
    (
        group,
        colour(group),
        escape_html(&describe_cell(source, pattern.levels)),
    )
}

fn group_of(source: CellSource) -> Option<&'static str> {
    match source {
        CellSource::Off => None,
        CellSource::PitchLevel(stem) | CellSource::NoteOnsets { stem, .. } => Some(stem.name()),
        CellSource::BandOnsets { band, .. } => Some(band.name()),
    }
}

fn colour(group: &str) -> &'static str {
    match group {
        "bass" => "#e4572e",
        "kick" => "#3b6fd8",
        "snare" => "#17a589",
        "toms" => "#9b59b6",
        "cymbals" => "#d4ac0d",
        "vocals" => "#e84393",
        "other" => "#2e86c1",
        "drums" => "#16a085",
        _ => "rgb(136,136,136)",
    }
}

fn dot_list(mask: u8) -> String {
    let v: Vec<String> = Dot::ALL
        .into_iter()
        .filter(|d| mask & d.mask() != 0)
        .map(|d| d.number().to_string())
        .collect();
    if v.len() == 8 {
        "all 8 dots".into()
    } else {
        format!("dots {}", v.join(", "))
    }
}

/// One line saying what a cell shows.
pub fn describe_cell(source: CellSource, levels: u8) -> String {
    match source {
        CellSource::Off => "nothing".into(),
        CellSource::PitchLevel(stem) => {
            let order: Vec<String> = (1..=levels)
                .map(|l| {
                    Dot::ALL
                        .into_iter()
                        .find(|d| level_dots(l, levels) & d.mask() != 0)
                        .map_or(String::new(), |d| d.number().to_string())
                })
                .collect();
            format!(
                "{} pitch level: one dot, levels 1–{levels} on dots {}",
                stem.name(),
                order.join(", ")
            )
        }
        CellSource::NoteOnsets { stem, dots } => {
            format!("{} note onsets: {}", stem.name(), dot_list(dots))
        }
        CellSource::BandOnsets { band, dots } => {
            format!("{} onsets: {}", band.name(), dot_list(dots))
        }
    }
}

fn round_to(x: f64, step: f64) -> Value {
    let r = (x / step).round() * step;
    // Print integers as integers (most pitch values are 0 = unvoiced).
    if r == r.trunc() && r.abs() < 1e15 {
        json!(r as i64)
    } else {
        json!((r * 1e6).round() / 1e6)
    }
}

/// The data island: pattern frames, timing, legend and a compact copy of the features
/// (pitch to 0.1 Hz, onsets to 1 ms).
fn data_json(pattern: &Pattern, features: &Features, title: &str) -> String {
    let mut pitch = Map::new();
    for (k, v) in &features.pitch_hz {
        pitch.insert(
            k.clone(),
            Value::Array(v.iter().map(|&x| round_to(f64::from(x), 0.1)).collect()),
        );
    }
    let mut onsets = Map::new();
    for (k, v) in &features.onsets_s {
        onsets.insert(
            k.clone(),
            Value::Array(v.iter().map(|&x| round_to(x, 0.001)).collect()),
        );
    }
    let cells: Vec<Value> = Finger::ALL
        .into_iter()
        .flat_map(|f| (0..CELLS_PER_FINGER).map(move |c| (f, c)))
        .map(|(f, c)| {
            let s = pattern.map.get(f, c);
            json!({"finger": f.name(), "cell": c, "group": group_of(s),
                   "what": describe_cell(s, pattern.levels)})
        })
        .collect();
    let v = json!({
        "title": title,
        "bin_ms": pattern.bin_ms,
        "duration_s": pattern.source.duration_s,
        "frames": pattern.frames.iter().map(|f| f.to_hex()).collect::<Vec<_>>(),
        "cells": cells,
        "hop_s": features.hop_s,
        "pitch_hz": pitch,
        "onsets_s": onsets,
    });
    // Inside <script>, "</" could end the element: escape it (JSON allows "\/").
    v.to_string().replace("</", "<\\/")
}

/// Builds the page for `pattern` (with the `features` rendered with it) and the song file's
/// bytes `audio` (embedded as they are). `title` is shown as the page's title (e.g. the
/// input path). Never fails: an audio format browsers cannot play is reported in
/// [`HtmlPage::audio`] and on the page, whose glove then runs on the wall clock.
pub fn render_page(pattern: &Pattern, features: &Features, audio: &[u8], title: &str) -> HtmlPage {
    let kind = audio_kind(audio);
    let mut glove = String::new();
    let mut legend = String::new();
    for finger in Finger::ALL {
        let _ = write!(
            glove,
            "<div class=\"finger f-{0}\"><div class=\"fname\">{0}</div>",
            finger.name()
        );
        for cell in 0..CELLS_PER_FINGER {
            let (group, colour, what) = cell_look(pattern, finger, cell);
            let name = finger.name();
            let _ = write!(
                glove,
                "<div class=\"cell\" data-group=\"{group}\" style=\"--c:{colour}\" title=\"{name} cell {cell}: {what}\">",
            );
            // The legend lists the cells in the same order.
            let _ = write!(
                legend,
                "<tr><td>{name}</td><td>{cell}</td><td><i style=\"background:{colour}\"></i>{what}</td></tr>",
            );
            for row in 0..4 {
                for col in 0..2 {
                    if let Some(d) = Dot::at(col, row) {
                        let _ = write!(
                            glove,
                            "<span class=\"dot\" data-finger=\"{}\" data-cell=\"{cell}\" data-dot=\"{}\"></span>",
                            finger.name(),
                            d.number()
                        );
                    }
                }
            }
            glove.push_str("</div>");
        }
        glove.push_str("</div>");
    }

    let mut groups: Vec<&str> = Vec::new();
    for source in pattern.map.cells.iter().flatten() {
        if let Some(g) = group_of(*source) {
            if !groups.contains(&g) {
                groups.push(g);
            }
        }
    }
    let mut toggles = String::new();
    for g in &groups {
        let _ = write!(
            toggles,
            "<label style=\"--c:{}\"><input type=\"checkbox\" data-mute=\"{g}\" checked> {g}</label>",
            colour(g)
        );
    }

    let audio_note = match &kind.unplayable {
        None => format!("{} embedded, {:.1} MB", kind.name, audio.len() as f64 / 1e6),
        Some(why) => format!(
            "{} embedded ({:.1} MB), but browsers may not play it: {}; the glove runs on the wall clock",
            kind.name,
            audio.len() as f64 / 1e6,
            why
        ),
    };
    let title_html = escape_html(title);
    let data = data_json(pattern, features, title);
    let b64 = base64(audio);

    let mut html = String::with_capacity(b64.len() + data.len() + 16_384);
    let _ = write!(
        html,
        r#"<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<meta name="generator" content="tactus render --html">
<title>Tactus — {title_html}</title>
<style>
{CSS}</style></head>
<body>
<header><h1>Tactus preview <small>{title_html}</small></h1>
<div id="status" data-audio="loading" data-clock="audio"><button id="playbtn" type="button">▶ play</button>
<span id="time">0.00 s</span> <span id="note">{audio_note_html}</span></div>
<input id="seek" type="range" min="0" max="{dur}" step="0.01" value="0" aria-label="position">
</header>
<main>
<div id="left">
<section id="glove" data-t="0" data-frame="0" aria-label="glove">
<div class="hand">{glove}</div><div class="palm">back of the right hand · cell 0 at the finger tip · dots 1 2 3 7 | 4 5 6 8</div>
</section>
<div id="legendbox"><table id="legend"><thead><tr><th>finger</th><th>cell</th><th>shows</th></tr></thead><tbody>{legend}</tbody></table></div>
</div>
<section id="side">
<canvas id="lanes" width="760" height="300"></canvas>
<div id="toggles"><b>show:</b> {toggles}</div>
<p class="help">space: play / pause · ← →: seek 5 s · <code>#t=SECONDS</code>: show that moment · {bin_ms} ms per frame, {frames} frames</p>
</section>
</main>
<audio id="audio" preload="auto"></audio>
<script type="application/json" id="tactus-data">{data}</script>
<script type="application/octet-stream" id="tactus-audio" data-mime="{mime}" data-playable="{playable}">{b64}</script>
<script>
{JS}</script>
</body></html>
"#,
        audio_note_html = escape_html(&audio_note),
        dur = pattern.source.duration_s,
        bin_ms = pattern.bin_ms,
        frames = pattern.frames.len(),
        mime = kind.mime,
        playable = kind.unplayable.is_none(),
    );
    HtmlPage {
        html,
        audio_bytes: audio.len(),
        audio: kind,
    }
}

/// The page's style sheet (`assets/preview.css`).
const CSS: &str = include_str!("../assets/preview.css");

/// The page's script (`assets/preview.js`): the clock, the glove, the lanes, the controls.
const JS: &str = include_str!("../assets/preview.js");

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_sample::sample;

    #[test]
    fn base64_matches_rfc4648_vectors() {
        for (input, want) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(input.as_bytes()), want);
        }
        let all: Vec<u8> = (0..=255).collect();
        assert!(base64(&all).ends_with("+/w=="));
    }

    #[test]
    fn recognises_containers() {
        let mut wav = b"RIFF\0\0\0\0WAVEfmt \x10\0\0\0\x01\0".to_vec();
        wav.extend([0u8; 14]);
        assert_eq!(audio_kind(&wav).mime, "audio/wav");
        assert!(audio_kind(&wav).unplayable.is_none());
        wav[20] = 0x11; // IMA ADPCM
        assert!(audio_kind(&wav).unplayable.is_some());
        assert_eq!(audio_kind(b"fLaC\0\0").mime, "audio/flac");
        assert_eq!(audio_kind(b"ID3\x04").mime, "audio/mpeg");
        assert_eq!(audio_kind(&[0xFF, 0xFB, 0x90]).mime, "audio/mpeg");
        assert_eq!(audio_kind(&[0xFF, 0xF1, 0x50]).mime, "audio/aac");
        assert!(audio_kind(b"garbage!").unplayable.is_some());
        let demo = std::fs::read(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../examples/demo.ogg"
        ))
        .unwrap();
        assert_eq!(audio_kind(&demo).name, "Ogg/Vorbis");
    }

    /// The page, byte for byte: it changes only on purpose (the page is not pinned by the
    /// render tests, which hash the pattern and features files).
    #[test]
    fn the_page_is_the_pinned_one() {
        let (p, f) = sample();
        let page = render_page(&p, &f, b"OggS\0\0\0\0", "song.ogg");
        let hash = crate::sha256_hex(page.html.as_bytes()).unwrap();
        assert_eq!(
            hash,
            "98c70e63b1765c2a49a548a4ee93c3c396d9014d42729c2a34672c020975066e"
        );
    }

    #[test]
    fn page_has_80_dots_and_no_network_reference() {
        let pattern = Pattern {
            source: crate::SourceInfo {
                path: "a</script>.ogg".into(),
                sha256: String::new(),
                duration_s: 1.0,
                sample_rate: 44100,
            },
            bin_ms: 100,
            levels: 8,
            map: crate::GloveMap::default(),
            frames: vec![crate::Frame::DOWN; 10],
        };
        let features = Features {
            hop_s: 0.01,
            bin_s: 0.1,
            ..Features::default()
        };
        let page = render_page(&pattern, &features, b"OggS", "x</script><b>");
        assert_eq!(page.html.matches("<span class=\"dot\"").count(), 80);
        assert!(!page.html.contains("://"));
        assert!(!page.html.contains("x</script><b>"));
        assert_eq!(page.html.matches("</script>").count(), 3);
    }
}
