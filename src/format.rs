//! The mechanics shared by the JSON files the steps hand each other (`calibration.json`,
//! `report.json`, `sim/truth.json`): read the version first, then the typed record, write by
//! atomic rename; every error names the file. Each format's owner module holds its serde type,
//! its file name and its version, and calls these; a reader never opens such a file as untyped
//! JSON.
//!
//! A file without `format_version` was written before versions were recorded: it is read as
//! version 1. A file of another version is refused with both versions named, before its fields
//! are looked at, so a reader never misreads a newer file.

use serde::Serialize;
use serde::de::DeserializeOwned;
use std::path::{Path, PathBuf};

/// Why a versioned file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    #[error("{path}: cannot read: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: not a valid {what}: {message}")]
    Parse {
        path: PathBuf,
        what: &'static str,
        message: String,
    },
    #[error(
        "{path}: {what} format_version {found}, but this brdf-rig reads version {supported} \
         ({remedy})"
    )]
    Version {
        path: PathBuf,
        what: &'static str,
        found: u64,
        supported: u32,
        remedy: &'static str,
    },
    #[error("{path}: cannot write: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
}

impl FormatError {
    /// True when the file does not exist (a reader may treat that as "not made yet").
    pub fn is_not_found(&self) -> bool {
        matches!(self, FormatError::Read { source, .. } if source.kind() == std::io::ErrorKind::NotFound)
    }
}

/// What a versioned file is, for its reader: its name in messages, its version, and what to do
/// about a file of another version.
#[derive(Clone, Copy, Debug)]
pub struct Versioned {
    /// e.g. "calibration file (calibration.json)".
    pub what: &'static str,
    pub version: u32,
    /// e.g. "re-run `brdf-rig calibrate` on the session".
    pub remedy: &'static str,
}

/// The version a file without `format_version` has.
pub const fn version_1() -> u32 {
    1
}

impl Versioned {
    /// Reads `path` as this format: the version first, then the typed record.
    pub fn read<T: DeserializeOwned>(&self, path: &Path) -> Result<T, FormatError> {
        let bytes = std::fs::read(path).map_err(|source| FormatError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        self.parse(&bytes, path)
    }

    /// Parses bytes as this format; `path` names them in errors.
    pub fn parse<T: DeserializeOwned>(&self, bytes: &[u8], path: &Path) -> Result<T, FormatError> {
        let parse_err = |message: String| FormatError::Parse {
            path: path.to_path_buf(),
            what: self.what,
            message,
        };
        #[derive(serde::Deserialize)]
        struct Version {
            #[serde(default)]
            format_version: Option<serde_json::Value>,
        }
        let v: Version = serde_json::from_slice(bytes).map_err(|e| parse_err(e.to_string()))?;
        let found = match v.format_version {
            None => u64::from(version_1()),
            Some(x) => x
                .as_u64()
                .ok_or_else(|| parse_err(format!("format_version {x} is not a version number")))?,
        };
        if found != u64::from(self.version) {
            return Err(FormatError::Version {
                path: path.to_path_buf(),
                what: self.what,
                found,
                supported: self.version,
                remedy: self.remedy,
            });
        }
        let mut de = serde_json::Deserializer::from_slice(bytes);
        serde_path_to_error::deserialize(&mut de).map_err(|e| {
            let field = e.path().to_string();
            parse_err(if field == "." {
                e.inner().to_string()
            } else {
                format!("`{field}`: {}", e.inner())
            })
        })
    }

    /// Writes `value` to `path` as pretty JSON, atomically.
    pub fn write<T: Serialize>(&self, path: &Path, value: &T) -> Result<(), FormatError> {
        let write_err = |source: std::io::Error| FormatError::Write {
            path: path.to_path_buf(),
            source,
        };
        let json = serde_json::to_vec_pretty(value).map_err(|e| write_err(e.into()))?;
        crate::imageio::write_atomic(path, &json).map_err(write_err)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[derive(Debug, PartialEq, serde::Serialize, serde::Deserialize)]
    struct Rec {
        #[serde(default = "version_1")]
        format_version: u32,
        items: Vec<f64>,
    }

    const FMT: Versioned = Versioned {
        what: "test file (t.json)",
        version: 1,
        remedy: "make it again",
    };

    #[test]
    fn versions_are_checked_before_fields_and_errors_name_file_and_field() {
        let p = Path::new("/x/t.json");
        let r: Rec = FMT.parse(br#"{"items": [1.0]}"#, p).unwrap();
        assert_eq!(r.format_version, 1, "a file without a version is version 1");
        let e = FMT
            .parse::<Rec>(br#"{"format_version": 2, "other": 1}"#, p)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("/x/t.json") && e.contains("format_version 2") && e.contains("version 1"),
            "{e}"
        );
        let e = FMT
            .parse::<Rec>(br#"{"items": [1.0, "a"]}"#, p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("/x/t.json") && e.contains("`items[1]`"), "{e}");
        let e = FMT.parse::<Rec>(b"{ not json", p).unwrap_err().to_string();
        assert!(e.contains("not a valid test file"), "{e}");
    }

    #[test]
    fn write_then_read() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.json");
        let r = Rec {
            format_version: 1,
            items: vec![0.5, 2.0],
        };
        FMT.write(&p, &r).unwrap();
        assert_eq!(FMT.read::<Rec>(&p).unwrap(), r);
        assert!(
            FMT.read::<Rec>(&dir.path().join("no.json"))
                .unwrap_err()
                .is_not_found()
        );
    }
}
