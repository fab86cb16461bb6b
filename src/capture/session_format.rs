//! The session folder's format: its file names, its version, the records a capture writes
//! (`session.json`, `journal.jsonl`, `manifest.json`) and their readers. The one owner of that
//! format: the capture that writes a session, `session verify`, a resume, `calibrate SESSION` and
//! the report all read it through these types, so a format change is a compile error in every
//! reader, and a file of another version is refused with both versions named.
//!
//! Layout (format version [`FORMAT_VERSION`]):
//! ```text
//! DIR/session.json    what the session is: format, plan name, rig and camera, creation time
//! DIR/plan.toml       the plan, verbatim; a resumed capture re-reads it, so it takes the same shots
//! DIR/journal.jsonl   one ShotRecord per line, appended and fsynced after its image is on disk
//! DIR/manifest.json   snapshot: header + every record so far + status, replaced by atomic rename
//! DIR/ambient/v003_e0.exr, DIR/light/v005_ch1_e2.exr, DIR/calib/sphere_ch0_e0.exr, ...
//! DIR/sim/            simulated captures only: ground truth and what photogrammetry would give
//! DIR/.lock           held (flock) while a capture writes, so two never write one folder
//! DIR/set-aside/      damaged images a resume replaced, at their session path (+ `.N` if taken)
//! ```
//! Reads files only; writing a session is `capture::session`'s.

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::fs;
use std::path::Path;

use super::error::CaptureError;
use super::plan::ShotKind;

/// Version of the session folder format; readers refuse other major versions.
pub const FORMAT_VERSION: u32 = 1;

pub const SESSION_FILE: &str = "session.json";
pub const PLAN_FILE: &str = "plan.toml";
pub const JOURNAL_FILE: &str = "journal.jsonl";
pub const MANIFEST_FILE: &str = "manifest.json";
pub const LOCK_FILE: &str = ".lock";
/// Where a resume moves a damaged image before re-taking its shot.
pub const SET_ASIDE_DIR: &str = "set-aside";

/// What the session is (written once when it is created).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SessionHeader {
    pub format_version: u32,
    pub tool: String,
    pub plan_name: String,
    pub planned_shots: usize,
    /// Rig profile: a built-in name, or the absolute path of its file.
    pub profile: String,
    /// Camera backend (e.g. `sim`, `gphoto2`).
    pub camera_backend: String,
    pub created_utc: String,
    /// True for a simulated capture (then `sim/` holds the ground truth).
    pub simulated: bool,
}

/// One shot as taken: everything the calibrate and reconstruct steps need about it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShotRecord {
    pub id: String,
    pub index: usize,
    pub kind: ShotKind,
    pub view: Option<usize>,
    /// Turntable angle asked for and the angle the turntable reported after settling.
    pub angle_deg: f64,
    pub measured_angle_deg: f64,
    pub channel: Option<usize>,
    pub level: f64,
    /// Nominal direction to the light in the lab frame (plan `[lab]`); calibration measures it.
    pub light_dir_lab: Option<[f64; 3]>,
    pub exposure_secs: f64,
    pub gain: f64,
    pub saturation: f32,
    pub device: String,
    pub file: String,
    pub width: usize,
    pub height: usize,
    pub bytes: u64,
    pub sha256: String,
    pub time_unix: f64,
    pub time_utc: String,
    /// Set when this record re-takes a shot whose journaled image was missing or damaged.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub retake: Option<Retake>,
}

/// Why a shot was taken again, and where its damaged image went.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Retake {
    /// What the resume found, e.g. `checksum mismatch ...` or `missing`.
    pub reason: String,
    /// The damaged file, relative to the session folder (`set-aside/...`); none when it was
    /// missing.
    pub set_aside: Option<String>,
}

/// The record that counts for each shot, in journal order: the first record of a shot, replaced
/// by any later record marked `retake`. Also returns the ids of plain duplicates (a record
/// without `retake` for a shot already journaled), which this tool never writes. `session
/// verify` and a resume both read a journal through this, so they agree on what was taken.
pub fn current_records(records: Vec<ShotRecord>) -> (Vec<ShotRecord>, Vec<String>) {
    let mut current: Vec<ShotRecord> = Vec::with_capacity(records.len());
    let mut at: HashMap<String, usize> = HashMap::new();
    let mut duplicates = Vec::new();
    for r in records {
        match at.get(&r.id) {
            Some(&i) if r.retake.is_some() => current[i] = r,
            Some(_) => duplicates.push(r.id),
            None => {
                at.insert(r.id.clone(), current.len());
                current.push(r);
            }
        }
    }
    (current, duplicates)
}

/// The snapshot written by atomic rename.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub header: SessionHeader,
    /// `in_progress`, `complete`.
    pub status: String,
    pub shots: Vec<ShotRecord>,
}

/// Hex SHA-256 of bytes.
pub fn sha256_hex(bytes: &[u8]) -> String {
    hex::encode(Sha256::digest(bytes))
}

fn read_json<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<T, CaptureError> {
    let text = fs::read_to_string(path).map_err(|e| CaptureError::io("reading", path, e))?;
    serde_json::from_str(&text).map_err(|e| CaptureError::Journal {
        path: path.to_path_buf(),
        line: e.line(),
        reason: e.to_string(),
    })
}

/// Reads `DIR/session.json`, refusing another format version (naming the file and both
/// versions), so no reader misreads a session of another version.
pub fn read_header(dir: &Path) -> Result<SessionHeader, CaptureError> {
    let path = dir.join(SESSION_FILE);
    let header: SessionHeader = read_json(&path)?;
    check_version(&path, &header)?;
    Ok(header)
}

/// Reads the snapshot `DIR/manifest.json`, refusing a header of another format version.
pub fn read_manifest(dir: &Path) -> Result<Manifest, CaptureError> {
    let path = dir.join(MANIFEST_FILE);
    let manifest: Manifest = read_json(&path)?;
    check_version(&path, &manifest.header)?;
    Ok(manifest)
}

fn check_version(path: &Path, header: &SessionHeader) -> Result<(), CaptureError> {
    if header.format_version == FORMAT_VERSION {
        return Ok(());
    }
    let dir = path.parent().unwrap_or(Path::new("."));
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    Err(CaptureError::Session {
        path: dir.to_path_buf(),
        reason: format!(
            "{name}: session format version {}, but this brdf-rig reads version \
             {FORMAT_VERSION} (captured with another version of the tool)",
            header.format_version
        ),
    })
}

/// Reads the journal. Returns the records and the byte length of the well-formed prefix: a last
/// line without its newline, or one that does not parse, is a torn append and is left out. A bad
/// line anywhere else is an error naming the line.
pub fn read_journal(path: &Path) -> Result<(Vec<ShotRecord>, u64), CaptureError> {
    let bytes = match fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok((Vec::new(), 0)),
        Err(e) => return Err(CaptureError::io("reading the journal", path, e)),
    };
    let mut records = Vec::new();
    let mut good_len = 0u64;
    let mut start = 0usize;
    let mut line_no = 0usize;
    while start < bytes.len() {
        line_no += 1;
        let end = match bytes[start..].iter().position(|&b| b == b'\n') {
            Some(p) => start + p,
            None => break, // torn: no newline
        };
        let line = &bytes[start..end];
        let is_last = end + 1 >= bytes.len();
        match serde_json::from_slice::<ShotRecord>(line) {
            Ok(r) => {
                records.push(r);
                good_len = (end + 1) as u64;
            }
            Err(_) if is_last => break,
            Err(e) => {
                return Err(CaptureError::Journal {
                    path: path.to_path_buf(),
                    line: line_no,
                    reason: format!("not a shot record: {e}"),
                });
            }
        }
        start = end + 1;
    }
    Ok((records, good_len))
}
