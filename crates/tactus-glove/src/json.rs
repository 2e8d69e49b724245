//! Shared helpers for reading the versioned JSON files (pattern, features): parse to an
//! object, check `format` and `version`, pull typed fields with errors that name the key.

use crate::error::one_line;
use serde::de::DeserializeOwned;
use serde_json::{Map, Value};

use crate::GloveError;

pub(crate) type Object = Map<String, Value>;

/// The readers and writers every versioned JSON file kind shares, written once:
/// `from_json_str`, `read_from` and `from_path` (errors name the file), all through the
/// kind's `from_slice`; `write_to` and `write_to_path` (atomic), through its
/// `to_json_string`.
macro_rules! json_file_readers {
    ($t:ident) => {
        impl $t {
            /// Parses from JSON text.
            pub fn from_json_str(s: &str) -> Result<$t, GloveError> {
                $t::from_slice(s.as_bytes())
            }

            /// Reads from `r`.
            pub fn read_from(mut r: impl std::io::Read) -> Result<$t, GloveError> {
                let mut bytes = Vec::new();
                r.read_to_end(&mut bytes)?;
                $t::from_slice(&bytes)
            }

            /// Reads a file; errors name the file.
            pub fn from_path(path: impl AsRef<std::path::Path>) -> Result<$t, GloveError> {
                let path = path.as_ref();
                std::fs::read(path)
                    .map_err(GloveError::from)
                    .and_then(|b| $t::from_slice(&b))
                    .map_err(|e| e.in_file(path))
            }

            /// Writes the JSON to `w`.
            pub fn write_to(&self, w: &mut dyn std::io::Write) -> Result<(), GloveError> {
                w.write_all(self.to_json_string()?.as_bytes())?;
                Ok(())
            }

            /// Writes the JSON to `path` atomically (`-` = stdout).
            pub fn write_to_path(
                &self,
                path: impl AsRef<std::path::Path>,
            ) -> Result<(), GloveError> {
                let path = path.as_ref();
                let text = self.to_json_string()?;
                crate::atomic::write_atomic(path, |w| w.write_all(text.as_bytes()))
                    .map_err(|e| GloveError::from(e).in_file(path))
            }
        }
    };
}
pub(crate) use json_file_readers;

/// Parses `bytes` as one JSON object; empty input and syntax errors get their own errors.
pub(crate) fn parse_object(bytes: &[u8], what: &'static str) -> Result<Object, GloveError> {
    if bytes.iter().all(u8::is_ascii_whitespace) {
        return Err(GloveError::Empty { what });
    }
    let value: Value = serde_json::from_slice(bytes).map_err(|e| GloveError::NotJson {
        line: e.line(),
        column: e.column(),
        message: one_line(e.to_string()),
    })?;
    match value {
        Value::Object(o) => Ok(o),
        other => Err(GloveError::InvalidField {
            field: "(document)".into(),
            reason: format!("expected a JSON object, found {}", kind(&other)),
        }),
    }
}

/// Checks `format` (required or optional) and `version` (same) against this reader.
pub(crate) fn check_header(
    obj: &Object,
    format: &'static str,
    what: &'static str,
    supported: u64,
    required: bool,
) -> Result<(), GloveError> {
    match obj.get("format") {
        None if required => return Err(GloveError::MissingField("format")),
        None => {}
        Some(Value::String(s)) if s == format => {}
        Some(other) => {
            return Err(GloveError::WrongFormat {
                expected: format,
                found: other.to_string(),
            })
        }
    }
    match obj.get("version") {
        None if required => Err(GloveError::MissingField("version")),
        None => Ok(()),
        Some(v) => match v.as_u64() {
            Some(found) if found == supported => Ok(()),
            Some(found) => Err(GloveError::UnsupportedVersion {
                what,
                found,
                supported,
            }),
            None => Err(GloveError::InvalidField {
                field: "version".into(),
                reason: format!("expected a whole number, found {v}"),
            }),
        },
    }
}

/// A required field of type `T`.
pub(crate) fn required<T: DeserializeOwned>(
    obj: &Object,
    key: &'static str,
) -> Result<T, GloveError> {
    let v = obj.get(key).ok_or(GloveError::MissingField(key))?;
    typed(v, key)
}

/// An optional field of type `T` (absent or null = `None`).
pub(crate) fn optional<T: DeserializeOwned>(
    obj: &Object,
    key: &'static str,
) -> Result<Option<T>, GloveError> {
    match obj.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(v) => typed(v, key).map(Some),
    }
}

pub(crate) fn typed<T: DeserializeOwned>(v: &Value, field: &str) -> Result<T, GloveError> {
    T::deserialize(v).map_err(|e| GloveError::InvalidField {
        field: one_line(field),
        reason: one_line(e.to_string()),
    })
}

pub(crate) fn kind(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

pub(crate) fn invalid(field: impl Into<String>, reason: impl Into<String>) -> GloveError {
    GloveError::InvalidField {
        field: one_line(field.into()),
        reason: one_line(reason.into()),
    }
}
