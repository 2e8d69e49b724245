//! Shared helpers for the transport tests: tool detection, a socat pty pair, test patterns.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use tactus_transport::Frame;

/// The path of `tool` on `$PATH`, if present.
pub fn which(tool: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join(tool))
        .find(|p| p.is_file())
}

/// Skips the calling test on a developer's machine, fails it under `CI=true`, when a
/// stand-in is missing.
pub use tactus_testkit::skip;

/// Skips (see [`skip`]) and returns true when `tool` is missing.
pub fn skip_without(tool: &str, test: &str) -> bool {
    if which(tool).is_none() {
        skip(&format!(
            "{test}: `{tool}` is not installed \
             (apt-get install socat python3-dbusmock dbus libdbus-1-dev)"
        ));
        return true;
    }
    false
}

/// A socat pty pair `DIR/ttyA` <-> `DIR/ttyB`.
pub struct PtyPair {
    pub dir: PathBuf,
    child: Option<Child>,
}

impl PtyPair {
    /// Starts socat and waits (up to 5 s) for both links to appear.
    pub fn start(dir: &Path) -> PtyPair {
        let mut pair = PtyPair {
            dir: dir.to_path_buf(),
            child: None,
        };
        pair.restart();
        pair
    }

    pub fn a(&self) -> PathBuf {
        self.dir.join("ttyA")
    }

    pub fn b(&self) -> PathBuf {
        self.dir.join("ttyB")
    }

    /// (Re)starts socat with the same link names.
    pub fn restart(&mut self) {
        let _ = std::fs::remove_file(self.a());
        let _ = std::fs::remove_file(self.b());
        let child = Command::new("socat")
            .arg(format!("pty,raw,echo=0,link={}", self.a().display()))
            .arg(format!("pty,raw,echo=0,link={}", self.b().display()))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("socat starts");
        self.child = Some(child);
        let t0 = Instant::now();
        while !(self.a().exists() && self.b().exists()) {
            assert!(
                t0.elapsed() < Duration::from_secs(5),
                "socat links did not appear"
            );
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// Kills socat (SIGKILL, like a yanked cable) and waits for it to exit; the pty master
    /// sides close, so both ends see a hang-up.
    pub fn kill(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

impl Drop for PtyPair {
    fn drop(&mut self) {
        self.kill();
    }
}

/// `n` frames of known, pairwise different content (no two consecutive frames equal).
pub fn pattern(n: usize) -> Vec<Frame> {
    (0..n)
        .map(|k| {
            let mut f = [0u8; 10];
            for (i, b) in f.iter_mut().enumerate() {
                // A different byte per cell and frame; frame k is unique through cell 0.
                *b = (k as u8)
                    .wrapping_mul(37)
                    .wrapping_add((i as u8).wrapping_mul(11))
                    ^ (k >> 8) as u8;
            }
            Frame(f)
        })
        .collect()
}

/// Nearest-rank percentile of non-negative values.
pub fn percentile(values: &[f64], p: f64) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return 0.0;
    }
    v[((v.len() as f64 * p).ceil() as usize).clamp(1, v.len()) - 1]
}
