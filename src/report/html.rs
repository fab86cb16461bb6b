//! The HTML report: one self-contained page (no network: SVG inline, images as `data:` URIs)
//! about a capture session folder and/or a reconstruction output folder.
//!
//! Two steps: [`gather`] reads what the folder holds into [`ReportData`], tolerantly (a piece
//! that is missing or unreadable becomes [`Avail::No`] with the reason, never an error), and
//! [`render_html`] turns that into the page (pure; every string from the data is escaped).
//!
//! What is read (all optional except that the folder must be one of the two kinds):
//! - session folder: `manifest.json` (else `journal.jsonl`), `session.json`, the images it lists
//!   (checksums, a few single-light thumbnails), calibration JSON (`calibration.json`,
//!   `calib/*.json`).
//! - reconstruction output: `brdf.binary` (MERL table) and `report.json`, read as untyped JSON so
//!   any producer's fields show; the keys interpreted are listed in `docs/report.md`
//!   (`trials`, `chosen_trial`, `components`, `timings`, `warnings`, `calibration`, `truth`,
//!   `baselines`, `session`), plus any `*.png` renders beside them.

use super::charts::{ChartSpec, Goal, ScatterPoint, Series, line_chart, scatter_pareto};
use super::inplane::{self, InPlaneCurve, InPlaneSettings};
use crate::brdf::Brdf;
use crate::brdf::merl::MerlTable;
use crate::brdf::nbrdf::Nbrdf;
use crate::geometry::camera::{Intrinsics, Pose};
use crate::render::image::LinearImage;
use crate::render::light::DirectionalLight;
use crate::render::sphere::{Sphere, render_sphere};
use base64::Engine;
use nalgebra::{Point3, Vector3};
use serde_json::Value;
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The reconstruction's MERL table, as the reconstruction step names it.
pub const BRDF_FILE: &str = "brdf.binary";
/// The reconstruction's JSON report.
pub const REPORT_JSON: &str = "report.json";
/// The session snapshot written by the capture step.
pub const MANIFEST_FILE: &str = "manifest.json";
/// The session journal (one shot record per line), used when there is no snapshot.
pub const JOURNAL_FILE: &str = "journal.jsonl";
/// What the session is (header), written once by the capture step.
pub const SESSION_FILE: &str = "session.json";

/// A piece of the report, or why it is missing.
#[derive(Clone, Debug, PartialEq)]
pub enum Avail<T> {
    Yes(T),
    No(String),
}

impl<T> Default for Avail<T> {
    fn default() -> Self {
        Avail::No("not looked for".into())
    }
}

impl<T> Avail<T> {
    pub fn is_available(&self) -> bool {
        matches!(self, Avail::Yes(_))
    }

    pub fn as_option(&self) -> Option<&T> {
        match self {
            Avail::Yes(t) => Some(t),
            Avail::No(_) => None,
        }
    }
}

/// An image embedded in the page.
#[derive(Clone, Debug, PartialEq)]
pub struct EmbeddedImage {
    pub caption: String,
    /// PNG bytes.
    pub png: Vec<u8>,
    pub width: u32,
    pub height: u32,
}

/// How the report is made.
#[derive(Clone, Debug, PartialEq)]
pub struct ReportOptions {
    pub inplane: InPlaneSettings,
    /// In-plane plots on a logarithmic f_r axis (specular peaks span decades).
    pub log_y: bool,
    /// Further BRDF files to compare in the in-plane plot: (label, path to `.binary` or `.f32`).
    pub compare: Vec<(String, PathBuf)>,
    /// Re-read every session image and check its SHA-256 against the manifest.
    pub verify_checksums: bool,
    /// At most this many single-light thumbnails from a session.
    pub max_thumbnails: usize,
    /// Width and height of each sphere render, pixels.
    pub sphere_pixels: usize,
}

impl Default for ReportOptions {
    fn default() -> Self {
        Self {
            inplane: InPlaneSettings::default(),
            log_y: true,
            compare: Vec::new(),
            verify_checksums: true,
            max_thumbnails: 6,
            sphere_pixels: 160,
        }
    }
}

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
    /// Largest |measured - asked| turntable angle, degrees.
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

/// One calibration record found (a file or a `report.json` entry).
#[derive(Clone, Debug, PartialEq)]
pub struct CalibrationEntry {
    pub source: String,
    pub light_dir: Option<[f64; 3]>,
    pub uncertainty_deg: Option<f64>,
    pub irradiance: Option<Vec<f64>>,
    pub irradiance_std_error: Option<Vec<f64>>,
    /// Everything else, as key/value text.
    pub other: Vec<(String, String)>,
}

/// The in-plane plot of the result (and of whatever it is compared with).
#[derive(Clone, Debug, PartialEq)]
pub struct BrdfSection {
    pub file: String,
    pub description: String,
    /// Labels of the curves, in chart order.
    pub labels: Vec<String>,
    /// One SVG chart per channel (red, green, blue).
    pub charts: Vec<String>,
    /// Peak of each curve in each channel (view angle, degrees).
    pub peaks: Vec<(String, [Option<f64>; 3])>,
    /// Comparisons that could not be loaded, with why.
    pub missing: Vec<String>,
    /// True when any curve is a neural MERL fit (an approximation, not measured data).
    pub uses_neural_fit: bool,
}

/// One reconstruction trial from `report.json`.
#[derive(Clone, Debug, PartialEq)]
pub struct TrialRow {
    pub index: i64,
    pub similarity: Option<f64>,
    /// Error against a ground truth, when the producer knew one (simulations).
    pub error: Option<f64>,
    /// Other scalar fields, as text.
    pub other: Vec<(String, String)>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct TrialsSection {
    pub rows: Vec<TrialRow>,
    pub chosen: Option<i64>,
    /// Similarity by trial (and similarity against error when errors are known).
    pub charts: Vec<String>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct ComponentsSection {
    pub k: Option<i64>,
    /// Validation curve: (k, error).
    pub curve: Vec<(f64, f64)>,
    pub chart: Option<String>,
    pub other: Vec<(String, String)>,
}

/// Everything the page shows.
#[derive(Clone, Debug, PartialEq)]
pub struct ReportData {
    pub title: String,
    pub dir: String,
    /// "session folder", "reconstruction output", or both.
    pub kinds: Vec<String>,
    pub capture: Avail<CaptureSummary>,
    pub calibration: Avail<Vec<CalibrationEntry>>,
    pub brdf: Avail<BrdfSection>,
    pub spheres: Avail<Vec<EmbeddedImage>>,
    pub renders: Avail<Vec<EmbeddedImage>>,
    pub trials: Avail<TrialsSection>,
    pub components: Avail<ComponentsSection>,
    pub timing: Avail<Vec<(String, f64)>>,
    pub warnings: Vec<String>,
    /// `report.json` keys not shown elsewhere, as key and pretty JSON.
    pub other_facts: Vec<(String, String)>,
}

/// Reads what `dir` holds. Fails only when `dir` cannot be listed or is neither a session folder
/// (`manifest.json`, `journal.jsonl` or `session.json`) nor a reconstruction output
/// (`brdf.binary` or `report.json`, here or in one subfolder).
pub fn gather(dir: &Path, opts: &ReportOptions) -> Result<ReportData, super::ReportError> {
    let meta = std::fs::metadata(dir).map_err(|source| super::ReportError::ReadDir {
        dir: dir.to_path_buf(),
        source,
    })?;
    if !meta.is_dir() {
        return Err(super::ReportError::NotADir {
            dir: dir.to_path_buf(),
        });
    }
    let is_session = [MANIFEST_FILE, JOURNAL_FILE, SESSION_FILE]
        .iter()
        .any(|f| dir.join(f).is_file());
    let recon_dir = find_recon_dir(dir)?;
    if !is_session && recon_dir.is_none() {
        return Err(super::ReportError::NotAReportDir {
            dir: dir.to_path_buf(),
        });
    }
    let mut warnings = Vec::new();
    let mut kinds = Vec::new();
    if is_session {
        kinds.push("session folder".to_string());
    }

    // report.json, untyped.
    let report: Avail<Value> = match &recon_dir {
        None => Avail::No("no reconstruction output in this folder".into()),
        Some(r) => {
            kinds.push(if r == dir {
                "reconstruction output".to_string()
            } else {
                format!("reconstruction output in {}", r.display())
            });
            read_json(&r.join(REPORT_JSON))
        }
    };
    if let Avail::No(why) = &report {
        if recon_dir.is_some() {
            warnings.push(format!("report.json: {why}"));
        }
    }
    let rj = report.as_option();

    // Capture: this folder, or the session report.json points to.
    let session_dir = if is_session {
        Some(dir.to_path_buf())
    } else {
        rj.and_then(|v| v.get("session"))
            .and_then(Value::as_str)
            .map(|s| resolve(recon_dir.as_deref().unwrap_or(dir), s))
    };
    let capture = match &session_dir {
        Some(s) if s.is_dir() => Avail::Yes(summarise_session(s, opts)),
        Some(s) => Avail::No(format!(
            "report.json names the session {}, which is not a folder here",
            s.display()
        )),
        None => Avail::No(
            "this is a reconstruction output without a session folder (report.json has no \
             \"session\" path)"
                .into(),
        ),
    };

    let calibration = gather_calibration(session_dir.as_deref(), rj);

    // The result BRDF, the in-plane plot and the spheres.
    let brdf_path = recon_dir.as_ref().map(|r| r.join(BRDF_FILE));
    let table: Avail<MerlTable> = match &brdf_path {
        None => Avail::No("no brdf.binary: the folder holds no reconstruction".into()),
        Some(p) if !p.is_file() => Avail::No(format!("{} does not exist", p.display())),
        Some(p) => match MerlTable::read(p) {
            Ok(t) => Avail::Yes(t),
            Err(e) => Avail::No(error_chain(&e)),
        },
    };
    let brdf = match (&table, &brdf_path) {
        (Avail::Yes(t), Some(p)) => {
            let mut compare = comparisons_from_report(rj, recon_dir.as_deref().unwrap_or(dir));
            compare.extend(opts.compare.iter().cloned());
            brdf_section(t, p, &compare, opts)
        }
        (Avail::No(why), _) => Avail::No(why.clone()),
        (_, None) => Avail::No("no brdf.binary".into()),
    };
    let spheres = match &table {
        Avail::Yes(t) => sphere_renders(t, opts.sphere_pixels),
        Avail::No(why) => Avail::No(why.clone()),
    };
    let renders = match &recon_dir {
        Some(r) => png_files(r),
        None => Avail::No("no reconstruction output folder".into()),
    };

    let (trials, components, timing, mut other_facts) = match rj {
        Some(v) => (
            trials_section(v),
            components_section(v),
            timing_section(v),
            other_facts(v),
        ),
        None => {
            let why = match &report {
                Avail::No(w) => format!("report.json: {w}"),
                Avail::Yes(_) => String::new(),
            };
            (
                Avail::No(why.clone()),
                Avail::No(why.clone()),
                Avail::No(why),
                Vec::new(),
            )
        }
    };
    if let Some(v) = rj {
        warnings.extend(strings_at(v, "warnings"));
    }
    if let Avail::Yes(c) = &capture {
        warnings.extend(c.notes.iter().cloned());
    }
    other_facts.sort();
    let title = format!(
        "brdf-rig report: {}",
        dir.file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| dir.display().to_string())
    );
    Ok(ReportData {
        title,
        dir: dir.display().to_string(),
        kinds,
        capture,
        calibration,
        brdf,
        spheres,
        renders,
        trials,
        components,
        timing,
        warnings,
        other_facts,
    })
}

/// `dir` itself if it holds `brdf.binary` or `report.json`, else the first subfolder (by name)
/// that does.
fn find_recon_dir(dir: &Path) -> Result<Option<PathBuf>, super::ReportError> {
    let holds = |d: &Path| d.join(BRDF_FILE).is_file() || d.join(REPORT_JSON).is_file();
    if holds(dir) {
        return Ok(Some(dir.to_path_buf()));
    }
    let entries = std::fs::read_dir(dir).map_err(|source| super::ReportError::ReadDir {
        dir: dir.to_path_buf(),
        source,
    })?;
    let mut subs: Vec<PathBuf> = entries
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.is_dir() && holds(p))
        .collect();
    subs.sort();
    Ok(subs.into_iter().next())
}

fn resolve(base: &Path, s: &str) -> PathBuf {
    let p = PathBuf::from(s);
    if p.is_absolute() { p } else { base.join(p) }
}

fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut src = e.source();
    while let Some(c) = src {
        let _ = write!(s, ": {c}");
        src = c.source();
    }
    s
}

fn read_json(path: &Path) -> Avail<Value> {
    match std::fs::read(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            Avail::No(format!("{} does not exist", path.display()))
        }
        Err(e) => Avail::No(format!("{}: cannot read: {e}", path.display())),
        Ok(bytes) => match serde_json::from_slice(&bytes) {
            Ok(v) => Avail::Yes(v),
            Err(e) => Avail::No(format!("{}: not valid JSON: {e}", path.display())),
        },
    }
}

fn as_f64_array<const N: usize>(v: Option<&Value>) -> Option<[f64; N]> {
    let a = v?.as_array()?;
    if a.len() != N {
        return None;
    }
    let mut out = [0.0; N];
    for (o, x) in out.iter_mut().zip(a) {
        *o = x.as_f64()?;
    }
    Some(out)
}

fn as_f64_vec(v: Option<&Value>) -> Option<Vec<f64>> {
    match v? {
        Value::Number(n) => n.as_f64().map(|x| vec![x]),
        Value::Array(a) => a.iter().map(Value::as_f64).collect(),
        _ => None,
    }
}

/// A JSON value as short text (strings without quotes).
fn value_text(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        Value::Number(n) => match n.as_f64() {
            Some(x) if n.is_f64() => fmt_num(x),
            _ => n.to_string(),
        },
        other => other.to_string(),
    }
}

/// Numbers with 4 significant digits, scientific when very large or small.
pub fn fmt_num(x: f64) -> String {
    if !x.is_finite() {
        return x.to_string();
    }
    let a = x.abs();
    if a != 0.0 && !(1e-3..1e6).contains(&a) {
        return format!("{x:.3e}");
    }
    let digits = if a == 0.0 {
        0
    } else {
        (3 - a.log10().floor() as i32).clamp(0, 6) as usize
    };
    let s = format!("{x:.digits$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

fn strings_at(v: &Value, key: &str) -> Vec<String> {
    match v.get(key) {
        Some(Value::Array(a)) => a.iter().map(value_text).collect(),
        Some(Value::Null) | None => Vec::new(),
        Some(other) => vec![value_text(other)],
    }
}

// ---------------------------------------------------------------------------------------------
// Capture

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
                let e = (m - a).abs();
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

/// Re-reads each listed file and compares its size and SHA-256 with the record.
// TODO(capture): use `capture::verify` once the capture module is in main.
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

/// Box-filter downscale so the width is at most `max_width` (integer factor).
fn downscale(img: &LinearImage, max_width: usize) -> LinearImage {
    let f = img.width().div_ceil(max_width.max(1)).max(1);
    if f == 1 {
        return img.clone();
    }
    let (w, h) = (img.width() / f, img.height() / f);
    let mut out = LinearImage::new(w.max(1), h.max(1));
    for y in 0..h {
        for x in 0..w {
            let mut acc = [0.0f32; 3];
            for dy in 0..f {
                for dx in 0..f {
                    let p = img.get(x * f + dx, y * f + dy);
                    for c in 0..3 {
                        acc[c] += p[c];
                    }
                }
            }
            let n = (f * f) as f32;
            out.set(x, y, acc.map(|a| a / n));
        }
    }
    out
}

/// Exposure (stops) mapping the 99th percentile of the largest channel over the non-black
/// pixels of all images to 0.9; 0 when every pixel is black.
fn auto_exposure(imgs: &[&LinearImage]) -> f32 {
    let mut v: Vec<f32> = imgs
        .iter()
        .flat_map(|i| i.data().chunks_exact(3).map(|p| p[0].max(p[1]).max(p[2])))
        .filter(|x| x.is_finite() && *x > 0.0)
        .collect();
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f32::total_cmp);
    let p = v[((v.len() - 1) as f64 * 0.99) as usize];
    (0.9 / p).log2()
}

/// An 8-bit sRGB PNG of `img * 2^stops`.
fn encode_png(img: &LinearImage, stops: f32) -> Option<EmbeddedImage> {
    let bytes = crate::imageio::preview_srgb8(img, stops);
    let (w, h) = (
        u32::try_from(img.width()).ok()?,
        u32::try_from(img.height()).ok()?,
    );
    let mut png = Vec::new();
    image::ImageEncoder::write_image(
        image::codecs::png::PngEncoder::new(&mut png),
        &bytes,
        w,
        h,
        image::ExtendedColorType::Rgb8,
    )
    .ok()?;
    Some(EmbeddedImage {
        caption: String::new(),
        png,
        width: w,
        height: h,
    })
}

// ---------------------------------------------------------------------------------------------
// Calibration

fn calibration_entry(source: String, v: &Value) -> CalibrationEntry {
    let light_dir = [
        "light_dir_camera",
        "light_dir",
        "direction",
        "light_dir_lab",
    ]
    .iter()
    .find_map(|k| as_f64_array::<3>(v.get(*k)));
    let uncertainty_deg = v.get("uncertainty_deg").and_then(Value::as_f64);
    let irradiance = as_f64_vec(v.get("irradiance"));
    let irradiance_std_error = as_f64_vec(v.get("irradiance_std_error"));
    let shown = [
        "light_dir_camera",
        "light_dir",
        "direction",
        "light_dir_lab",
        "uncertainty_deg",
        "irradiance",
        "irradiance_std_error",
    ];
    let other = v
        .as_object()
        .map(|o| {
            o.iter()
                .filter(|(k, _)| !shown.contains(&k.as_str()))
                .map(|(k, v)| (k.clone(), short_json(v)))
                .collect()
        })
        .unwrap_or_default();
    CalibrationEntry {
        source,
        light_dir,
        uncertainty_deg,
        irradiance,
        irradiance_std_error,
        other,
    }
}

/// JSON as compact text, cut at 300 characters.
fn short_json(v: &Value) -> String {
    let s = value_text(v);
    if s.chars().count() > 300 {
        let cut: String = s.chars().take(300).collect();
        format!("{cut}...")
    } else {
        s
    }
}

fn gather_calibration(session: Option<&Path>, rj: Option<&Value>) -> Avail<Vec<CalibrationEntry>> {
    let mut out = Vec::new();
    let mut notes = Vec::new();
    if let Some(c) = rj.and_then(|v| v.get("calibration")) {
        match c {
            Value::Array(a) => {
                for (i, x) in a.iter().enumerate() {
                    out.push(calibration_entry(
                        format!("report.json calibration[{i}]"),
                        x,
                    ));
                }
            }
            other => out.push(calibration_entry("report.json calibration".into(), other)),
        }
    }
    if let Some(dir) = session {
        let mut files = vec![dir.join("calibration.json")];
        if let Ok(rd) = std::fs::read_dir(dir.join("calib")) {
            let mut js: Vec<PathBuf> = rd
                .filter_map(Result::ok)
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|e| e == "json"))
                .collect();
            js.sort();
            files.extend(js);
        }
        for f in files.iter().filter(|f| f.is_file()) {
            match read_json(f) {
                Avail::Yes(Value::Array(a)) => {
                    for (i, x) in a.iter().enumerate() {
                        out.push(calibration_entry(format!("{}[{i}]", f.display()), x));
                    }
                }
                Avail::Yes(v) => out.push(calibration_entry(f.display().to_string(), &v)),
                Avail::No(why) => notes.push(why),
            }
        }
    }
    if out.is_empty() {
        let mut why = "no calibration found (looked for report.json \"calibration\", \
                       calibration.json and calib/*.json in the session)"
            .to_string();
        if !notes.is_empty() {
            let _ = write!(why, "; {}", notes.join("; "));
        }
        Avail::No(why)
    } else {
        Avail::Yes(out)
    }
}

// ---------------------------------------------------------------------------------------------
// The BRDF

/// Loads a BRDF file: `.f32` is a neural MERL fit, anything else a MERL table.
pub fn load_brdf(path: &Path) -> Result<Box<dyn Brdf>, String> {
    if path.extension().is_some_and(|e| e == "f32") {
        Nbrdf::load(path)
            .map(|n| Box::new(n) as Box<dyn Brdf>)
            .map_err(|e| error_chain(&e))
    } else {
        MerlTable::read(path)
            .map(|t| Box::new(t) as Box<dyn Brdf>)
            .map_err(|e| error_chain(&e))
    }
}

fn is_neural(path: &Path) -> bool {
    path.extension().is_some_and(|e| e == "f32")
}

/// `truth` and `baselines` of report.json: a path string, or an object with `path` (or `file`)
/// and an optional `label`.
fn comparisons_from_report(rj: Option<&Value>, base: &Path) -> Vec<(String, PathBuf)> {
    let Some(v) = rj else {
        return Vec::new();
    };
    let one = |x: &Value, default: &str| -> Option<(String, PathBuf)> {
        match x {
            Value::String(s) => Some((default.to_string(), resolve(base, s))),
            Value::Object(o) => {
                let p = o
                    .get("path")
                    .or_else(|| o.get("file"))
                    .and_then(Value::as_str)?;
                let label = o
                    .get("label")
                    .or_else(|| o.get("name"))
                    .map(value_text)
                    .unwrap_or_else(|| default.to_string());
                Some((label, resolve(base, p)))
            }
            _ => None,
        }
    };
    let mut out = Vec::new();
    if let Some(t) = v.get("truth").and_then(|t| one(t, "truth")) {
        out.push(t);
    }
    if let Some(Value::Array(a)) = v.get("baselines") {
        for (i, b) in a.iter().enumerate() {
            if let Some(x) = one(b, &format!("baseline {}", i + 1)) {
                out.push(x);
            }
        }
    }
    out
}

fn brdf_section(
    table: &MerlTable,
    path: &Path,
    compare: &[(String, PathBuf)],
    opts: &ReportOptions,
) -> Avail<BrdfSection> {
    let mut loaded: Vec<(String, Box<dyn Brdf>)> = Vec::new();
    let mut missing = Vec::new();
    let mut uses_neural_fit = false;
    for (label, p) in compare {
        match load_brdf(p) {
            Ok(b) => {
                let label = if is_neural(p) {
                    uses_neural_fit = true;
                    format!("{label} (neural MERL fit, not measured)")
                } else {
                    label.clone()
                };
                loaded.push((label, b));
            }
            Err(e) => missing.push(format!("{label}: {e}")),
        }
    }
    let mut brdfs: Vec<(&str, &dyn Brdf)> = vec![("reconstruction", table)];
    brdfs.extend(loaded.iter().map(|(l, b)| (l.as_str(), b.as_ref())));
    let curves: Vec<InPlaneCurve> = inplane::compare(&brdfs, &opts.inplane);
    let mut charts = Vec::new();
    for c in 0..3 {
        match inplane::channel_chart(&curves, c, &opts.inplane, opts.log_y) {
            Ok(svg) => charts.push(svg),
            Err(e) => return Avail::No(format!("the in-plane chart could not be drawn: {e}")),
        }
    }
    let peaks = curves
        .iter()
        .map(|k| {
            (
                k.label.clone(),
                [
                    k.peak_alpha_deg(0),
                    k.peak_alpha_deg(1),
                    k.peak_alpha_deg(2),
                ],
            )
        })
        .collect();
    Avail::Yes(BrdfSection {
        file: path.display().to_string(),
        description: inplane::describe(&opts.inplane),
        labels: curves.iter().map(|k| k.label.clone()).collect(),
        charts,
        peaks,
        missing,
        uses_neural_fit,
    })
}

/// The lights of the sphere previews: angle between light and view (degrees), light towards
/// the upper left of the image. With one light fixed relative to the camera this angle is
/// 2 theta_d for every pixel, as on the rig.
pub const SPHERE_LIGHT_ANGLES_DEG: [f64; 3] = [0.0, 45.0, 90.0];

/// The result on a sphere under the lights of [`SPHERE_LIGHT_ANGLES_DEG`], one exposure for
/// all (so their brightness compares).
pub fn sphere_renders(brdf: &dyn Brdf, pixels: usize) -> Avail<Vec<EmbeddedImage>> {
    let n = pixels.clamp(16, 1024);
    let sphere = Sphere {
        centre: Point3::origin(),
        radius: 1.0,
    };
    let eye = Point3::new(0.0, 0.0, 4.0);
    let pose = Pose::look_at(eye, sphere.centre, Vector3::y());
    // The sphere's outline (half angle asin(1/4)) fills 80 % of the frame.
    let half = (0.25f64).asin().tan();
    let f = 0.4 * n as f64 / half;
    let k = Intrinsics::pinhole(n, n, f, f, n as f64 / 2.0, n as f64 / 2.0);
    let irradiance = [std::f64::consts::PI; 3];
    let mut imgs = Vec::new();
    for a in SPHERE_LIGHT_ANGLES_DEG {
        let r = a.to_radians();
        // Rotate the view direction (+z towards the camera) towards the upper left (-x, +y).
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let to_light = Vector3::new(-s * r.sin(), s * r.sin(), r.cos());
        let Some(light) = DirectionalLight::new(to_light, irradiance) else {
            return Avail::No("internal: a sphere light direction is degenerate".into());
        };
        imgs.push((a, render_sphere(&sphere, brdf, &light, &k, &pose, [0.0; 3])));
    }
    let refs: Vec<&LinearImage> = imgs.iter().map(|(_, i)| i).collect();
    let stops = auto_exposure(&refs);
    let mut out = Vec::new();
    for (a, img) in &imgs {
        match encode_png(img, stops) {
            Some(e) => out.push(EmbeddedImage {
                caption: format!(
                    "light {a:.0} deg from the view (theta_d = {:.1} deg), irradiance pi; \
                     exposure {stops:+.1} stops",
                    a / 2.0
                ),
                ..e
            }),
            None => return Avail::No("a sphere render could not be encoded as PNG".into()),
        }
    }
    Avail::Yes(out)
}

/// The `*.png` files of the reconstruction output (its own renders), embedded as they are.
fn png_files(dir: &Path) -> Avail<Vec<EmbeddedImage>> {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return Avail::No(format!("{}: cannot list the folder", dir.display()));
    };
    let mut files: Vec<PathBuf> = rd
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")))
        .collect();
    files.sort();
    if files.is_empty() {
        return Avail::No("the reconstruction output has no PNG renders".into());
    }
    let mut out = Vec::new();
    let mut bad = Vec::new();
    for p in files {
        let name = p
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let dims = std::fs::read(&p).map_err(|e| e.to_string()).and_then(|b| {
            image::load_from_memory_with_format(&b, image::ImageFormat::Png)
                .map(|i| (b, i.width(), i.height()))
                .map_err(|e| e.to_string())
        });
        match dims {
            Ok((png, width, height)) => out.push(EmbeddedImage {
                caption: name,
                png,
                width,
                height,
            }),
            Err(e) => bad.push(format!("{}: {e}", p.display())),
        }
    }
    if out.is_empty() {
        Avail::No(format!("no PNG could be decoded: {}", bad.join("; ")))
    } else {
        Avail::Yes(out)
    }
}

// ---------------------------------------------------------------------------------------------
// report.json sections

fn trials_section(v: &Value) -> Avail<TrialsSection> {
    let Some(arr) = v.get("trials").and_then(Value::as_array) else {
        return Avail::No("report.json has no \"trials\" list".into());
    };
    let rows: Vec<TrialRow> = arr
        .iter()
        .enumerate()
        .map(|(i, t)| match t {
            Value::Number(n) => TrialRow {
                index: i as i64,
                similarity: n.as_f64(),
                error: None,
                other: Vec::new(),
            },
            _ => TrialRow {
                index: t.get("index").and_then(Value::as_i64).unwrap_or(i as i64),
                similarity: t.get("similarity").and_then(Value::as_f64),
                error: ["error", "relative_error", "error_vs_truth"]
                    .iter()
                    .find_map(|k| t.get(*k).and_then(Value::as_f64)),
                other: t
                    .as_object()
                    .map(|o| {
                        o.iter()
                            .filter(|(k, x)| {
                                ![
                                    "index",
                                    "similarity",
                                    "error",
                                    "relative_error",
                                    "error_vs_truth",
                                ]
                                .contains(&k.as_str())
                                    && !x.is_array()
                                    && !x.is_object()
                            })
                            .map(|(k, x)| (k.clone(), value_text(x)))
                            .collect()
                    })
                    .unwrap_or_default(),
            },
        })
        .collect();
    let chosen = ["chosen_trial", "chosen", "best_trial"]
        .iter()
        .find_map(|k| v.get(*k).and_then(Value::as_i64));
    let mut charts = Vec::new();
    let sims: Vec<(f64, f64)> = rows
        .iter()
        .filter_map(|r| r.similarity.map(|s| (r.index as f64, s)))
        .collect();
    if !sims.is_empty() {
        let mut series = vec![Series::new("similarity (eq. 3)", sims.clone())];
        if let Some(c) = chosen {
            let pt: Vec<(f64, f64)> = sims.iter().copied().filter(|p| p.0 == c as f64).collect();
            series.push(Series::new("chosen", pt).with_color([214, 39, 40]));
        }
        let spec =
            ChartSpec::new("Cosine similarity of each trial", "trial", "similarity").size(560, 320);
        if let Ok(svg) = line_chart(&series, &spec) {
            charts.push(svg);
        }
    }
    let pairs: Vec<ScatterPoint> = rows
        .iter()
        .filter_map(|r| {
            Some(ScatterPoint::new(
                format!("#{}", r.index),
                r.similarity?,
                r.error?,
            ))
        })
        .collect();
    if pairs.len() >= 2 {
        let spec = ChartSpec::new(
            "Similarity against error (paper Fig. 6)",
            "similarity",
            "error vs truth",
        )
        .size(560, 360);
        if let Ok(svg) = scatter_pareto(&pairs, &spec, Goal::Maximise, Goal::Minimise) {
            charts.push(svg);
        }
    }
    Avail::Yes(TrialsSection {
        rows,
        chosen,
        charts,
    })
}

fn components_section(v: &Value) -> Avail<ComponentsSection> {
    let c = v.get("components");
    let k = c
        .and_then(|c| c.get("k").and_then(Value::as_i64).or_else(|| c.as_i64()))
        .or_else(|| v.get("k").and_then(Value::as_i64));
    if c.is_none() && k.is_none() {
        return Avail::No("report.json has neither \"components\" nor \"k\"".into());
    }
    let curve: Vec<(f64, f64)> = c
        .and_then(|c| c.get("curve"))
        .and_then(Value::as_array)
        .map(|a| {
            a.iter()
                .filter_map(|p| {
                    Some((
                        p.get("k")?.as_f64()?,
                        p.get("error").and_then(Value::as_f64)?,
                    ))
                })
                .collect()
        })
        .unwrap_or_default();
    let chart = (!curve.is_empty())
        .then(|| {
            let spec = ChartSpec::new(
                "Held-out error against the number of components k",
                "k",
                "held-out error",
            )
            .size(560, 320);
            line_chart(&[Series::new("validation", curve.clone())], &spec).ok()
        })
        .flatten();
    let other = c
        .and_then(Value::as_object)
        .map(|o| {
            o.iter()
                .filter(|(k, _)| k.as_str() != "k" && k.as_str() != "curve")
                .map(|(k, x)| (k.clone(), short_json(x)))
                .collect()
        })
        .unwrap_or_default();
    Avail::Yes(ComponentsSection {
        k,
        curve,
        chart,
        other,
    })
}

fn timing_section(v: &Value) -> Avail<Vec<(String, f64)>> {
    let Some(t) = ["timings", "timing", "timings_secs", "stage_secs"]
        .iter()
        .find_map(|k| v.get(*k))
    else {
        return Avail::No("report.json has no \"timings\"".into());
    };
    let mut out = Vec::new();
    match t {
        Value::Object(o) => {
            for (k, x) in o {
                if let Some(s) = x.as_f64() {
                    out.push((k.clone(), s));
                }
            }
        }
        Value::Array(a) => {
            for x in a {
                match x {
                    Value::Array(p) if p.len() == 2 => {
                        if let (Some(n), Some(s)) = (p[0].as_str(), p[1].as_f64()) {
                            out.push((n.to_string(), s));
                        }
                    }
                    Value::Object(o) => {
                        let name = ["stage", "name", "step"]
                            .iter()
                            .find_map(|k| o.get(*k).and_then(Value::as_str));
                        let secs = ["secs", "seconds", "time_secs", "duration_secs"]
                            .iter()
                            .find_map(|k| o.get(*k).and_then(Value::as_f64));
                        if let (Some(n), Some(s)) = (name, secs) {
                            out.push((n.to_string(), s));
                        }
                    }
                    _ => {}
                }
            }
        }
        _ => {}
    }
    if out.is_empty() {
        Avail::No("report.json \"timings\" has no (stage, seconds) entries".into())
    } else {
        Avail::Yes(out)
    }
}

const INTERPRETED: [&str; 17] = [
    "trials",
    "chosen_trial",
    "chosen",
    "best_trial",
    "components",
    "k",
    "timings",
    "timing",
    "timings_secs",
    "stage_secs",
    "warnings",
    "calibration",
    "truth",
    "baselines",
    "session",
    "brdf",
    "renders",
];

fn other_facts(v: &Value) -> Vec<(String, String)> {
    v.as_object()
        .map(|o| {
            o.iter()
                .filter(|(k, _)| !INTERPRETED.contains(&k.as_str()))
                .map(|(k, x)| {
                    let text = match x {
                        Value::Object(_) | Value::Array(_) => {
                            serde_json::to_string_pretty(x).unwrap_or_else(|_| x.to_string())
                        }
                        other => value_text(other),
                    };
                    (k.clone(), text)
                })
                .collect()
        })
        .unwrap_or_default()
}

// ---------------------------------------------------------------------------------------------
// HTML

/// Escapes text for HTML element content and attribute values.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

const STYLE: &str = "body{font-family:sans-serif;max-width:1100px;margin:1em auto;padding:0 1em;\
color:#222}h1{font-size:1.5em}h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.6em}\
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ddd;padding:.2em .6em;\
text-align:left;vertical-align:top}th{background:#f4f4f4}.na{color:#a33;font-style:italic}\
.note{background:#fff8e0;border-left:4px solid #e0b000;padding:.4em .8em}\
.warn li{color:#8a4b00}figure{display:inline-block;margin:.4em;vertical-align:top}\
figcaption{font-size:.8em;max-width:320px}.charts svg{max-width:100%;height:auto}\
pre{background:#f7f7f7;padding:.5em;overflow:auto;max-height:20em}.chosen{background:#e8f4e8}\
.hole{display:inline-block;width:200px;height:200px;border:2px dashed #c66;color:#a33;\
padding:1em;box-sizing:border-box}";

/// After load, marks `<body>` with `data-images-ok` (every image decoded) and counts, so a
/// headless browser test can check the page rendered.
const SCRIPT: &str = "window.addEventListener('load',function(){var im=document.images;\
var ok=true;for(var i=0;i<im.length;i++){if(!(im[i].complete&&im[i].naturalWidth>0)){ok=false;}}\
document.body.setAttribute('data-images-ok',ok?'true':'false');\
document.body.setAttribute('data-images',String(im.length));\
document.body.setAttribute('data-svgs',String(document.querySelectorAll('svg').length));});";

fn na(html: &mut String, why: &str) {
    let _ = write!(html, "<p class=\"na\">not available: {}</p>", escape(why));
}

fn kv_table(html: &mut String, rows: &[(String, String)]) {
    html.push_str("<table>");
    for (k, v) in rows {
        let _ = write!(
            html,
            "<tr><th>{}</th><td>{}</td></tr>",
            escape(k),
            escape(v)
        );
    }
    html.push_str("</table>");
}

fn figure(html: &mut String, img: &EmbeddedImage) {
    let b64 = base64::engine::general_purpose::STANDARD.encode(&img.png);
    let _ = write!(
        html,
        "<figure><img src=\"data:image/png;base64,{b64}\" width=\"{}\" height=\"{}\" alt=\"{}\">\
         <figcaption>{}</figcaption></figure>",
        img.width,
        img.height,
        escape(&img.caption),
        escape(&img.caption)
    );
}

fn fmt_vec(v: &[f64]) -> String {
    let parts: Vec<String> = v.iter().map(|x| fmt_num(*x)).collect();
    format!("({})", parts.join(", "))
}

/// The page. Pure: everything comes from `data`, every string in it is escaped; charts are the
/// SVG documents made by [`super::charts`], inlined.
pub fn render_html(data: &ReportData) -> String {
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\
         <title>{}</title><style>{STYLE}</style></head><body>\n",
        escape(&data.title)
    );
    let _ = writeln!(
        h,
        "<h1>{}</h1><p>Folder <code>{}</code>: {}.</p>",
        escape(&data.title),
        escape(&data.dir),
        escape(&data.kinds.join(", "))
    );
    section_capture(&mut h, &data.capture);
    section_calibration(&mut h, &data.calibration);
    section_brdf(&mut h, data);
    section_trials(&mut h, &data.trials, &data.components);
    section_timing(&mut h, &data.timing);

    h.push_str("<h2 id=\"warnings\">Warnings</h2>");
    if data.warnings.is_empty() {
        h.push_str("<p>None recorded.</p>");
    } else {
        h.push_str("<ul class=\"warn\">");
        for w in &data.warnings {
            let _ = write!(h, "<li>{}</li>", escape(w));
        }
        h.push_str("</ul>");
    }
    if !data.other_facts.is_empty() {
        h.push_str("<h2 id=\"other\">Other facts from report.json</h2><table>");
        for (k, v) in &data.other_facts {
            let _ = write!(
                h,
                "<tr><th>{}</th><td><pre>{}</pre></td></tr>",
                escape(k),
                escape(v)
            );
        }
        h.push_str("</table>");
    }
    let _ = write!(
        h,
        "\n<p><small>Made by brdf-rig {} (<code>brdf-rig report</code>).</small></p>\
         <script>{SCRIPT}</script>\n</body></html>\n",
        env!("CARGO_PKG_VERSION")
    );
    h
}

fn section_capture(h: &mut String, capture: &Avail<CaptureSummary>) {
    h.push_str("<h2 id=\"capture\">Capture</h2>");
    let c = match capture {
        Avail::No(why) => return na(h, why),
        Avail::Yes(c) => c,
    };
    let mut rows: Vec<(String, String)> = vec![("session folder".into(), c.dir.clone())];
    rows.extend(c.facts.iter().cloned());
    rows.push(("shots".into(), c.shots.to_string()));
    let kinds: Vec<String> = c.by_kind.iter().map(|(k, n)| format!("{k}: {n}")).collect();
    rows.push(("shots by kind".into(), kinds.join(", ")));
    let angles = if c.angles_deg.is_empty() {
        "none recorded".to_string()
    } else if c.angles_deg.len() <= 24 {
        let a: Vec<String> = c.angles_deg.iter().map(|x| fmt_num(*x)).collect();
        format!("{} angles: {}", c.angles_deg.len(), a.join(", "))
    } else {
        format!(
            "{} angles from {} to {} deg",
            c.angles_deg.len(),
            fmt_num(c.angles_deg[0]),
            fmt_num(c.angles_deg[c.angles_deg.len() - 1])
        )
    };
    rows.push(("turntable angles (deg)".into(), angles));
    if let Some(e) = c.max_angle_error_deg {
        rows.push((
            "largest |measured - asked| angle".into(),
            format!("{} deg", fmt_num(e)),
        ));
    }
    let ch: Vec<String> = c
        .channels
        .iter()
        .map(|(k, (n, d))| match d {
            Some(d) => format!(
                "channel {k}: {n} shots, nominal lab direction {}",
                fmt_vec(d)
            ),
            None => format!("channel {k}: {n} shots"),
        })
        .collect();
    rows.push((
        "light channels".into(),
        if ch.is_empty() {
            "none recorded".into()
        } else {
            ch.join("; ")
        },
    ));
    if let (Some(a), Some(b), Some(s)) = (&c.first_utc, &c.last_utc, c.span_secs) {
        rows.push(("time span".into(), format!("{a} to {b} ({} s)", fmt_num(s))));
    }
    if let Some((lo, hi)) = c.exposure_secs {
        rows.push((
            "exposure (s)".into(),
            format!("{} to {}", fmt_num(lo), fmt_num(hi)),
        ));
    }
    kv_table(h, &rows);
    h.push_str("<h3>Checksums</h3>");
    match &c.checksums {
        Avail::No(why) => na(h, why),
        Avail::Yes(st) => {
            let verdict = if st.problems.is_empty() {
                "all intact"
            } else {
                "PROBLEMS"
            };
            let _ = write!(
                h,
                "<p data-checksums=\"{}\">{verdict}: {} of {} files match their recorded size and \
                 SHA-256.</p>",
                if st.problems.is_empty() { "ok" } else { "bad" },
                st.ok,
                st.checked
            );
            if !st.problems.is_empty() {
                h.push_str("<ul class=\"warn\">");
                for p in st.problems.iter().take(50) {
                    let _ = write!(h, "<li>{}</li>", escape(p));
                }
                if st.problems.len() > 50 {
                    let _ = write!(h, "<li>... {} more</li>", st.problems.len() - 50);
                }
                h.push_str("</ul>");
            }
        }
    }
    h.push_str("<h3>Single-light images</h3>");
    match &c.thumbnails {
        Avail::No(why) => na(h, why),
        Avail::Yes(imgs) => {
            h.push_str("<p>Previews (sRGB, auto exposure per image), not data.</p><div>");
            for i in imgs {
                figure(h, i);
            }
            h.push_str("</div>");
        }
    }
}

fn section_calibration(h: &mut String, cal: &Avail<Vec<CalibrationEntry>>) {
    h.push_str("<h2 id=\"calibration\">Calibration</h2>");
    let entries = match cal {
        Avail::No(why) => return na(h, why),
        Avail::Yes(e) => e,
    };
    h.push_str(
        "<table><tr><th>source</th><th>light direction</th><th>uncertainty</th>\
         <th>irradiance</th><th>other</th></tr>",
    );
    for e in entries {
        let dir = e
            .light_dir
            .map(|d| fmt_vec(&d))
            .unwrap_or_else(|| "-".into());
        let unc = e
            .uncertainty_deg
            .map(|u| format!("{} deg", fmt_num(u)))
            .unwrap_or_else(|| "-".into());
        let irr = match (&e.irradiance, &e.irradiance_std_error) {
            (Some(i), Some(s)) => format!("{} +- {}", fmt_vec(i), fmt_vec(s)),
            (Some(i), None) => fmt_vec(i),
            _ => "-".into(),
        };
        let other: Vec<String> = e.other.iter().map(|(k, v)| format!("{k}: {v}")).collect();
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td><small>{}</small></td></tr>",
            escape(&e.source),
            escape(&dir),
            escape(&unc),
            escape(&irr),
            escape(&other.join("; "))
        );
    }
    h.push_str("</table>");
}

fn section_brdf(h: &mut String, data: &ReportData) {
    h.push_str("<h2 id=\"brdf\">Recovered BRDF: in-plane plot</h2>");
    match &data.brdf {
        Avail::No(why) => na(h, why),
        Avail::Yes(b) => {
            let _ = write!(
                h,
                "<p>From <code>{}</code>. {}. f_r in 1/sr without the cosine factor.</p>",
                escape(&b.file),
                escape(&b.description)
            );
            if b.uses_neural_fit {
                h.push_str(
                    "<p class=\"note\">Curves marked \"neural MERL fit\" are smooth neural \
                     approximations of the MERL measurements (Sztrajman et al. 2021), not \
                     measured MERL data; they are smoother at specular peaks and grazing \
                     angles.</p>",
                );
            }
            h.push_str("<div class=\"charts\">");
            for svg in &b.charts {
                let _ = write!(h, "<figure class=\"chart\">{svg}</figure>");
            }
            h.push_str("</div>");
            h.push_str("<table><tr><th>curve</th><th>peak red</th><th>peak green</th><th>peak blue</th></tr>");
            for (label, p) in &b.peaks {
                let cell = |x: Option<f64>| {
                    x.map(|a| format!("{} deg", fmt_num(a)))
                        .unwrap_or_else(|| "-".into())
                };
                let _ = write!(
                    h,
                    "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                    escape(label),
                    escape(&cell(p[0])),
                    escape(&cell(p[1])),
                    escape(&cell(p[2]))
                );
            }
            h.push_str("</table>");
            for m in &b.missing {
                let _ = write!(
                    h,
                    "<p class=\"na\">comparison not available: {}</p>",
                    escape(m)
                );
            }
        }
    }
    h.push_str("<h2 id=\"spheres\">Spheres rendered with the result</h2>");
    match &data.spheres {
        Avail::No(why) => {
            na(h, why);
            h.push_str("<div class=\"hole\">sphere renders not available</div>");
        }
        Avail::Yes(imgs) => {
            h.push_str(
                "<p>A unit sphere seen from 4 units away, one directional light; the same \
                 exposure for every light.</p><div>",
            );
            for i in imgs {
                figure(h, i);
            }
            h.push_str("</div>");
        }
    }
    h.push_str("<h3>Renders written by the reconstruction</h3>");
    match &data.renders {
        Avail::No(why) => na(h, why),
        Avail::Yes(imgs) => {
            h.push_str("<div>");
            for i in imgs {
                figure(h, i);
            }
            h.push_str("</div>");
        }
    }
}

fn section_trials(h: &mut String, trials: &Avail<TrialsSection>, comps: &Avail<ComponentsSection>) {
    h.push_str("<h2 id=\"trials\">Trials and their similarities</h2>");
    match trials {
        Avail::No(why) => na(h, why),
        Avail::Yes(t) => {
            let chosen_row = t.chosen.and_then(|c| t.rows.iter().find(|r| r.index == c));
            match (t.chosen, chosen_row) {
                (Some(c), Some(r)) => {
                    let _ = write!(
                        h,
                        "<p id=\"chosen\">Chosen trial: <b>#{c}</b>, cosine similarity <b>{}</b> \
                         (highest of {} trials).</p>",
                        r.similarity
                            .map(fmt_num)
                            .unwrap_or_else(|| "unknown".into()),
                        t.rows.len()
                    );
                }
                (Some(c), None) => {
                    let _ = write!(
                        h,
                        "<p class=\"na\">Chosen trial #{c} is not among the listed trials.</p>"
                    );
                }
                (None, _) => na(h, "report.json names no chosen trial (\"chosen_trial\")"),
            }
            let has_err = t.rows.iter().any(|r| r.error.is_some());
            let mut other_keys: Vec<String> = t
                .rows
                .iter()
                .flat_map(|r| r.other.iter().map(|(k, _)| k.clone()))
                .collect();
            other_keys.sort();
            other_keys.dedup();
            h.push_str("<table><tr><th>trial</th><th>similarity</th>");
            if has_err {
                h.push_str("<th>error vs truth</th>");
            }
            for k in &other_keys {
                let _ = write!(h, "<th>{}</th>", escape(k));
            }
            h.push_str("</tr>");
            for r in &t.rows {
                let cls = if Some(r.index) == t.chosen {
                    " class=\"chosen\""
                } else {
                    ""
                };
                let _ = write!(
                    h,
                    "<tr{cls}><td>#{}</td><td>{}</td>",
                    r.index,
                    r.similarity.map(fmt_num).unwrap_or_else(|| "-".into())
                );
                if has_err {
                    let _ = write!(
                        h,
                        "<td>{}</td>",
                        r.error.map(fmt_num).unwrap_or_else(|| "-".into())
                    );
                }
                for k in &other_keys {
                    let v = r
                        .other
                        .iter()
                        .find(|(kk, _)| kk == k)
                        .map(|(_, v)| v.as_str())
                        .unwrap_or("-");
                    let _ = write!(h, "<td>{}</td>", escape(v));
                }
                h.push_str("</tr>");
            }
            h.push_str("</table><div class=\"charts\">");
            for svg in &t.charts {
                let _ = write!(h, "<figure class=\"chart\">{svg}</figure>");
            }
            h.push_str("</div>");
        }
    }
    h.push_str("<h2 id=\"components\">Basis components k</h2>");
    match comps {
        Avail::No(why) => na(h, why),
        Avail::Yes(c) => {
            let _ = write!(
                h,
                "<p id=\"k\">k chosen: <b>{}</b></p>",
                c.k.map(|k| k.to_string())
                    .unwrap_or_else(|| "not recorded".into())
            );
            if !c.other.is_empty() {
                kv_table(h, &c.other);
            }
            if let Some(svg) = &c.chart {
                let _ = write!(
                    h,
                    "<div class=\"charts\"><figure class=\"chart\">{svg}</figure></div>"
                );
            }
        }
    }
}

fn section_timing(h: &mut String, timing: &Avail<Vec<(String, f64)>>) {
    h.push_str("<h2 id=\"timing\">Time per stage</h2>");
    match timing {
        Avail::No(why) => na(h, why),
        Avail::Yes(t) => {
            let total: f64 = t.iter().map(|(_, s)| s).sum();
            h.push_str("<table><tr><th>stage</th><th>seconds</th><th>share</th></tr>");
            for (name, s) in t {
                let share = if total > 0.0 { 100.0 * s / total } else { 0.0 };
                let _ = write!(
                    h,
                    "<tr><td>{}</td><td>{}</td><td>{:.0} %</td></tr>",
                    escape(name),
                    fmt_num(*s),
                    share
                );
            }
            let _ = write!(
                h,
                "<tr><th>total</th><th>{}</th><th></th></tr></table>",
                fmt_num(total)
            );
        }
    }
}
