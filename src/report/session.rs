//! The capture part of a report: what a session folder's manifest (or journal) says was shot,
//! whether every image still matches its recorded size and SHA-256, and a few single-light
//! previews.
//!
//! The files are read through their owner, `capture::session` (typed records, its file names,
//! its format version), and each image is checked by `capture::verify::check_record`, the one
//! check `session verify`, a resume and `calibrate` use. Unlike `session verify`, a report says
//! what it can of a partial folder: problems (a manifest of another version, a torn journal)
//! become notes or `Avail::No` with the reason, never errors.

use super::avail::{Avail, error_chain};
use super::images::{EmbeddedImage, auto_exposure, downscale, encode_png};
use super::numbers::fmt_num;
use super::options::ReportOptions;
use crate::capture::plan::ShotKind;
use crate::capture::session::{
    JOURNAL_FILE, MANIFEST_FILE, SESSION_FILE, SessionHeader, ShotRecord, current_records,
    read_header, read_journal, read_manifest,
};
use crate::capture::verify::check_record;
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
    /// Problems met while reading (a torn journal line, a manifest that could not be read).
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

/// A shot kind as the session files name it (`single_light`).
fn kind_name(k: ShotKind) -> &'static str {
    match k {
        ShotKind::Ambient => "ambient",
        ShotKind::SingleLight => "single_light",
        ShotKind::Sphere => "sphere",
        ShotKind::White => "white",
    }
}

fn header_facts(h: &SessionHeader) -> Vec<(String, String)> {
    vec![
        ("format_version".into(), h.format_version.to_string()),
        ("tool".into(), h.tool.clone()),
        ("plan_name".into(), h.plan_name.clone()),
        ("planned_shots".into(), h.planned_shots.to_string()),
        ("profile".into(), h.profile.clone()),
        ("camera_backend".into(), h.camera_backend.clone()),
        ("created_utc".into(), h.created_utc.clone()),
        ("simulated".into(), h.simulated.to_string()),
    ]
}

/// Summarises a session folder; never fails (problems go into `notes` and `Avail::No`).
pub fn summarise_session(dir: &Path, opts: &ReportOptions) -> CaptureSummary {
    let mut s = CaptureSummary {
        dir: dir.display().to_string(),
        ..Default::default()
    };
    let (header, status, shots) = read_shots(dir, &mut s.notes);
    if let Some(h) = &header {
        s.facts = header_facts(h);
    }
    if let Some(st) = status {
        s.facts.push(("status".into(), st));
    }
    s.shots = shots.len();
    let mut angles: Vec<f64> = Vec::new();
    let mut times: Vec<(f64, String)> = Vec::new();
    let mut exposure: Option<(f64, f64)> = None;
    for r in &shots {
        *s.by_kind.entry(kind_name(r.kind).to_string()).or_default() += 1;
        let a = r.angle_deg;
        if !angles.iter().any(|x| (x - a).abs() < 1e-9) {
            angles.push(a);
        }
        // turntable angles are equal modulo a turn (a sweep may end at 360 for 0)
        let e = (r.measured_angle_deg - a).rem_euclid(360.0);
        let e = e.min(360.0 - e);
        s.max_angle_error_deg = Some(s.max_angle_error_deg.map_or(e, |x: f64| x.max(e)));
        if let Some(ch) = r.channel {
            let entry = s.channels.entry(ch as i64).or_insert((0, None));
            entry.0 += 1;
            if entry.1.is_none() {
                entry.1 = r.light_dir_lab;
            }
        }
        times.push((r.time_unix, r.time_utc.clone()));
        let e = r.exposure_secs;
        exposure = Some(exposure.map_or((e, e), |(lo, hi)| (lo.min(e), hi.max(e))));
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

/// Header, status and the shot records that count: from `manifest.json`, else `session.json` +
/// `journal.jsonl` (a torn last line is left out, a re-taken shot counts once).
fn read_shots(
    dir: &Path,
    notes: &mut Vec<String>,
) -> (Option<SessionHeader>, Option<String>, Vec<ShotRecord>) {
    match read_manifest(dir) {
        Ok(m) => return (Some(m.header), Some(m.status), m.shots),
        Err(e) => {
            if dir.join(MANIFEST_FILE).exists() {
                notes.push(error_chain(&e));
            }
        }
    }
    let header = match read_header(dir) {
        Ok(h) => Some(h),
        // A header that exists but is of another version (or unreadable): its journal's records
        // are not guessed at.
        Err(e) if dir.join(SESSION_FILE).exists() => {
            notes.push(error_chain(&e));
            return (None, None, Vec::new());
        }
        Err(e) => {
            notes.push(error_chain(&e));
            None
        }
    };
    let shots = match read_journal(&dir.join(JOURNAL_FILE)) {
        Ok((records, _)) => current_records(records).0,
        Err(e) => {
            notes.push(error_chain(&e));
            Vec::new()
        }
    };
    let status = Some("no manifest snapshot: read from the journal".to_string());
    (header, status, shots)
}

/// Checks each listed image against its record's size and SHA-256 (`check_record`).
fn verify_checksums(dir: &Path, shots: &[ShotRecord]) -> ChecksumStatus {
    let mut st = ChecksumStatus::default();
    for r in shots {
        st.checked += 1;
        match check_record(dir, r).1 {
            None => st.ok += 1,
            Some(problem) => st.problems.push(problem.to_string()),
        }
    }
    st
}

/// Previews of the first few single-light images (auto exposure: the 99th percentile of each
/// image maps to 0.9).
fn thumbnails(dir: &Path, shots: &[ShotRecord], max: usize) -> Avail<Vec<EmbeddedImage>> {
    let light: Vec<&ShotRecord> = shots
        .iter()
        .filter(|r| r.kind == ShotKind::SingleLight)
        .collect();
    if light.is_empty() {
        return Avail::No("the session has no single-light shots".into());
    }
    let mut out = Vec::new();
    let mut failures = Vec::new();
    // Spread the chosen shots over the session.
    let step = light.len().div_ceil(max.max(1)).max(1);
    for r in light.iter().step_by(step).take(max) {
        let file = &r.file;
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
                            fmt_num(r.angle_deg),
                            r.channel.map(|c| c.to_string()).unwrap_or_default()
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

    fn record(id: &str, angle_deg: f64, measured_angle_deg: f64) -> ShotRecord {
        ShotRecord {
            id: id.into(),
            index: 0,
            kind: ShotKind::Ambient,
            view: Some(0),
            angle_deg,
            measured_angle_deg,
            channel: None,
            level: 0.0,
            light_dir_lab: None,
            exposure_secs: 0.01,
            gain: 1.0,
            saturation: 1.0,
            device: "sim".into(),
            file: format!("ambient/{id}.exr"),
            width: 4,
            height: 4,
            bytes: 0,
            sha256: String::new(),
            time_unix: 0.0,
            time_utc: String::new(),
            retake: None,
        }
    }

    #[test]
    fn a_sweep_ending_at_360_is_not_an_angle_error() {
        let dir = tempfile::tempdir().unwrap();
        let lines: Vec<String> = [
            record("a", 0.0, 360.0),
            record("b", 10.0, 10.25),
            record("c", 350.0, -10.0),
        ]
        .iter()
        .map(|r| serde_json::to_string(r).unwrap() + "\n")
        .collect();
        std::fs::write(dir.path().join(JOURNAL_FILE), lines.concat()).unwrap();
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
