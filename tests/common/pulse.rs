//! A private PulseAudio server with a null sink `vsink` (48 kHz) whose monitor is the
//! default source, in its own runtime directory, stopped on drop: the stand-in for a sound
//! card in the live and play tests (`#[path = "common/pulse.rs"] mod pulse;`).

use std::path::Path;
use std::process::{Command, Stdio};

use super::common;

pub struct Pulse {
    dir: tempfile::TempDir,
    /// Held for the server's lifetime: one audio test at a time on this machine. Several
    /// servers and renderers at once on two cores starved the sound (a 4 s song took 9.9 s
    /// of wall time) and the sink coalesced frames that the tests require to arrive.
    _turn: std::fs::File,
}

impl Pulse {
    /// Starts the server, or `None` (after `common::skip` says why) when one of `programs`
    /// (pulseaudio and whatever else the test runs) is not installed.
    pub fn start(test: &str, programs: &[&str]) -> Option<Pulse> {
        for p in programs {
            let found = Command::new("sh")
                .args(["-c", &format!("command -v {p}")])
                .stdout(Stdio::null())
                .status()
                .is_ok_and(|s| s.success());
            if !found {
                common::skip(&format!(
                    "{test}: {p} is not installed \
                     (apt-get install pulseaudio pulseaudio-utils libasound2-plugins; CI does)"
                ));
                return None;
            }
        }
        let turn = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(std::env::temp_dir().join("tactus-audio-tests.lock"))
            .unwrap();
        turn.lock().unwrap();
        let dir = tempfile::tempdir().unwrap();
        let mut perms = std::fs::metadata(dir.path()).unwrap().permissions();
        std::os::unix::fs::PermissionsExt::set_mode(&mut perms, 0o700);
        std::fs::set_permissions(dir.path(), perms).unwrap();
        let p = Pulse { dir, _turn: turn };
        let st = p
            .cmd("pulseaudio")
            .args([
                "-D",
                "-n",
                "--exit-idle-time=-1",
                "-L",
                "module-native-protocol-unix",
                "-L",
                "module-null-sink sink_name=vsink rate=48000",
                "-L",
                "module-always-sink",
            ])
            .stderr(Stdio::null())
            .status()
            .unwrap();
        assert!(st.success(), "pulseaudio did not start");
        let st = p
            .cmd("pactl")
            .args(["set-default-source", "vsink.monitor"])
            .status()
            .unwrap();
        assert!(st.success(), "pactl set-default-source failed");
        Some(p)
    }

    /// A command that talks to this server.
    pub fn cmd(&self, program: &str) -> Command {
        let mut c = Command::new(program);
        c.env("XDG_RUNTIME_DIR", self.dir.path());
        c
    }
}

impl Drop for Pulse {
    fn drop(&mut self) {
        // `-k` stops the server of this runtime directory only.
        let _ = self
            .cmd("pulseaudio")
            .arg("-k")
            .stderr(Stdio::null())
            .status();
    }
}

/// Writes `x` as a mono 16-bit WAV (scaled by 32,000, clamped to ±1) for the server to play.
pub fn write_wav(path: &Path, rate: u32, x: &[f32]) {
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: rate,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    for &v in x {
        w.write_sample((v.clamp(-1.0, 1.0) * 32_000.0) as i16)
            .unwrap();
    }
    w.finalize().unwrap();
}

/// (time_ms, mono_ms, frame hex) of every pins packet in a file-sink log (`--glove
/// file:LOG.jsonl`).
pub fn pins(log: &Path) -> Vec<(u64, f64, String)> {
    std::fs::read_to_string(log)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|v| v["type"] == "pins")
        .map(|v| {
            (
                v["time_ms"].as_u64().unwrap(),
                v["mono_ms"].as_f64().unwrap(),
                v["frame"].as_str().unwrap().to_string(),
            )
        })
        .collect()
}

/// Whether any index-finger pin (cells 2 and 3: kick and snare) is up in a frame's hex.
pub fn index_up(frame_hex: &str) -> bool {
    &frame_hex[4..8] != "0000"
}
