//! Live audio with real stand-ins: a private PulseAudio server with a null sink (`vsink`)
//! whose monitor is the default source (docs/install.md, "Live setup"). `paplay`
//! plays a generated drum pattern into the sink, and cpal's ALSA `default` device captures
//! it through PulseAudio's ALSA plugin.
//!
//! * `live_follows_a_drum_pattern`: `tactus live` turns hits every 500 ms into index-finger
//!   (kick/snare) onsets every 500 ms.
//! * `play_times_frames_on_the_audio_output`: `tactus play` plays a song into the null sink,
//!   takes about its duration, and delivers every frame the streaming render produces.
//! * `play_pattern_plays_its_song_on_the_audio_clock`: `tactus play PATTERN.json` finds the
//!   pattern's song, plays it into the null sink and delivers the pattern's frames on its
//!   clock; `play_pattern_refuses_a_wrong_or_missing_song_and_engine_options`: the errors.
//!
//! Skips (saying so on stderr) only when `pulseaudio` is not installed; CI installs it.
#![cfg(feature = "audio")]

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Instant;

mod common;

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_tactus")
}

#[path = "common/pulse.rs"]
mod pulse;
use pulse::Pulse;

/// One drum hit: a 70 Hz thump (40 ms decay) plus a noise burst (8 ms decay), 300 ms long so
/// that it has decayed to silence (below −60 dB) before it ends.
fn hit(rate: u32, seed: &mut u32) -> Vec<f32> {
    (0..(rate as usize * 3 / 10))
        .map(|j| {
            let t = j as f32 / rate as f32;
            *seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let noise = (*seed >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0;
            0.8 * (std::f32::consts::TAU * 70.0 * t).sin() * (-t / 0.04).exp()
                + 0.5 * noise * (-t / 0.008).exp()
        })
        .collect()
}

/// A mono 16-bit WAV of `seconds` with a hit at `first + k · period`.
fn write_hits(path: &Path, rate: u32, seconds: f32, first: f32, period: f32) -> Vec<f32> {
    let n = (seconds * rate as f32) as usize;
    let mut x = vec![0.0f32; n];
    let mut seed = 1u32;
    let mut t = first;
    let mut times = Vec::new();
    while t < seconds {
        let h = hit(rate, &mut seed);
        let i0 = (t * rate as f32) as usize;
        for (j, v) in h.iter().enumerate() {
            if i0 + j < n {
                x[i0 + j] += v;
            }
        }
        times.push(t);
        t += period;
    }
    pulse::write_wav(path, rate, &x);
    times
}

use pulse::{index_up, pins};

#[test]
fn live_follows_a_drum_pattern() {
    let Some(pulse) = Pulse::start(
        "live_follows_a_drum_pattern",
        &["pulseaudio", "pactl", "paplay"],
    ) else {
        return;
    };
    let d = tempfile::tempdir().unwrap();
    let wav = d.path().join("hits.wav");
    write_hits(&wav, 48_000, 14.0, 0.25, 0.5);
    let log = d.path().join("live.jsonl");
    let live = pulse
        .cmd(bin())
        .args(["live", "--seconds", "9", "--glove"])
        .arg(format!("file:{}", log.display()))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The "microphone": the hits played into the null sink, captured from its monitor.
    let mut player = pulse
        .cmd("paplay")
        .args(["-d", "vsink"])
        .arg(&wav)
        .spawn()
        .unwrap();
    let out = live.wait_with_output().unwrap();
    let _ = player.kill();
    let _ = player.wait();
    let err = String::from_utf8_lossy(&out.stderr);
    eprintln!("{err}");
    assert!(out.status.success(), "tactus live failed: {err}");
    assert!(err.contains("overruns 0 samples"), "{err}");

    let p = pins(&log);
    // 9 s of 25 ms bins = 360 frames; the sink may coalesce a burst (latest state), and
    // the engine's look-ahead holds back the last ~0.3 s.
    assert!(p.len() > 250, "only {} frames arrived", p.len());
    let mut onsets = Vec::new();
    let mut prev = false;
    // Judge the steady state: from 3 s of captured audio on, paplay has started and the
    // streaming engine's running statistics (gate reference, flux threshold) have settled;
    // before that, measured runs show extra onsets 75-100 ms after a hit.
    for (t, _, f) in p.iter().filter(|x| x.0 >= 3000) {
        let up = index_up(f);
        if up && !prev {
            onsets.push(*t as f64);
        }
        prev = up;
    }
    // paplay starts within ~1.5 s of the first capture callback, so 3..9 s hold 12 hits;
    // ask for 8.
    eprintln!("index onsets ({}): {onsets:?}", onsets.len());
    assert!(onsets.len() >= 8, "index onsets {onsets:?}");
    // In captured-sample time the hits are exactly 500 ms apart (the WAV is at the sink's
    // rate, and the engine resamples by an exact ratio). Each onset is quantised to a 25 ms
    // bin and the flux peak can move by one 10 ms hop: |interval − 500| ≤ 25 + 10 < 40 ms.
    // A frame lost to the sink's latest-state coalescing can merge two intervals, so 80 %
    // of them must be within the tolerance (spurious onsets would break this).
    let intervals: Vec<f64> = onsets.windows(2).map(|w| w[1] - w[0]).collect();
    let good = intervals
        .iter()
        .filter(|&&i| (i - 500.0).abs() < 40.0)
        .count();
    assert!(
        good * 5 >= intervals.len() * 4,
        "onsets {onsets:?}, intervals {intervals:?}"
    );
}

/// Plays `target` (a song or a pattern file) with `extra` arguments through the server
/// into a file glove in `d`; asserts that it succeeded on the audio clock and returns the
/// process's wall time and the frames the glove logged.
fn play_on_audio(pulse: &Pulse, target: &Path, extra: &[&str], d: &Path) -> (f64, Vec<String>) {
    let log = d.join("play.jsonl");
    let t = Instant::now();
    let out = pulse
        .cmd(bin())
        .arg("play")
        .arg(target)
        .args(extra)
        .arg("--glove")
        .arg(format!("file:{}", log.display()))
        .output()
        .unwrap();
    let wall = t.elapsed().as_secs_f64();
    let err = String::from_utf8_lossy(&out.stderr);
    eprintln!("{err}  (process wall time {wall:.3} s)");
    assert!(out.status.success(), "tactus play failed: {err}");
    assert!(
        !err.contains("warning"),
        "play fell back to the wall clock: {err}"
    );
    assert!(err.contains("tactus: audio on "), "{err}");
    (wall, pins(&log).into_iter().map(|x| x.2).collect())
}

/// PulseAudio's ALSA plugin swallows the first 170-300 ms of writes at once, so the
/// frames-written clock leaps at start and the sink coalesces the first few frames (latest
/// state). From 300 ms (frame 12) on, every frame must arrive, in order, equal.
fn assert_every_frame_from_300_ms(got: &[String], expected: &[String]) {
    let tail = &expected[12..];
    assert!(
        got.len() >= tail.len() && got[got.len() - tail.len()..] == *tail,
        "frames sent differ from the streaming render: got {} frames, want {}",
        got.len(),
        expected.len()
    );
}

#[test]
fn play_times_frames_on_the_audio_output() {
    let Some(pulse) = Pulse::start(
        "play_times_frames_on_the_audio_output",
        &["pulseaudio", "pactl"],
    ) else {
        return;
    };
    let d = tempfile::tempdir().unwrap();
    // The frames a streaming render produces: what play must deliver, all of them.
    let (song, _pattern, expected) = song_and_pattern(d.path());
    let (wall, got) = play_on_audio(&pulse, &song, &[], d.path());
    assert_every_frame_from_300_ms(&got, &expected);
    // The audio clock cannot run faster than the sound: the song takes its duration at
    // least. Upper bound: PulseAudio's ~1.5 s start plus render start-up, far below 8 s.
    assert!(
        (4.0..12.0).contains(&wall),
        "play took {wall:.3} s for a 4 s song"
    );
}

/// Renders a 4 s hit track to `song.wav` and `song.json` (streaming, 25 ms bins: what
/// `play SONG` would send) in `d`; returns (song, pattern, expected frames).
fn song_and_pattern(d: &Path) -> (std::path::PathBuf, std::path::PathBuf, Vec<String>) {
    let song = d.join("song.wav");
    write_hits(&song, 44_100, 4.0, 0.1, 0.5);
    let pattern = d.join("song.json");
    let frames = common::render_frames(&song, &pattern, "streaming");
    (song, pattern, frames)
}

/// `play SONG --whole` on the audio clock: the song rendered offline first, its frames then
/// sent on the sound's own clock, every one from 300 ms on.
#[test]
fn play_whole_follows_the_audio_clock_with_the_offline_frames() {
    let test = "play_whole_follows_the_audio_clock_with_the_offline_frames";
    let Some(pulse) = Pulse::start(test, &["pulseaudio", "pactl"]) else {
        return;
    };
    let d = tempfile::tempdir().unwrap();
    let (song, _pattern, _streaming) = song_and_pattern(d.path());
    let expected = common::render_frames(&song, &d.path().join("offline.json"), "offline");
    let (wall, got) = play_on_audio(&pulse, &song, &["--whole"], d.path());
    assert_every_frame_from_300_ms(&got, &expected);
    assert!(
        (4.0..12.0).contains(&wall),
        "play took {wall:.3} s for a 4 s song"
    );
}

#[test]
fn play_pattern_plays_its_song_on_the_audio_clock() {
    let test = "play_pattern_plays_its_song_on_the_audio_clock";
    let Some(pulse) = Pulse::start(test, &["pulseaudio", "pactl"]) else {
        return;
    };
    let d = tempfile::tempdir().unwrap();
    let (_song, pattern, expected) = song_and_pattern(d.path());
    let (wall, got) = play_on_audio(&pulse, &pattern, &[], d.path());
    assert_every_frame_from_300_ms(&got, &expected);
    // The audio clock cannot run faster than the sound.
    assert!(
        (4.0..12.0).contains(&wall),
        "play took {wall:.3} s for a 4 s song"
    );
}

/// Frames due after the song's last sample still go out, and play ends cleanly: with
/// `--offset-ms -300` the last 250 ms of frames are due after the sound has ended, when
/// the device has no position left to follow (the play clock then runs on the wall clock;
/// a clock that waited for the device stopped there and play failed after 10 s).
#[test]
fn frames_due_after_the_song_s_end_still_go_out() {
    let test = "frames_due_after_the_song_s_end_still_go_out";
    let Some(pulse) = Pulse::start(test, &["pulseaudio", "pactl"]) else {
        return;
    };
    let d = tempfile::tempdir().unwrap();
    let (_song, pattern, expected) = song_and_pattern(d.path());
    let (_, got) = play_on_audio(&pulse, &pattern, &["--offset-ms", "-300"], d.path());
    assert_every_frame_from_300_ms(&got, &expected);
}

#[test]
fn play_pattern_refuses_a_wrong_or_missing_song_and_engine_options() {
    let d = tempfile::tempdir().unwrap();
    let (song, pattern, _) = song_and_pattern(d.path());
    let play = |extra: &[&str]| {
        let o = Command::new(bin())
            .arg("play")
            .arg(&pattern)
            .args(["--glove", "null"])
            .args(extra)
            .output()
            .unwrap();
        assert!(!o.status.success(), "play {extra:?} succeeded");
        let err = String::from_utf8_lossy(&o.stderr).to_string();
        assert_eq!(err.lines().count(), 1, "{err}");
        err
    };
    // A different file: refused by its SHA-256.
    let other = d.path().join("other.wav");
    write_hits(&other, 44_100, 4.0, 0.2, 0.5);
    let err = play(&["--audio", other.to_str().unwrap()]);
    assert!(err.contains("does not match the pattern's"), "{err}");
    // Engine options with a pattern are an error, not ignored.
    let err = play(&["--levels", "4", "--bin-ms", "10"]);
    assert!(
        err.contains("a pattern file is played as rendered") && err.contains("--levels"),
        "{err}"
    );
    // The recorded song gone: a clear error naming the way out.
    std::fs::remove_file(&song).unwrap();
    let err = play(&[]);
    assert!(
        err.contains("was not found") && err.contains("--audio"),
        "{err}"
    );
    // ... while --no-audio still plays on the wall clock, without the song.
    let o = Command::new(bin())
        .arg("play")
        .arg(&pattern)
        .args(["--glove", "null", "--no-audio"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
