//! The `--glove SINK` syntax (docs/design.md, "CLI", a contract):
//!
//! ```text
//! SINK = serial:PATH[@BAUD] | ble[:NAME|ADDRESS] | file:LOG.jsonl | emulator[:LOG.jsonl] | null
//! ```
//!
//! * `serial:/dev/ttyUSB0` uses [`DEFAULT_BAUD`] (115200); `serial:/dev/ttyUSB0@9600` sets it.
//!   Only a trailing `@` followed by digits is a baud rate, so paths may contain `@`.
//! * `ble` connects to the first device offering service 0xFFE0; `ble:HMP-Glove` matches the
//!   advertised name exactly; `ble:AA:BB:CC:DD:EE:FF` (six hex pairs) matches the address.
//! * `file:LOG.jsonl` records every packet as one JSON object per line.
//! * `emulator` runs the virtual glove in process; `emulator:LOG.jsonl` also writes its
//!   actuation log.
//! * `null` only counts.
//!
//! Parsing is pure and never panics; [`std::fmt::Display`] writes the canonical form back.

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

use crate::TransportError;

/// Default UART speed of the glove's serial link (docs/design.md, "Wire protocol v1").
pub const DEFAULT_BAUD: u32 = 115_200;

/// Which BLE device a `ble` sink connects to.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BleTarget {
    /// The first device that advertises service 0xFFE0.
    Any,
    /// The device whose advertised local name equals this.
    Name(String),
    /// The device with this address (upper-case `AA:BB:CC:DD:EE:FF`).
    Address(String),
}

/// A parsed `--glove SINK`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SinkSpec {
    /// A UART (or a pty) at `path`.
    Serial {
        /// Device path.
        path: String,
        /// Baud rate (> 0).
        baud: u32,
    },
    /// A Bluetooth LE module (feature `ble`).
    Ble(BleTarget),
    /// A JSON Lines packet recorder.
    File(PathBuf),
    /// The in-process virtual glove, with an optional actuation log.
    Emulator(Option<PathBuf>),
    /// Counts only.
    Null,
}

fn bad(spec: &str, reason: impl Into<String>) -> TransportError {
    TransportError::BadSpec {
        spec: spec.to_string(),
        reason: reason.into(),
    }
}

fn is_address(s: &str) -> bool {
    let parts: Vec<&str> = s.split(':').collect();
    parts.len() == 6
        && parts
            .iter()
            .all(|p| p.len() == 2 && p.chars().all(|c| c.is_ascii_hexdigit()))
}

impl FromStr for SinkSpec {
    type Err = TransportError;

    fn from_str(s: &str) -> Result<SinkSpec, TransportError> {
        let (scheme, rest) = match s.split_once(':') {
            Some((a, b)) => (a, Some(b)),
            None => (s, None),
        };
        match scheme {
            "null" => match rest {
                None => Ok(SinkSpec::Null),
                Some(_) => Err(bad(s, "`null` takes no argument")),
            },
            "emulator" => match rest {
                None => Ok(SinkSpec::Emulator(None)),
                Some("") => Err(bad(s, "empty log path after `emulator:`")),
                Some(p) => Ok(SinkSpec::Emulator(Some(PathBuf::from(p)))),
            },
            "file" => match rest {
                None | Some("") => Err(bad(s, "`file:` needs a log path, e.g. file:glove.jsonl")),
                Some(p) => Ok(SinkSpec::File(PathBuf::from(p))),
            },
            "ble" => match rest {
                None => Ok(SinkSpec::Ble(BleTarget::Any)),
                Some("") => Err(bad(s, "empty device name after `ble:`")),
                Some(t) if is_address(t) => {
                    Ok(SinkSpec::Ble(BleTarget::Address(t.to_ascii_uppercase())))
                }
                Some(t) => Ok(SinkSpec::Ble(BleTarget::Name(t.to_string()))),
            },
            "serial" => {
                let rest = match rest {
                    None | Some("") => {
                        return Err(bad(
                            s,
                            "`serial:` needs a device path, e.g. serial:/dev/ttyUSB0",
                        ))
                    }
                    Some(r) => r,
                };
                let (path, baud) = match rest.rsplit_once('@') {
                    Some((p, b)) if !b.contains('/') => {
                        let baud: u32 = b.parse().map_err(|_| {
                            bad(s, format!("baud rate {b:?} is not a positive integer"))
                        })?;
                        if baud == 0 {
                            return Err(bad(s, "baud rate must be positive"));
                        }
                        (p, baud)
                    }
                    _ => (rest, DEFAULT_BAUD),
                };
                if path.is_empty() {
                    return Err(bad(s, "empty device path"));
                }
                Ok(SinkSpec::Serial {
                    path: path.to_string(),
                    baud,
                })
            }
            "" => Err(bad(s, "empty sink")),
            other => Err(bad(s, format!("unknown sink kind {other:?}"))),
        }
    }
}

impl fmt::Display for SinkSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SinkSpec::Serial { path, baud } => write!(f, "serial:{path}@{baud}"),
            SinkSpec::Ble(BleTarget::Any) => f.write_str("ble"),
            SinkSpec::Ble(BleTarget::Name(n)) => write!(f, "ble:{n}"),
            SinkSpec::Ble(BleTarget::Address(a)) => write!(f, "ble:{a}"),
            SinkSpec::File(p) => write!(f, "file:{}", p.display()),
            SinkSpec::Emulator(None) => f.write_str("emulator"),
            SinkSpec::Emulator(Some(p)) => write!(f, "emulator:{}", p.display()),
            SinkSpec::Null => f.write_str("null"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_every_kind() {
        let cases: &[(&str, SinkSpec)] = &[
            ("null", SinkSpec::Null),
            ("emulator", SinkSpec::Emulator(None)),
            (
                "emulator:a.jsonl",
                SinkSpec::Emulator(Some("a.jsonl".into())),
            ),
            ("file:/tmp/x.jsonl", SinkSpec::File("/tmp/x.jsonl".into())),
            ("ble", SinkSpec::Ble(BleTarget::Any)),
            (
                "ble:HMP-Glove",
                SinkSpec::Ble(BleTarget::Name("HMP-Glove".into())),
            ),
            (
                "ble:aa:bb:cc:dd:ee:0f",
                SinkSpec::Ble(BleTarget::Address("AA:BB:CC:DD:EE:0F".into())),
            ),
            (
                "serial:/dev/ttyUSB0",
                SinkSpec::Serial {
                    path: "/dev/ttyUSB0".into(),
                    baud: 115_200,
                },
            ),
            (
                "serial:/dev/ttyUSB0@9600",
                SinkSpec::Serial {
                    path: "/dev/ttyUSB0".into(),
                    baud: 9600,
                },
            ),
            (
                "serial:/tmp/a@b/tty",
                SinkSpec::Serial {
                    path: "/tmp/a@b/tty".into(),
                    baud: 115_200,
                },
            ),
        ];
        for (text, want) in cases {
            let got: SinkSpec = text.parse().unwrap();
            assert_eq!(&got, want, "{text}");
            // Display is canonical and parses back to the same spec.
            assert_eq!(&got.to_string().parse::<SinkSpec>().unwrap(), want);
        }
    }

    #[test]
    fn rejects_bad_specs_with_reasons() {
        for (text, needle) in [
            ("", "empty sink"),
            ("usb:/dev/x", "unknown sink kind"),
            ("serial", "needs a device path"),
            ("serial:", "needs a device path"),
            ("serial:/dev/x@fast", "not a positive integer"),
            ("serial:/dev/x@0", "must be positive"),
            ("serial:@9600", "empty device path"),
            ("file", "needs a log path"),
            ("null:x", "no argument"),
            ("ble:", "empty device name"),
            ("emulator:", "empty log path"),
        ] {
            let err = text.parse::<SinkSpec>().unwrap_err().to_string();
            assert!(err.contains(needle), "{text:?} gave {err:?}");
            assert!(err.contains("expected serial:PATH"), "{err}");
        }
    }
}
