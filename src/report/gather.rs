//! Gathering a report: what a capture session folder and/or a reconstruction output folder hold,
//! read into [`ReportData`] for the page ([`super::html`]).
//!
//! Two steps: [`gather`] reads what the folder holds into [`ReportData`], tolerantly (a piece
//! that is missing or unreadable becomes [`Avail::No`] with the reason, never an error), and
//! [`super::html::render_html`] turns that into the page.
//!
//! What is read (all optional except that the folder must be one of the two kinds):
//! - session folder: `manifest.json` (else `journal.jsonl`), `session.json`, the images it lists
//!   (checksums, a few single-light thumbnails), through their owner `capture::session`
//!   ([`super::session`]); `calibration.json` through its owner `pipeline::calibration_file`.
//! - reconstruction output: `brdf.binary` (MERL table) and `report.json`, read as untyped JSON so
//!   any producer's fields show; the keys interpreted are listed in `docs/report.md`
//!   (`trials`, `chosen_trial`, `components`, `timings`, `warnings`, `truth`,
//!   `baselines`, `session`), plus any `*.png` renders beside them.

use super::charts::{ChartSpec, Goal, ScatterPoint, Series, line_chart, scatter_pareto};
use super::images::{EmbeddedImage, png_files, sphere_renders};
use super::inplane::{self, InPlaneCurve, InPlaneSettings};
use super::session::{CaptureSummary, summarise_session};
use crate::brdf::Brdf;
use crate::brdf::merl::MerlTable;
use crate::brdf::nbrdf::Nbrdf;
use crate::capture::session::{JOURNAL_FILE, MANIFEST_FILE, SESSION_FILE};
use crate::pipeline::calibration_file::{self, CALIBRATION_FILE, ChannelCalibration};
use serde_json::Value;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::reconstruct::output::REPORT_FORMAT_VERSION;
pub use crate::reconstruct::output::{BRDF_FILE, REPORT_FILE as REPORT_JSON};

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
    /// The reconstruction's own verdict (`report.json` `confidence`): level and reasons.
    pub confidence: Option<(String, Vec<String>)>,
    /// `report.json` keys not shown elsewhere, as key and pretty JSON.
    pub other_facts: Vec<(String, String)>,
    /// Where the result's prior came from, as the producer states it (`basis.note`,
    /// `provenance`): shown beside the result.
    pub provenance: Vec<String>,
    /// The model ladder and the plausibility step (`model`, `ladder`, `plausibility`).
    pub ladder: Avail<LadderSection>,
    /// Every light image beside its re-render (`comparisons`).
    pub comparisons: Avail<Vec<ComparisonRow>>,
    /// The normal refinement (`normals`); `None` when it did not run.
    pub normals: Option<NormalsSection>,
}

/// One alternation of the normal refinement, as shown.
#[derive(Clone, Debug, PartialEq)]
pub struct NormalsRow {
    pub iteration: u64,
    pub mean_tilt_deg: Option<f64>,
    pub max_tilt_deg: Option<f64>,
    pub train_error: Option<f64>,
    pub held_out_error: Option<f64>,
}

/// What the normal refinement did (`report.json` `normals`).
#[derive(Clone, Debug, PartialEq)]
pub struct NormalsSection {
    pub accepted: bool,
    pub reason: String,
    pub held_out_images: String,
    pub chosen_iterations: Option<u64>,
    pub mean_tilt_deg: Option<f64>,
    pub max_tilt_deg: Option<f64>,
    pub vertices_refined: Option<u64>,
    pub rows: Vec<NormalsRow>,
}

/// One rung of the ladder, as shown.
#[derive(Clone, Debug, PartialEq)]
pub struct LadderRow {
    pub label: String,
    pub parameters: Option<f64>,
    pub error: Option<f64>,
    pub standard_error: Option<f64>,
    pub chosen: bool,
}

/// The model ladder's table, the choice and the plausibility facts.
#[derive(Clone, Debug, PartialEq)]
pub struct LadderSection {
    pub model: String,
    pub reason: String,
    pub scheme: String,
    pub rows: Vec<LadderRow>,
    pub plausibility: Vec<(String, String)>,
}

/// One light image beside its re-render.
#[derive(Clone, Debug, PartialEq)]
pub struct ComparisonRow {
    pub image: EmbeddedImage,
    pub fit_error: Option<f64>,
    pub held_out_error: Option<f64>,
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
            match read_json(&r.join(REPORT_JSON)) {
                // a file of another version is not misread (a file without one is version 1)
                Avail::Yes(v)
                    if v.get("format_version")
                        .is_some_and(|f| f.as_u64() != Some(u64::from(REPORT_FORMAT_VERSION))) =>
                {
                    Avail::No(format!(
                        "{}: format_version {}, but this brdf-rig reads version \
                         {REPORT_FORMAT_VERSION}",
                        r.join(REPORT_JSON).display(),
                        v["format_version"]
                    ))
                }
                other => other,
            }
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
        let base = recon_dir.as_deref().unwrap_or(dir);
        let named = rj
            .and_then(|v| v.get("session"))
            .and_then(Value::as_str)
            .map(|s| resolve(base, s));
        // Else the folder of the job, when the capture step wrote the job into its session.
        let of_job = || {
            let job = resolve(base, rj?.get("job")?.as_str()?);
            let parent = job.parent()?;
            parent
                .join(MANIFEST_FILE)
                .is_file()
                .then(|| parent.to_path_buf())
        };
        named.or_else(of_job)
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

    let calibration = gather_calibration(session_dir.as_deref());

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
        confidence: rj.and_then(confidence),
        other_facts,
        provenance: rj.map(provenance).unwrap_or_default(),
        ladder: rj.map_or_else(|| Avail::No("no report.json".into()), ladder_section),
        normals: rj.and_then(normals_section),
        comparisons: match (rj, &recon_dir) {
            (Some(v), Some(d)) => comparisons_section(v, d),
            _ => Avail::No("no report.json".into()),
        },
    })
}

/// A rung's label from its JSON (`family`, `k`, `eta`).
fn rung_label(r: &Value) -> String {
    let family = match r.get("family").and_then(Value::as_str).unwrap_or("?") {
        "lambert" => "Lambert",
        "lambert-ggx" => "Lambert + GGX",
        "basis" => "basis",
        "hybrid" => "basis + GGX peak",
        other => other,
    };
    match (
        r.get("k").and_then(Value::as_u64),
        r.get("eta").and_then(Value::as_f64),
    ) {
        (Some(k), Some(eta)) => format!("{family} (k = {k}, eta = {eta})"),
        _ => family.to_string(),
    }
}

/// `model`, `ladder` and `plausibility` of report.json.
fn ladder_section(v: &Value) -> Avail<LadderSection> {
    let Some(model) = v.get("model") else {
        return Avail::No("report.json has no \"model\" (made before the model ladder)".into());
    };
    let ladder = v.get("ladder").filter(|l| !l.is_null());
    let chosen = ladder
        .and_then(|l| l.get("chosen"))
        .and_then(Value::as_u64)
        .map(|c| c as usize);
    let rows = ladder
        .and_then(|l| l.get("rungs"))
        .and_then(Value::as_array)
        .map(|rs| {
            rs.iter()
                .enumerate()
                .map(|(i, r)| LadderRow {
                    label: rung_label(r),
                    parameters: r.get("parameters").and_then(Value::as_f64),
                    error: r.get("error").and_then(Value::as_f64),
                    standard_error: r.get("standard_error").and_then(Value::as_f64),
                    chosen: Some(i) == chosen,
                })
                .collect()
        })
        .unwrap_or_default();
    let scheme = ladder
        .and_then(|l| l.get("scheme"))
        .map(|s| match s.get("kind").and_then(Value::as_str) {
            Some("images") => format!(
                "whole images held out, {} folds",
                s.get("folds").map(value_text).unwrap_or_default()
            ),
            Some("blocks") => format!(
                "spatial blocks of {} px held out, {} folds",
                s.get("block_px").map(value_text).unwrap_or_default(),
                s.get("folds").map(value_text).unwrap_or_default()
            ),
            _ => value_text(s),
        })
        .unwrap_or_else(|| "the ladder did not run".to_string());
    let plausibility = v
        .get("plausibility")
        .and_then(Value::as_object)
        .map(|o| {
            o.iter()
                .map(|(k, x)| (k.replace('_', " "), value_text(x)))
                .collect()
        })
        .unwrap_or_default();
    Avail::Yes(LadderSection {
        model: rung_label(model),
        reason: model.get("reason").map(value_text).unwrap_or_default(),
        scheme,
        rows,
        plausibility,
    })
}

/// `normals` of report.json; `None` when the refinement did not run (absent or null).
fn normals_section(v: &Value) -> Option<NormalsSection> {
    let n = v.get("normals").filter(|n| !n.is_null())?;
    let f = |x: &Value, k: &str| x.get(k).and_then(Value::as_f64);
    let rows = n
        .get("iterations")
        .and_then(Value::as_array)
        .map(|its| {
            its.iter()
                .map(|it| NormalsRow {
                    iteration: it.get("iteration").and_then(Value::as_u64).unwrap_or(0),
                    mean_tilt_deg: f(it, "mean_tilt_deg"),
                    max_tilt_deg: f(it, "max_tilt_deg"),
                    train_error: f(it, "train_error"),
                    held_out_error: f(it, "held_out_error"),
                })
                .collect()
        })
        .unwrap_or_default();
    Some(NormalsSection {
        accepted: n.get("accepted").and_then(Value::as_bool).unwrap_or(false),
        reason: n.get("reason").map(value_text).unwrap_or_default(),
        held_out_images: n.get("held_out_images").map(value_text).unwrap_or_default(),
        chosen_iterations: n.get("chosen_iterations").and_then(Value::as_u64),
        mean_tilt_deg: f(n, "mean_tilt_deg"),
        max_tilt_deg: f(n, "max_tilt_deg"),
        vertices_refined: n.get("vertices_refined").and_then(Value::as_u64),
        rows,
    })
}

/// `comparisons` of report.json, with their panels embedded.
fn comparisons_section(v: &Value, recon_dir: &Path) -> Avail<Vec<ComparisonRow>> {
    let Some(list) = v.get("comparisons").and_then(Value::as_array) else {
        return Avail::No(
            "report.json has no \"comparisons\" (made before photo/re-render panels)".into(),
        );
    };
    let mut rows = Vec::new();
    let mut bad = Vec::new();
    for c in list {
        let Some(file) = c.get("file").and_then(Value::as_str) else {
            continue;
        };
        let photo = c.get("photo").map(value_text).unwrap_or_default();
        let caption = format!(
            "light image {}: {photo} | re-render | error (red: re-render brighter)",
            c.get("image").map(value_text).unwrap_or_default()
        );
        match super::images::embed_png(&recon_dir.join(file), caption) {
            Ok(image) => rows.push(ComparisonRow {
                image,
                fit_error: c.get("fit_error").and_then(Value::as_f64),
                held_out_error: c.get("held_out_error").and_then(Value::as_f64),
            }),
            Err(e) => bad.push(format!("{file}: {e}")),
        }
    }
    if rows.is_empty() {
        Avail::No(if bad.is_empty() {
            "no light image to compare".into()
        } else {
            bad.join("; ")
        })
    } else {
        Avail::Yes(rows)
    }
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

pub(super) fn resolve(base: &Path, s: &str) -> PathBuf {
    let p = PathBuf::from(s);
    if p.is_absolute() { p } else { base.join(p) }
}

pub(super) fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut src = e.source();
    while let Some(c) = src {
        let _ = write!(s, ": {c}");
        src = c.source();
    }
    s
}

pub(super) fn read_json(path: &Path) -> Avail<Value> {
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

/// A JSON value as short text (strings without quotes).
pub(super) fn value_text(v: &Value) -> String {
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
// Calibration

/// One row of the page per light channel of `calibration.json`.
fn calibration_entry(source: String, c: &ChannelCalibration) -> CalibrationEntry {
    let l = &c.light;
    let mut other = vec![
        ("spread_deg".into(), fmt_num(l.spread_deg)),
        ("std_error_deg".into(), fmt_num(l.std_error_deg)),
        ("fit_uncertainty_deg".into(), fmt_num(l.fit_uncertainty_deg)),
        ("images".into(), l.images.to_string()),
        ("flat_field_spread".into(), fmt_num(c.flat_field_spread)),
        ("sphere_clip".into(), c.sphere_clip.to_string()),
        ("white_clip".into(), c.white_clip.to_string()),
    ];
    if let Some(e) = c.truth_dir_error_deg {
        other.push(("truth_dir_error_deg".into(), fmt_num(e)));
    }
    if let Some(e) = c.truth_irradiance_error {
        other.push(("truth_irradiance_error".into(), fmt_num(e)));
    }
    if !c.warnings.is_empty() {
        other.push(("warnings".into(), c.warnings.join("; ")));
    }
    CalibrationEntry {
        source,
        light_dir: Some(l.dir_camera),
        uncertainty_deg: Some(l.uncertainty_deg),
        irradiance: Some(c.irradiance.to_vec()),
        irradiance_std_error: Some(c.irradiance_std_error.to_vec()),
        other,
    }
}

/// JSON as compact text, cut at 300 characters.
pub(super) fn short_json(v: &Value) -> String {
    let s = value_text(v);
    if s.chars().count() > 300 {
        let cut: String = s.chars().take(300).collect();
        format!("{cut}...")
    } else {
        s
    }
}

/// The session's `calibration.json` (written by `brdf-rig calibrate SESSION`), one entry per
/// light channel.
fn gather_calibration(session: Option<&Path>) -> Avail<Vec<CalibrationEntry>> {
    let Some(dir) = session else {
        return Avail::No("no session folder, so no calibration.json".into());
    };
    let path = dir.join(CALIBRATION_FILE);
    match calibration_file::read(dir) {
        Ok(cal) if cal.channels.is_empty() => {
            Avail::No(format!("{}: no light channel", path.display()))
        }
        Ok(cal) => Avail::Yes(
            cal.channels
                .iter()
                .map(|c| calibration_entry(format!("{} channel {}", path.display(), c.channel), c))
                .collect(),
        ),
        Err(e) if e.is_not_found() => Avail::No(format!(
            "{} does not exist: run `brdf-rig calibrate {}`",
            path.display(),
            dir.display()
        )),
        Err(e) => Avail::No(error_chain(&e)),
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

/// Provenance statements of `report.json` (`provenance`, `basis.note`).
fn provenance(v: &Value) -> Vec<String> {
    [
        v.get("provenance"),
        v.get("basis").and_then(|b| b.get("note")),
    ]
    .into_iter()
    .flatten()
    .map(value_text)
    .filter(|t| !t.is_empty())
    .collect()
}

/// `confidence.level` and `confidence.reasons` of report.json.
fn confidence(v: &Value) -> Option<(String, Vec<String>)> {
    let c = v.get("confidence")?;
    let level = c.get("level")?.as_str()?.to_string();
    Some((level, strings_at(c, "reasons")))
}

const INTERPRETED: [&str; 25] = [
    "format_version",
    "model",
    "normals",
    "ladder",
    "plausibility",
    "comparisons",
    "provenance",
    "confidence",
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

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn normals_section_when_the_refinement_ran() {
        assert_eq!(normals_section(&json!({})), None);
        assert_eq!(normals_section(&json!({"normals": null})), None);
        let v = json!({"normals": {
        "accepted": true, "reason": "1 iteration(s) lowered ...", "held_out_images": [1, 5],
        "chosen_iterations": 1, "mean_tilt_deg": 1.5, "max_tilt_deg": 9.0,
        "vertices_refined": 300,
        "iterations": [
            {"iteration": 0, "mean_tilt_deg": 0.0, "max_tilt_deg": 0.0,
             "train_error": 0.3, "held_out_error": 0.4},
            {"iteration": 1, "mean_tilt_deg": 1.4, "max_tilt_deg": 8.0,
             "train_error": 0.25, "held_out_error": 0.35}
        ]}});
        let n = normals_section(&v).unwrap();
        assert!(n.accepted);
        assert_eq!(n.chosen_iterations, Some(1));
        assert_eq!(n.rows.len(), 2);
        assert_eq!(n.rows[1].held_out_error, Some(0.35));
        assert!(other_facts(&v).iter().all(|(k, _)| k != "normals"));
    }

    #[test]
    fn timings_in_each_accepted_shape() {
        let want = vec![("a".to_string(), 1.5), ("b".to_string(), 2.0)];
        for v in [
            json!({"timings": [["a", 1.5], ["b", 2.0]]}),
            json!({"timings": {"a": 1.5, "b": 2.0}}),
            json!({"timing": [{"stage": "a", "secs": 1.5}, {"name": "b", "seconds": 2.0}]}),
        ] {
            assert_eq!(timing_section(&v), Avail::Yes(want.clone()), "{v}");
        }
        assert!(matches!(timing_section(&json!({})), Avail::No(w) if w.contains("timings")));
        assert!(!timing_section(&json!({"timings": "soon"})).is_available());
    }

    #[test]
    fn trials_components_and_other_facts() {
        let v = json!({
            "trials": [0.9, 0.95, 0.8], "chosen": 1, "k": 7,
            "reliable_pixels": 12, "settings": {"eta": 40}
        });
        let Avail::Yes(t) = trials_section(&v) else {
            panic!()
        };
        assert_eq!(t.chosen, Some(1));
        assert_eq!(t.rows[1].similarity, Some(0.95));
        assert_eq!(t.charts.len(), 1); // no errors known: no Fig. 6 chart
        let Avail::Yes(c) = components_section(&v) else {
            panic!()
        };
        assert_eq!(c.k, Some(7));
        let facts = other_facts(&v);
        assert_eq!(facts.len(), 2);
        assert!(
            facts
                .iter()
                .any(|(k, x)| k == "reliable_pixels" && x == "12")
        );
        assert!(!trials_section(&json!({"trials": 3})).is_available());
    }

    #[test]
    fn session_calibration_is_one_entry_per_channel() {
        use crate::calib::clip::ClipLevel;
        use crate::calib::light::LightSummary;
        use crate::pipeline::calibration_file::SessionCalibration;
        let dir = tempfile::tempdir().unwrap();
        let channel = |channel, dir_camera: [f64; 3], uncertainty_deg, irr| ChannelCalibration {
            channel,
            light: LightSummary {
                dir_camera,
                uncertainty_deg,
                spread_deg: 0.0,
                std_error_deg: 0.0,
                fit_uncertainty_deg: uncertainty_deg,
                images: 1,
            },
            irradiance: [irr; 3],
            irradiance_std_error: [0.07; 3],
            flat_field_spread: 0.0003,
            sphere_clip: ClipLevel::given(1.0),
            white_clip: ClipLevel::given(1.0),
            warnings: Vec::new(),
            truth_dir_error_deg: None,
            truth_irradiance_error: None,
        };
        let cal = SessionCalibration {
            format_version: 1,
            channels: vec![
                channel(0, [0.3, 0.0, -0.95], 0.6, 1200.0),
                channel(2, [0.96, 0.0, 0.27], 0.7, 1100.0),
            ],
            light_images: 9,
            job: "job.toml".into(),
        };
        calibration_file::write(dir.path(), &cal).unwrap();
        let Avail::Yes(es) = gather_calibration(Some(dir.path())) else {
            panic!()
        };
        assert_eq!(es.len(), 2);
        assert!(es[1].source.ends_with("calibration.json channel 2"));
        assert_eq!(es[0].light_dir, Some([0.3, 0.0, -0.95]));
        assert_eq!(es[1].uncertainty_deg, Some(0.7));
        assert_eq!(es[0].irradiance, Some(vec![1200.0; 3]));
        assert!(es[0].other.iter().any(|(k, _)| k == "flat_field_spread"));
        // a calibration.json of another version is refused with the reason, not misread
        std::fs::write(
            dir.path().join(CALIBRATION_FILE),
            br#"{"format_version": 7, "channels": []}"#,
        )
        .unwrap();
        let Avail::No(why) = gather_calibration(Some(dir.path())) else {
            panic!()
        };
        assert!(why.contains("format_version 7"), "{why}");
    }

    #[test]
    fn numbers_are_short() {
        assert_eq!(fmt_num(0.981), "0.981");
        assert_eq!(fmt_num(1234.5678), "1235");
        assert_eq!(fmt_num(12.0), "12");
        assert_eq!(fmt_num(0.0), "0");
        assert_eq!(fmt_num(2.5e-5), "2.500e-5");
        assert_eq!(fmt_num(-0.125), "-0.125");
    }
}
