//! `truth_labels.json`, the material of every face of a simulated multi-material scene, written
//! beside the scene by `job_scene::write_scene_materials` so a benchmark or a test can score a
//! segmentation against it (`geometry::labels::area_agreement`). The owner of the format: its
//! serde type, file name and version; read and written through `crate::format` (version checked
//! first, atomic writes, errors naming the file and the field).
//!
//! Format, version [`TRUTH_LABELS_VERSION`]:
//! `{"format_version": 1, "count": N, "names": [N names, or none], "face_labels": [one label in
//! 0..N per face]}`. The labels are per face of the truth mesh, in its face order; the job's
//! `mesh.ply` has the same faces in the same order when it came from `geometry::sfm_like` (which
//! moves vertices and keeps the topology), so they are its labels too.

use crate::format::{FormatError, Versioned, version_1};
use crate::geometry::labels::FaceLabels;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The truth file's name, in the scene folder.
pub const TRUTH_LABELS_FILE: &str = "truth_labels.json";
/// The version written, and the only one read.
pub const TRUTH_LABELS_VERSION: u32 = 1;

const FORMAT: Versioned = Versioned {
    what: "truth labels file (truth_labels.json)",
    version: TRUTH_LABELS_VERSION,
    remedy: "write the simulated scene again with this brdf-rig",
};

/// The file as stored.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct TruthLabelsFile {
    #[serde(default = "version_1")]
    format_version: u32,
    count: u32,
    #[serde(default)]
    names: Vec<String>,
    face_labels: Vec<u32>,
}

/// A scene's true material per face, and the materials' names (empty when none were given).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TruthLabels {
    pub labels: FaceLabels,
    /// `labels.count` names, label `i` named `names[i]`; or empty.
    pub names: Vec<String>,
}

/// Why a truth labels file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum TruthLabelsError {
    #[error(transparent)]
    Format(#[from] FormatError),
    #[error("{path}: `{field}`: {message}")]
    Invalid {
        path: PathBuf,
        field: String,
        message: String,
    },
}

/// Checks the record's fields agree with each other; `path` names the file in errors.
fn check(
    path: &Path,
    count: u32,
    names: &[String],
    labels: &[u32],
) -> Result<(), TruthLabelsError> {
    let invalid = |field: String, message: String| TruthLabelsError::Invalid {
        path: path.to_path_buf(),
        field,
        message,
    };
    if count == 0 {
        return Err(invalid(
            "count".into(),
            "0 materials: an object has at least one".into(),
        ));
    }
    if !names.is_empty() && names.len() != count as usize {
        return Err(invalid(
            "names".into(),
            format!("{} names for {count} materials", names.len()),
        ));
    }
    if let Some((f, l)) = labels.iter().enumerate().find(|(_, l)| **l >= count) {
        return Err(invalid(
            format!("face_labels[{f}]"),
            format!("label {l}, but there are only {count} materials (labels 0..{count})"),
        ));
    }
    Ok(())
}

/// Writes `path` (a `truth_labels.json`) atomically. `names` is empty or one name per label.
pub fn write_truth_labels(
    path: &Path,
    labels: &FaceLabels,
    names: &[String],
) -> Result<(), TruthLabelsError> {
    check(path, labels.count, names, &labels.labels)?;
    let file = TruthLabelsFile {
        format_version: TRUTH_LABELS_VERSION,
        count: labels.count,
        names: names.to_vec(),
        face_labels: labels.labels.clone(),
    };
    Ok(FORMAT.write(path, &file)?)
}

/// Reads a `truth_labels.json`: the version first, then the fields, then their consistency
/// (every label below `count`, one name per material when names are given).
pub fn read_truth_labels(path: &Path) -> Result<TruthLabels, TruthLabelsError> {
    let file: TruthLabelsFile = FORMAT.read(path)?;
    check(path, file.count, &file.names, &file.face_labels)?;
    Ok(TruthLabels {
        labels: FaceLabels {
            labels: file.face_labels,
            count: file.count,
        },
        names: file.names,
    })
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_clear_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join(TRUTH_LABELS_FILE);
        let labels = FaceLabels::new(vec![0, 1, 1, 2], 4).unwrap();
        let names = vec!["a".to_string(), "b".to_string(), "c".to_string()];
        write_truth_labels(&p, &labels, &names).unwrap();
        let back = read_truth_labels(&p).unwrap();
        assert_eq!(back.labels, labels);
        assert_eq!(back.names, names);
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.contains("\"format_version\": 1") && text.contains("\"face_labels\""));

        // names are optional
        write_truth_labels(&p, &labels, &[]).unwrap();
        assert!(read_truth_labels(&p).unwrap().names.is_empty());
        assert!(write_truth_labels(&p, &labels, &names[..2]).is_err());

        let bad = |json: &str| {
            std::fs::write(&p, json).unwrap();
            read_truth_labels(&p).unwrap_err().to_string()
        };
        let e = bad(r#"{"format_version": 2, "count": 2, "face_labels": [0]}"#);
        assert!(
            e.contains(TRUTH_LABELS_FILE) && e.contains("format_version 2"),
            "{e}"
        );
        let e = bad(r#"{"format_version": 1, "count": 2, "face_labels": [0, 1, 2]}"#);
        assert!(
            e.contains(TRUTH_LABELS_FILE) && e.contains("`face_labels[2]`"),
            "{e}"
        );
        let e = bad(r#"{"format_version": 1, "count": 2, "face_labels": [0, -1]}"#);
        assert!(e.contains("`face_labels[1]`"), "{e}");
        let e = bad(r#"{"format_version": 1, "face_labels": [0]}"#);
        assert!(e.contains("count"), "{e}");
        let e = bad(r#"{"count": 2, "names": ["x"], "face_labels": [0]}"#);
        assert!(e.contains("`names`") && e.contains("1 names for 2"), "{e}");
        let missing = read_truth_labels(&dir.path().join("none.json")).unwrap_err();
        assert!(matches!(missing, TruthLabelsError::Format(ref f) if f.is_not_found()));
    }
}
