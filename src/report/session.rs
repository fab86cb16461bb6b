//! The capture part of a report: what a session folder's manifest (or journal) says was shot,
//! whether every image still matches its recorded SHA-256, and a few single-light previews.
//!
//! Read tolerantly (records are untyped JSON, so an older or newer manifest still reports what
//! it can); problems become notes or `Avail::No` with the reason, never errors.

use super::gather::{
    Avail, JOURNAL_FILE, MANIFEST_FILE, ReportOptions, SESSION_FILE, as_f64_array, error_chain,
    read_json, value_text,
};
use super::images::{EmbeddedImage, auto_exposure, downscale, encode_png};
use serde_json::Value;
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::path::Path;

/// What a session folder says about its capture.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct CaptureSummary {
    pub dir: String,
    /// Header facts (plan, profile, camera, created, simulated, status), as text.
    pub facts: Vec<(String, String)>,
    pub shots: usize,
    pub by_kind: BTreeMap<String, usize>,
    /// Distinct turntable angles asked for, degrees, sorted.
    pub angles_deg: Vec<f64>,
    /// Largest |measured - asked| turntable angle, degrees, modulo a full turn.
    pub max_angle_error_deg: Option<f64>,
    /// Light channel -> (shots, nominal lab direction if recorded).
    pub channels: BTreeMap<i64, (usize, Option<[f64; 3]>)>,
    pub first_utc: Option<String>,
    pub last_utc: Option<String>,
    pub span_secs: Option<f64>,
    pub exposure_secs: Option<(f64, f64)>,
    pub checksums: Avail<ChecksumStatus>,
    pub thumbnails: Avail<Vec<EmbeddedImage>>,
    /// Problems met while reading (a torn journal line, a record without a field).
    pub notes: Vec<String>,
}

/// The result of re-reading every listed image.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct ChecksumStatus {
    pub checked: usize,
    pub ok: usize,
    /// One line per problem (missing file, size or hash mismatch).
    pub problems: Vec<String>,
}

/// Summarises a session folder; never fails (problems go into `notes` and `Avail::No`).
pub fn summarise_session(dir: &Path, opts: &ReportOptions) -> CaptureSummary {
    let mut s = CaptureSummary {
        dir: dir.display().to_string(),
        ..Default::default()
    };
    let (header, status, shots) = read_shots(dir, &mut s.notes);
    if let Some(h) = header.as_ref().and_then(Value::as_object) {
        for (k, v) in h {
            s.facts.push((k.clone(), value_text(v)));
        }
    }
    if let Some(st) = status {
        s.facts.push(("status".into(), st));
    }
    s.shots = shots.len();
    let mut angles: Vec<f64> = Vec::new();
    let mut times: Vec<(f64, String)> = Vec::new();
    let mut exposure: Option<(f64, f64)> = None;
    for r in &shots {
        let kind = r.get("kind").map(value_text).unwrap_or_else(|| "?".into());
        *s.by_kind.entry(kind).or_default() += 1;
        if let Some(a) = r.get("angle_deg").and_then(Value::as_f64) {
            if !angles.iter().any(|x| (x - a).abs() < 1e-9) {
                angles.push(a);
            }
            if let Some(m) = r.get("measured_angle_deg").and_then(Value::as_f64) {
                // turntable angles are equal modulo a turn (a sweep may end at 360 for 0)
                let e = (m - a).rem_euclid(360.0);
                let e = e.min(360.0 - e);
                s.max_angle_error_deg = Some(s.max_angle_error_deg.map_or(e, |x: f64| x.max(e)));
            }
        }
        if let Some(ch) = r.get("channel").and_then(Value::as_i64) {
            let entry = s.channels.entry(ch).or_insert((0, None));
            entry.0 += 1;
            if entry.1.is_none() {
                entry.1 = as_f64_array::<3>(r.get("light_dir_lab"));
            }
        }
        if let Some(t) = r.get("time_unix").and_then(Value::as_f64) {
            let utc = r
                .get("time_utc")
                .and_then(Value::as_str)
                .unwrap_or_default()
                .to_string();
            times.push((t, utc));
        }
        if let Some(e) = r.get("exposure_secs").and_then(Value::as_f64) {
            exposure = Some(exposure.map_or((e, e), |(lo, hi)| (lo.min(e), hi.max(e))));
        }
    }
    angles.sort_by(f64::total_cmp);
    s.angles_deg = angles;
    s.exposure_secs = exposure;
    times.sort_by(|a, b| a.0.total_cmp(&b.0));
    if let (Some(first), Some(last)) = (times.first(), times.last()) {
        s.first_utc = Some(first.1.clone());
        s.last_utc = Some(last.1.clone());
        s.span_secs = Some(last.0 - first.0);
    }
    if shots.is_empty() {
        s.checksums = Avail::No("the session lists no shots".into());
    } else if opts.verify_checksums {
        s.checksums = Avail::Yes(verify_checksums(dir, &shots));
    } else {
        s.checksums = Avail::No("checksum verification was turned off (--no-verify)".into());
    }
    s.thumbnails = thumbnails(dir, &shots, opts.max_thumbnails);
    s
}

/// Header, status and shot records: from `manifest.json`, else `session.json` +
/// `journal.jsonl` (a torn last line is skipped with a note).
fn read_shots(dir: &Path, notes: &mut Vec<String>) -> (Option<Value>, Option<String>, Vec<Value>) {
    match read_json(&dir.join(MANIFEST_FILE)) {
        Avail::Yes(m) => {
            let shots = m
                .get("shots")
                .and_then(Value::as_array)
                .cloned()
                .unwrap_or_default();
            let status = m.get("status").map(value_text);
            return (m.get("header").cloned(), status, shots);
        }
        Avail::No(why) => {
            if dir.join(MANIFEST_FILE).exists() {
                notes.push(why);
            }
        }
    }
    let header = match read_json(&dir.join(SESSION_FILE)) {
        Avail::Yes(h) => Some(h),
        Avail::No(why) => {
            notes.push(why);
            None
        }
    };
    let path = dir.join(JOURNAL_FILE);
    let mut shots = Vec::new();
    match std::fs::read(&path) {
        Ok(bytes) => {
            for (n, line) in bytes.split(|b| *b == b'\n').enumerate() {
                if line.iter().all(u8::is_ascii_whitespace) {
                    continue;
                }
                match serde_json::from_slice::<Value>(line) {
                    Ok(v) => shots.push(v),
                    Err(e) => notes.push(format!(
                        "{}: line {} skipped (torn or not JSON: {e})",
                        path.display(),
                        n + 1
                    )),
                }
            }
        }
        Err(e) => notes.push(format!("{}: cannot read: {e}", path.display())),
    }
    let status = Some("no manifest snapshot: read from the journal".to_string());
    (header, status, shots)
}

/// Re-reads each listed file and compares its size and SHA-256 with the record. Deliberately not
/// `capture::verify::verify_session`: that one is the strict check (`brdf-rig session verify`:
/// plan, header and journal must all parse, duplicates and unplanned shots are errors), while a
/// report must still say what it can of a partial or hand-copied folder (a manifest alone, a torn
/// journal), so it checks whatever records it found.
fn verify_checksums(dir: &Path, shots: &[Value]) -> ChecksumStatus {
    let mut st = ChecksumStatus::default();
    for r in shots {
        let id = r.get("id").map(value_text).unwrap_or_else(|| "?".into());
        let Some(file) = r.get("file").and_then(Value::as_str) else {
            st.problems
                .push(format!("shot {id}: no file in its record"));
            continue;
        };
        st.checked += 1;
        let path = dir.join(file);
        let bytes = match std::fs::read(&path) {
            Ok(b) => b,
            Err(e) => {
                st.problems
                    .push(format!("{}: cannot read: {e}", path.display()));
                continue;
            }
        };
        if let Some(n) = r.get("bytes").and_then(Value::as_u64) {
            if n != bytes.len() as u64 {
                st.problems.push(format!(
                    "{}: {} bytes, the record says {n}",
                    path.display(),
                    bytes.len()
                ));
                continue;
            }
        }
        match r.get("sha256").and_then(Value::as_str) {
            Some(want) => {
                let got = hex::encode(Sha256::digest(&bytes));
                if got.eq_ignore_ascii_case(want) {
                    st.ok += 1;
                } else {
                    st.problems.push(format!(
                        "{}: SHA-256 {got}, the record says {want}",
                        path.display()
                    ));
                }
            }
            None => st
                .problems
                .push(format!("shot {id}: no sha256 in its record")),
        }
    }
    st
}

/// Previews of the first few single-light images (auto exposure: the 99th percentile of each
/// image maps to 0.9).
fn thumbnails(dir: &Path, shots: &[Value], max: usize) -> Avail<Vec<EmbeddedImage>> {
    let light: Vec<&Value> = shots
        .iter()
        .filter(|r| r.get("kind").and_then(Value::as_str) == Some("single_light"))
        .collect();
    if light.is_empty() {
        return Avail::No("the session has no single-light shots".into());
    }
    let mut out = Vec::new();
    let mut failures = Vec::new();
    // Spread the chosen shots over the session.
    let step = light.len().div_ceil(max.max(1)).max(1);
    for r in light.iter().step_by(step).take(max) {
        let Some(file) = r.get("file").and_then(Value::as_str) else {
            continue;
        };
        let path = dir.join(file);
        let img = if file.to_ascii_lowercase().ends_with(".exr") {
            crate::imageio::read_exr(&path)
        } else {
            crate::imageio::read_linear(&path, 1.0)
        };
        match img {
            Ok(img) => {
                let small = downscale(&img, 240);
                let stops = auto_exposure(&[&small]);
                match encode_png(&small, stops) {
                    Some(e) => out.push(EmbeddedImage {
                        caption: format!(
                            "{file}: turntable {} deg, channel {}",
                            r.get("angle_deg").map(value_text).unwrap_or_default(),
                            r.get("channel").map(value_text).unwrap_or_default()
                        ),
                        ..e
                    }),
                    None => {
                        failures.push(format!("{}: could not encode a preview", path.display()))
                    }
                }
            }
            Err(e) => failures.push(error_chain(&e)),
        }
    }
    if out.is_empty() {
        Avail::No(format!(
            "no single-light image could be read: {}",
            failures.join("; ")
        ))
    } else {
        Avail::Yes(out)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn a_sweep_ending_at_360_is_not_an_angle_error() {
        let dir = tempfile::tempdir().unwrap();
        let lines = [
            r#"{"id":"a","kind":"ambient","angle_deg":0.0,"measured_angle_deg":360.0}"#,
            r#"{"id":"b","kind":"ambient","angle_deg":10.0,"measured_angle_deg":10.25}"#,
            r#"{"id":"c","kind":"ambient","angle_deg":350.0,"measured_angle_deg":-10.0}"#,
        ];
        std::fs::write(dir.path().join(JOURNAL_FILE), lines.join("\n")).unwrap();
        let opts = ReportOptions {
            verify_checksums: false,
            ..ReportOptions::default()
        };
        let s = summarise_session(dir.path(), &opts);
        assert_eq!(s.shots, 3);
        let e = s.max_angle_error_deg.unwrap();
        assert!((e - 0.25).abs() < 1e-9, "{e}");
    }
}
