//! The `file:LOG.jsonl` sink: a packet recorder, JSON Lines, one object per packet written:
//!
//! ```json
//! {"mono_ms":12.345,"wall_ms":1767225600123,"seq":3,"time_ms":75,"type":"pins","frame":"8000ff00000000000000","bytes":"a50103..."}
//! ```
//!
//! * `mono_ms`: monotonic ms since the sink opened (µs resolution), the send timestamp;
//! * `wall_ms`: wall-clock ms since the Unix epoch at the same moment;
//! * `seq`, `time_ms`: the packet's sequence number and frame time (as on the wire);
//! * `type`: `pins`, `all_down` or `keep_alive`; `frame`: the 10 cell bytes in hex;
//! * `bytes`: the 16 wire bytes in hex.
//!
//! The file is created (truncated) when the sink opens; each line is flushed as it is written,
//! so an interrupted run leaves every packet sent so far. It is a stream, so it is not written
//! atomically. Latency: one buffered write and flush per packet.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::PathBuf;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

use tactus_glove::protocol::PACKET_LEN;
use tactus_glove::Packet;

use crate::link::Link;
use crate::LinkError;

pub(crate) struct FileLink {
    path: PathBuf,
    out: Option<BufWriter<File>>,
    start: Instant,
    opened: bool,
}

impl FileLink {
    pub(crate) fn new(path: PathBuf) -> FileLink {
        FileLink {
            path,
            out: None,
            start: Instant::now(),
            opened: false,
        }
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

impl Link for FileLink {
    fn connect(&mut self) -> Result<(), LinkError> {
        // Truncate on the first open only; a re-open (after a write error) appends.
        let f = if self.opened {
            std::fs::OpenOptions::new().append(true).open(&self.path)
        } else {
            File::create(&self.path)
        }?;
        if !self.opened {
            self.start = Instant::now();
            self.opened = true;
        }
        self.out = Some(BufWriter::new(f));
        Ok(())
    }

    fn write(&mut self, packet: &Packet, bytes: &[u8; PACKET_LEN]) -> Result<(), LinkError> {
        let out = self.out.as_mut().ok_or(LinkError::NotOpen("recorder"))?;
        let mono_ms = self.start.elapsed().as_secs_f64() * 1e3;
        let wall_ms = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map(|d| d.as_millis() as u64)
            .unwrap_or(0);
        let line = serde_json::json!({
            "mono_ms": (mono_ms * 1e3).round() / 1e3,
            "wall_ms": wall_ms,
            "seq": packet.seq,
            "time_ms": packet.time_ms,
            "type": packet.kind.name(),
            "frame": hex(&bytes[5..15]),
            "bytes": hex(bytes),
        });
        writeln!(out, "{line}")
            .and_then(|()| out.flush())
            .map_err(|source| LinkError::Write {
                path: self.path.display().to_string(),
                source,
            })
    }

    fn disconnect(&mut self) {
        if let Some(mut out) = self.out.take() {
            let _ = out.flush();
        }
    }
}
