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
//! - reconstruction output: `brdf.binary` (MERL table) and `report.json` through its owner
//!   `reconstruct::report_file` (the typed record `brdf-rig reconstruct` writes; a file of another
//!   version says so), plus any `*.png` renders beside them, and with several materials each
//!   material's table ([`super::materials`]).

use super::avail::{Avail, error_chain};
use super::brdf_file::{is_neural, load_brdf};
use super::charts::{ChartSpec, Series, line_chart};
use super::images::{EmbeddedImage, png_files, sphere_renders};
use super::inplane::{self, InPlaneCurve};
use super::numbers::fmt_num;
use super::options::ReportOptions;
use super::session::{CaptureSummary, summarise_session};
use crate::brdf::Brdf;
use crate::brdf::merl::MerlTable;
use crate::capture::session::{JOURNAL_FILE, MANIFEST_FILE, SESSION_FILE};
use crate::pipeline::calibration_file::{self, CALIBRATION_FILE, ChannelCalibration};
use crate::reconstruct::ladder::{Family, FoldScheme, Ladder};
use crate::reconstruct::plausible::Plausibility;
use crate::reconstruct::refine::RefineReport;
use crate::reconstruct::report_file::{self, BRDF_FILE, REPORT_FILE, Report};
use serde_json::Value;
use std::path::{Path, PathBuf};

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
    /// Other scalar fields, as text.
    pub other: Vec<(String, String)>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct TrialsSection {
    pub rows: Vec<TrialRow>,
    pub chosen: Option<i64>,
    /// Similarity by trial.
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
    /// The materials found (`materials`) with, per material, its sphere renders and its
    /// pixels per light image; `None` when the segmentation did not run.
    pub materials: Option<super::materials::MaterialsSection>,
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
    /// The starts tried, e.g. "0 steps: 0.176; 4 steps: 0.145 (chosen)"; empty when only the
    /// mesh's own normals were (reports written before starts were chosen).
    pub starts: String,
    /// The reflectance table's shape and why, e.g. "48 x 32 x 8 (theta_h x theta_d x phi_d):
    /// 2.61 fitting samples per observed cell, at least 2 for this shape".
    pub table: String,
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
    /// Held-out relative error of the linear pixel values, mean over folds, and its SE.
    pub error: Option<f64>,
    pub standard_error: Option<f64>,
    /// The same in log space (the error the default choice reads).
    pub error_log: Option<f64>,
    pub standard_error_log: Option<f64>,
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
    /// Index of the light image in the job.
    pub index: usize,
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

    // report.json, through its owner.
    let report: Avail<Report> = match &recon_dir {
        None => Avail::No("no reconstruction output in this folder".into()),
        Some(r) => {
            kinds.push(if r == dir {
                "reconstruction output".to_string()
            } else {
                format!("reconstruction output in {}", r.display())
            });
            match report_file::read(r) {
                Ok(report) => Avail::Yes(report),
                Err(e) if e.is_not_found() => {
                    Avail::No(format!("{} does not exist", r.join(REPORT_FILE).display()))
                }
                // a file of another version is refused with both versions, never misread
                Err(e) => Avail::No(error_chain(&e)),
            }
        }
    };
    if let Avail::No(why) = &report
        && recon_dir.is_some()
    {
        warnings.push(format!("report.json: {why}"));
    }
    let rj = report.as_option();

    // Capture: this folder, or the session the job was written into (`calibrate` writes the
    // job into its session folder).
    let session_dir = if is_session {
        Some(dir.to_path_buf())
    } else {
        let base = recon_dir.as_deref().unwrap_or(dir);
        rj.and_then(|r| {
            let job = base.join(&r.job);
            let parent = job.parent()?;
            parent
                .join(MANIFEST_FILE)
                .is_file()
                .then(|| parent.to_path_buf())
        })
    };
    let capture = match (&session_dir, rj) {
        (Some(s), _) => Avail::Yes(summarise_session(s, opts)),
        (None, Some(r)) => Avail::No(format!(
            "this is a reconstruction output without a session folder (its job, {}, is not in \
             a session folder)",
            r.job.display()
        )),
        (None, None) => Avail::No(
            "this is a reconstruction output without a session folder (no readable report.json \
             names its job)"
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
        (Avail::Yes(t), Some(p)) => brdf_section(t, p, &opts.compare, opts),
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
        Some(r) => (
            trials_section(r),
            Avail::Yes(components_section(r)),
            timing_section(r),
            other_facts(r),
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
    if let Some(r) = rj {
        warnings.extend(r.warnings.iter().cloned());
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
        confidence: rj.map(|r| (r.confidence.level.to_string(), r.confidence.reasons.clone())),
        other_facts,
        provenance: rj.map(|r| vec![r.basis.note.clone()]).unwrap_or_default(),
        ladder: rj.map_or_else(
            || Avail::No("no report.json".into()),
            |r| Avail::Yes(ladder_section(r)),
        ),
        normals: rj.and_then(normals_section),
        materials: match (rj, &recon_dir) {
            (Some(r), Some(d)) => super::materials::gather_materials(r, d, opts),
            _ => None,
        },
        comparisons: match (rj, &recon_dir) {
            (Some(r), Some(d)) => comparisons_section(r, d),
            _ => Avail::No("no report.json".into()),
        },
    })
}

/// A model's label from its family and, for the basis families, k and eta.
fn model_label(family: Family, k: Option<usize>, eta: Option<f64>) -> String {
    match (k, eta) {
        (Some(k), Some(eta)) => format!("{family} (k = {k}, eta = {})", fmt_num(eta)),
        _ => family.to_string(),
    }
}

/// `model`, `ladder` and `plausibility` of report.json.
fn ladder_section(r: &Report) -> LadderSection {
    let ladder = r.ladder.as_ref();
    LadderSection {
        model: model_label(r.model.family, r.model.k, r.model.eta),
        reason: r.model.reason.clone(),
        scheme: ladder.map_or_else(|| "the ladder did not run".to_string(), ladder_scheme),
        rows: ladder.map(ladder_rows).unwrap_or_default(),
        plausibility: plausibility_rows(&r.plausibility),
    }
}

/// A ladder's rungs as the page shows them (the whole result's, or one material's).
pub fn ladder_rows(l: &Ladder) -> Vec<LadderRow> {
    l.rungs
        .iter()
        .enumerate()
        .map(|(i, g)| LadderRow {
            label: model_label(g.family, g.k, g.eta),
            parameters: Some(g.parameters as f64),
            error: g.error,
            standard_error: g.standard_error,
            error_log: g.error_log,
            standard_error_log: g.standard_error_log,
            chosen: i == l.chosen,
        })
        .collect()
}

/// How a ladder held pixels out, in words.
pub fn ladder_scheme(l: &Ladder) -> String {
    match l.scheme {
        FoldScheme::Images { folds } => format!("whole images held out, {folds} folds"),
        FoldScheme::Blocks { folds, block_px } => {
            format!("spatial blocks of {block_px} px held out, {folds} folds")
        }
    }
}

/// What the plausibility step found and did, as (field, value) rows.
pub fn plausibility_rows(p: &Plausibility) -> Vec<(String, String)> {
    fields_as_text(p)
        .into_iter()
        .map(|(k, v)| match (k.as_str(), &p.hedge) {
            ("hedge", Some(h)) => (
                "hedge (averaged with Lambert + GGX)".to_string(),
                format!("{} (docs/reconstruction.md, stage 6)", h.describe()),
            ),
            ("peak_energy", _) => match &p.peak_energy {
                Some(e) => (
                    "peak energy (from the images' patch sums)".to_string(),
                    format!("{} (docs/reconstruction.md, stage 6)", e.describe()),
                ),
                None => (k.replace('_', " "), v),
            },
            _ => (k.replace('_', " "), v),
        })
        .collect()
}

/// `normals` of report.json; `None` when the refinement did not run.
fn normals_section(r: &Report) -> Option<NormalsSection> {
    let n = r.normals.as_ref()?;
    Some(NormalsSection {
        accepted: n.accepted,
        reason: n.reason.clone(),
        held_out_images: format!("{:?}", n.held_out_images),
        chosen_iterations: Some(n.chosen_iterations as u64),
        starts: if n.starts.len() > 1 {
            n.starts
                .iter()
                .map(|s| {
                    format!(
                        "{} steps: {}{}",
                        s.smoothing_iterations,
                        fmt_num(s.held_out_error),
                        if s.smoothing_iterations == n.chosen_start_smoothing {
                            " (chosen)"
                        } else {
                            ""
                        }
                    )
                })
                .collect::<Vec<_>>()
                .join("; ")
        } else {
            String::new()
        },
        table: table_text(n),
        mean_tilt_deg: Some(n.mean_tilt_deg),
        max_tilt_deg: Some(n.max_tilt_deg),
        vertices_refined: Some(n.vertices_refined as u64),
        rows: n
            .iterations
            .iter()
            .map(|it| NormalsRow {
                iteration: it.iteration as u64,
                mean_tilt_deg: Some(it.mean_tilt_deg),
                max_tilt_deg: Some(it.max_tilt_deg),
                train_error: Some(it.train_error),
                held_out_error: Some(it.held_out_error),
            })
            .collect(),
    })
}

/// The refinement's reflectance table as the report says it.
fn table_text(n: &RefineReport) -> String {
    let s = &n.settings;
    let why = match n.table_samples_per_cell {
        None => "one shape for every scene (reports before session 40), or not chosen".to_string(),
        Some(d) if n.table_bins == s.table_bins => format!(
            "{} fitting samples per observed cell, at least {} for this shape",
            fmt_num(d),
            fmt_num(s.min_samples_per_cell)
        ),
        Some(d) => format!(
            "{} fitting samples per observed cell of {}, fewer than its {}: the coarser shape",
            fmt_num(d),
            s.table_bins,
            fmt_num(s.min_samples_per_cell)
        ),
    };
    let foreign = n
        .foreign_colour_text()
        .map_or(String::new(), |t| format!("; {t}"));
    format!(
        "{} (theta_h x theta_d x phi_d): {why}{foreign}",
        n.table_bins
    )
}

/// `comparisons` of report.json, with their panels embedded.
fn comparisons_section(r: &Report, recon_dir: &Path) -> Avail<Vec<ComparisonRow>> {
    let mut rows = Vec::new();
    let mut bad = Vec::new();
    for c in &r.comparisons {
        let caption = format!(
            "light image {}: {} | re-render | error (red: re-render brighter){}",
            c.image,
            c.photo.display(),
            if c.materials.is_empty() {
                ""
            } else {
                " | material map"
            }
        );
        match super::images::embed_png(&recon_dir.join(&c.file), caption) {
            Ok(image) => rows.push(ComparisonRow {
                index: c.image,
                image,
                fit_error: Some(c.fit_error),
                held_out_error: c.held_out_error,
            }),
            Err(e) => bad.push(format!("{}: {e}", c.file)),
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
    let holds = |d: &Path| d.join(BRDF_FILE).is_file() || d.join(REPORT_FILE).is_file();
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
            // the page shows the whole cause chain in one line
            Err(e) => missing.push(format!("{label}: {}", error_chain(&e))),
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

fn trials_section(r: &Report) -> Avail<TrialsSection> {
    let rows: Vec<TrialRow> = r
        .trials
        .iter()
        .map(|t| TrialRow {
            index: t.index as i64,
            similarity: Some(t.similarity),
            other: vec![
                (
                    "rejected_by_monotonicity".to_string(),
                    t.rejected_by_monotonicity.to_string(),
                ),
                ("fitted_samples".to_string(), t.fitted_samples.to_string()),
            ],
        })
        .collect();
    let chosen = Some(r.chosen_trial as i64);
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
    Avail::Yes(TrialsSection {
        rows,
        chosen,
        charts,
    })
}

fn components_section(r: &Report) -> ComponentsSection {
    let c = &r.components;
    let curve: Vec<(f64, f64)> = c
        .curve
        .iter()
        .filter_map(|p| Some((p.k as f64, p.error?)))
        .collect();
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
    let other = fields_as_text(c)
        .into_iter()
        .filter(|(k, _)| k.as_str() != "k" && k.as_str() != "curve")
        .collect();
    ComponentsSection {
        k: Some(c.k as i64),
        curve,
        chart,
        other,
    }
}

fn timing_section(r: &Report) -> Avail<Vec<(String, f64)>> {
    if r.timings.is_empty() {
        return Avail::No("report.json records no stage times".into());
    }
    Avail::Yes(
        r.timings
            .iter()
            .map(|t| (t.stage.clone(), t.seconds))
            .collect(),
    )
}

/// A section's fields as (name, short text), in the order written.
fn fields_as_text<T: serde::Serialize>(section: &T) -> Vec<(String, String)> {
    match serde_json::to_value(section) {
        Ok(Value::Object(o)) => o.iter().map(|(k, x)| (k.clone(), short_json(x))).collect(),
        _ => Vec::new(),
    }
}

/// The report.json fields that have a section of their own.
const INTERPRETED: [&str; 13] = [
    "format_version",
    "model",
    "normals",
    "materials",
    "ladder",
    "plausibility",
    "comparisons",
    "confidence",
    "trials",
    "chosen_trial",
    "components",
    "timings",
    "warnings",
];

/// Every other field of report.json, verbatim (`basis` as well: its note is the provenance).
fn other_facts(r: &Report) -> Vec<(String, String)> {
    let Ok(Value::Object(o)) = serde_json::to_value(r) else {
        return Vec::new();
    };
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
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

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
}
