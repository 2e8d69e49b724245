//! The terminal glove view (`play --tui`, `live --tui`) in a real terminal:
//! `tactus play PATTERN.json --no-audio --tui --glove file:LOG` runs in a tmux pane, and
//! every capture of the pane (`tmux capture-pane -p`) taken while the log stood still must
//! show, dot for dot, the frame the log says was sent last.
//!
//! The pattern holds long (800 ms) frames, so most captures fall well inside one frame:
//! a capture counts only when the log did not change while it was taken and its last packet
//! had been seen at least 250 ms before (the view redraws every 50 ms).
//!
//! Also: without a terminal on stdout, `--tui` says so in one line and draws nothing; without
//! `--tui`, stdout stays empty.
//!
//! Needs `tmux`; without it the tmux test prints SKIPPED, and fails under `CI=true`
//! (`.ci/run` installs it).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use tactus_glove::tui::read_frame;
use tactus_glove::Frame;

mod common;

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_tactus")
}

/// Frames that between them raise every dot of every cell alone (one bit walking through
/// all 80 pins, eight at a time) plus a few mixed ones.
fn frames() -> Vec<Frame> {
    let mut v = vec![Frame::DOWN];
    for bit in 0..8 {
        // Frame k raises dot k+1 on cells whose index is even, dot 8-k on the odd ones.
        let mut f = Frame::DOWN;
        for (c, b) in f.0.iter_mut().enumerate() {
            *b = if c % 2 == 0 { 1 << bit } else { 0x80 >> bit };
        }
        v.push(f);
    }
    v.push(Frame([0xFF; 10]));
    v.push(Frame::from_hex("0102040810204080aa55").unwrap());
    v.push(Frame::from_hex("8000ff00000000000000").unwrap());
    v
}

/// A pattern file of `frames`, each `bin_ms` long, from the glove crate's fixture.
fn write_pattern(path: &Path, frames: &[Frame], bin_ms: u32) {
    let fixture = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/crates/tactus-glove/tests/fixtures/pattern-v1.json"
    );
    let mut p: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fixture).unwrap()).unwrap();
    p["bin_ms"] = bin_ms.into();
    p["source"]["duration_s"] = (frames.len() as f64 * f64::from(bin_ms) / 1e3).into();
    p["frames"] = frames.iter().map(|f| f.to_hex()).collect::<Vec<_>>().into();
    std::fs::write(path, serde_json::to_string(&p).unwrap()).unwrap();
}

/// The state the glove is in after the log's last pins / all-down packet (all down before
/// any), and how many packets the log holds.
fn last_state(log: &Path) -> (Frame, usize) {
    let text = std::fs::read_to_string(log).unwrap_or_default();
    let mut state = Frame::DOWN;
    let mut n = 0;
    // A line being written has no newline yet: only complete lines count.
    for line in text.split_inclusive('\n').filter(|l| l.ends_with('\n')) {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        match v["type"].as_str().unwrap() {
            "pins" => state = Frame::from_hex(v["frame"].as_str().unwrap()).unwrap(),
            "all_down" => state = Frame::DOWN,
            _ => {}
        }
        n += 1;
    }
    (state, n)
}

struct Tmux {
    socket: PathBuf,
}

impl Tmux {
    fn cmd(&self) -> Command {
        let mut c = Command::new("tmux");
        c.arg("-S").arg(&self.socket).args(["-f", "/dev/null"]);
        c
    }

    fn capture(&self) -> Vec<String> {
        let out = self
            .cmd()
            .args(["capture-pane", "-p", "-t", "view"])
            .output()
            .unwrap();
        assert!(out.status.success(), "tmux capture-pane failed");
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .map(str::to_string)
            .collect()
    }
}

impl Drop for Tmux {
    fn drop(&mut self) {
        let _ = self.cmd().arg("kill-server").stderr(Stdio::null()).status();
    }
}

#[test]
fn the_view_in_a_tmux_pane_shows_the_frame_that_was_sent() {
    if Command::new("tmux").arg("-V").output().is_err() {
        common::skip(
            "the_view_in_a_tmux_pane_shows_the_frame_that_was_sent: tmux is not installed \
             (apt-get install tmux; CI does)",
        );
        return;
    }
    let d = tempfile::tempdir().unwrap();
    let pattern = d.path().join("p.json");
    let log = d.path().join("glove.jsonl");
    let frames = frames();
    write_pattern(&pattern, &frames, 800);
    let tmux = Tmux {
        socket: d.path().join("tmux.sock"),
    };
    let command = format!(
        "'{}' play '{}' --no-audio --tui --glove 'file:{}'; echo tactus exited $?; sleep 600",
        bin(),
        pattern.display(),
        log.display()
    );
    let st = tmux
        .cmd()
        .args(["new-session", "-d", "-s", "view", "-x", "100", "-y", "40"])
        .arg(command)
        .status()
        .unwrap();
    assert!(st.success(), "tmux new-session failed");

    let t0 = Instant::now();
    let mut seen_at = (usize::MAX, Instant::now());
    let mut checked: Vec<Frame> = Vec::new();
    let mut screens = 0;
    let mut link_up = false;
    let last_screen = loop {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "tactus did not finish"
        );
        let (before, n) = last_state(&log);
        if n != seen_at.0 {
            seen_at = (n, Instant::now());
        }
        let stable_for = seen_at.1.elapsed();
        let screen = tmux.capture();
        let (after, n_after) = last_state(&log);
        if screen.iter().any(|l| l.starts_with("tactus exited")) {
            break screen;
        }
        if n_after == n && after == before && stable_for >= Duration::from_millis(250) {
            // The log stood still for 250 ms before the capture and during it.
            if let Some(shown) = read_frame(&screen) {
                screens += 1;
                link_up |= screen.iter().any(|l| l.contains("   link up"));
                assert_eq!(
                    shown,
                    before,
                    "the pane shows {} but the last frame sent was {} ({n} packets)\n{}",
                    shown.to_hex(),
                    before.to_hex(),
                    screen.join("\n")
                );
                if checked.last() != Some(&shown) {
                    checked.push(shown);
                }
            }
        }
        std::thread::sleep(Duration::from_millis(70));
    };
    let text = last_screen.join("\n");
    assert!(text.contains("tactus exited 0"), "{text}");
    // The final view: all down (the closing packet), above the report.
    assert_eq!(read_frame(&last_screen), Some(Frame::DOWN), "{text}");
    assert!(text.contains("tactus play"), "{text}");
    assert!(text.contains("link closed"), "{text}");
    assert!(link_up, "no capture showed the link up");
    // Most frames were caught standing still (12 frames of 800 ms, a capture every ~100 ms).
    let distinct: std::collections::HashSet<_> = checked.iter().collect();
    eprintln!(
        "{screens} captures checked, {} distinct frames",
        distinct.len()
    );
    assert!(
        distinct.len() >= frames.len() - 2,
        "only {} of {} frames checked in {screens} captures",
        distinct.len(),
        frames.len()
    );
}

#[test]
fn without_a_terminal_the_view_says_so_and_without_tui_stdout_stays_empty() {
    let d = tempfile::tempdir().unwrap();
    let pattern = d.path().join("p.json");
    write_pattern(&pattern, &frames()[..3], 20);
    for tui in [true, false] {
        let mut c = Command::new(bin());
        c.arg("play")
            .arg(&pattern)
            .args(["--no-audio", "--glove", "null"]);
        if tui {
            c.arg("--tui");
        }
        let out = c.output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        assert!(out.stdout.is_empty(), "{:?}", out.stdout);
        assert!(!err.contains('\x1b'), "{err:?}");
        assert_eq!(
            err.contains("tactus: --tui: stdout is not a terminal, so the glove view is not drawn"),
            tui,
            "{err}"
        );
    }
}
