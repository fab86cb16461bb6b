//! Errors of the capture module. Each names what was being done and on which file.

use std::path::PathBuf;
use thiserror::Error;

use crate::devices::DeviceError;

#[derive(Debug, Error)]
pub enum CaptureError {
    #[error("{what} ({path}): {source}")]
    Io {
        what: String,
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("capture plan {origin}: {reason}")]
    Plan { origin: String, reason: String },
    #[error("session folder {path}: {reason}")]
    Session { path: PathBuf, reason: String },
    #[error("{path}, line {line}: {reason}")]
    Journal {
        path: PathBuf,
        line: usize,
        reason: String,
    },
    #[error(
        "not enough free disk space in {path}: the capture needs about {needed_mib} MiB, {available_mib} MiB are free"
    )]
    DiskSpace {
        path: PathBuf,
        needed_mib: u64,
        available_mib: u64,
    },
    #[error("shot {shot}: {source}")]
    Device {
        shot: String,
        #[source]
        source: DeviceError,
    },
    #[error("{0}")]
    Setup(String),
    #[error(
        "capture interrupted by the operator ({done} of {total} shots are in the session; resume with `brdf-rig capture --resume`)"
    )]
    Interrupted { done: usize, total: usize },
    #[error("encoding {file}: {reason}")]
    Encode { file: String, reason: String },
}

impl CaptureError {
    pub fn io(what: impl Into<String>, path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        CaptureError::Io {
            what: what.into(),
            path: path.into(),
            source,
        }
    }
}
