//! `session verify`: re-reads every image a session lists and checks its size and SHA-256, and
//! that the journal holds exactly the planned shots. Read-only; works on a session a capture is
//! still writing (it reads the journal prefix that is complete).
//!
//! [`check_record`] is the one check of an image against its record: a resume uses it to find
//! the shots to take again, and `calibrate SESSION` to refuse a damaged image, so all three
//! agree on what is intact. A shot taken again (`retake`) is judged by its latest record.

use std::collections::HashSet;
use std::fmt;
use std::fs;
use std::path::Path;

use super::error::CaptureError;
use super::plan::parse_plan;
use super::session_format::{
    JOURNAL_FILE, MANIFEST_FILE, PLAN_FILE, SessionHeader, ShotRecord, current_records,
    read_header, read_journal, read_manifest, sha256_hex,
};

/// One problem found.
#[derive(Clone, Debug, PartialEq)]
pub enum Problem {
    Missing {
        id: String,
        file: String,
    },
    Mismatch {
        id: String,
        file: String,
        expected: String,
        actual: String,
    },
    WrongSize {
        id: String,
        file: String,
        expected: u64,
        actual: u64,
    },
    Duplicate {
        id: String,
    },
    Unplanned {
        id: String,
    },
    SnapshotAhead {
        id: String,
    },
}

impl Problem {
    /// What is wrong, without the file and shot (a re-take record's `reason`).
    pub fn what(&self) -> String {
        match self {
            Problem::Missing { .. } => "missing".to_string(),
            Problem::Mismatch {
                expected, actual, ..
            } => format!("checksum mismatch: journal sha256 {expected}, file {actual}"),
            Problem::WrongSize {
                expected, actual, ..
            } => format!("size {actual} bytes, journal says {expected}"),
            Problem::Duplicate { .. } => "journaled more than once".to_string(),
            Problem::Unplanned { .. } => "not in the session's plan".to_string(),
            Problem::SnapshotAhead { .. } => format!("in {MANIFEST_FILE} but not journaled"),
        }
    }
}

/// Checks the image of one record against its size and SHA-256. Returns the bytes read and
/// the problem, if any (`Missing`, `WrongSize` or `Mismatch`).
pub fn check_record(dir: &Path, r: &ShotRecord) -> (u64, Option<Problem>) {
    let data = match fs::read(dir.join(&r.file)) {
        Ok(d) => d,
        Err(_) => {
            return (
                0,
                Some(Problem::Missing {
                    id: r.id.clone(),
                    file: r.file.clone(),
                }),
            );
        }
    };
    let len = data.len() as u64;
    if len != r.bytes {
        return (
            len,
            Some(Problem::WrongSize {
                id: r.id.clone(),
                file: r.file.clone(),
                expected: r.bytes,
                actual: len,
            }),
        );
    }
    let actual = sha256_hex(&data);
    if actual != r.sha256 {
        return (
            len,
            Some(Problem::Mismatch {
                id: r.id.clone(),
                file: r.file.clone(),
                expected: r.sha256.clone(),
                actual,
            }),
        );
    }
    (len, None)
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Problem::Missing { id, file } => write!(f, "{file}: missing (shot {id})"),
            Problem::Mismatch {
                id,
                file,
                expected,
                actual,
            } => write!(
                f,
                "{file}: checksum mismatch (shot {id}): manifest sha256 {expected}, file {actual}"
            ),
            Problem::WrongSize {
                id,
                file,
                expected,
                actual,
            } => write!(
                f,
                "{file}: size {actual} bytes, manifest says {expected} (shot {id})"
            ),
            Problem::Duplicate { id } => write!(f, "shot {id} is journaled more than once"),
            Problem::Unplanned { id } => write!(f, "shot {id} is not in the session's plan"),
            Problem::SnapshotAhead { id } => {
                write!(
                    f,
                    "{MANIFEST_FILE} lists shot {id}, which the journal lacks"
                )
            }
        }
    }
}

/// The outcome of a verification.
#[derive(Clone, Debug)]
pub struct VerifyReport {
    pub header: SessionHeader,
    pub planned: usize,
    pub checked: usize,
    pub bytes: u64,
    pub problems: Vec<Problem>,
    /// Planned shots not yet taken (an interrupted capture; resume it).
    pub not_taken: Vec<String>,
    /// Shots taken again by a resume, with why (their damaged files are in `set-aside/`).
    pub retaken: Vec<(String, super::session_format::Retake)>,
}

impl VerifyReport {
    /// True when every journaled image is intact (the session may still be incomplete).
    pub fn intact(&self) -> bool {
        self.problems.is_empty()
    }

    pub fn complete(&self) -> bool {
        self.not_taken.is_empty()
    }
}

/// Verifies the session in `dir`.
pub fn verify_session(dir: &Path) -> Result<VerifyReport, CaptureError> {
    let header = read_header(dir)?;
    let plan_path = dir.join(PLAN_FILE);
    let plan_text = fs::read_to_string(&plan_path)
        .map_err(|e| CaptureError::io("reading the session's plan", &plan_path, e))?;
    let plan = parse_plan(&plan_text, &plan_path.display().to_string())?;
    let planned = plan.shots();
    let (records, _) = read_journal(&dir.join(JOURNAL_FILE))?;
    let (records, duplicates) = current_records(records);
    let mut problems: Vec<Problem> = duplicates
        .into_iter()
        .map(|id| Problem::Duplicate { id })
        .collect();
    let seen: HashSet<String> = records.iter().map(|r| r.id.clone()).collect();
    let planned_ids: HashSet<&str> = planned.iter().map(|s| s.id.as_str()).collect();
    let mut bytes = 0;
    let mut retaken = Vec::new();
    for r in &records {
        if !planned_ids.contains(r.id.as_str()) {
            problems.push(Problem::Unplanned { id: r.id.clone() });
        }
        let (n, problem) = check_record(dir, r);
        bytes += n;
        problems.extend(problem);
        if let Some(t) = &r.retake {
            retaken.push((r.id.clone(), t.clone()));
        }
    }
    // The snapshot may lag the journal (a kill between the two) but never lead it.
    if dir.join(MANIFEST_FILE).exists() {
        let m = read_manifest(dir)?;
        for s in m.shots {
            if !seen.contains(&s.id) {
                problems.push(Problem::SnapshotAhead { id: s.id });
            }
        }
    }
    let not_taken = planned
        .iter()
        .filter(|s| !seen.contains(&s.id))
        .map(|s| s.id.clone())
        .collect();
    Ok(VerifyReport {
        header,
        planned: planned.len(),
        checked: seen.len(),
        bytes,
        problems,
        not_taken,
        retaken,
    })
}
