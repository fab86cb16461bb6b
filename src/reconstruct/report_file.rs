//! `report.json`, the reconstruction's report: the owner of its format. [`Report`] is the one
//! serde type for it: `brdf-rig reconstruct` writes it ([`write`], built by
//! `output::report_of`), and every reader (the HTML report, the benchmarks, the tests) reads it
//! back with [`read`], so a change of the format is a compile error in every reader.
//!
//! Each section's type is owned where the section is built (`ladder::Ladder`,
//! `refine::RefineReport`, `confidence::Confidence`, ...); this file only puts them together.
//!
//! Version [`REPORT_FORMAT_VERSION`]. Version 1 files (and files without `format_version`) were
//! read as untyped JSON, whatever fields they had; they are refused with a version error, and
//! re-running `brdf-rig reconstruct` on the job makes a current one.
//!
//! Paths inside the file are absolute (`job`, the light images) or relative to the file's
//! folder (the comparison panels).

use super::components::ComponentChoice;
use super::confidence::Confidence;
use super::core::{CoreSettings, ModelReport};
use super::ladder::Ladder;
use super::nielsen::NielsenSettings;
use super::observe::{DropCounts, ImageCounts, ObserveSettings};
use super::plausible::Plausibility;
use super::refine::RefineReport;
use super::trials::Trial;
use crate::format::{FormatError, Versioned, version_1};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The reconstruction's MERL table, in the output folder.
pub const BRDF_FILE: &str = "brdf.binary";
/// The reconstruction's report, in the output folder.
pub const REPORT_FILE: &str = "report.json";
/// The version written, and the only one read.
pub const REPORT_FORMAT_VERSION: u32 = 2;

const FORMAT: Versioned = Versioned {
    what: "reconstruction report",
    version: REPORT_FORMAT_VERSION,
    remedy: "re-run `brdf-rig reconstruct` on the job to write a current one",
};

/// One light image's comparison, as reported.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ComparisonReport {
    /// Index of the light image in the job.
    pub image: usize,
    /// The light image.
    pub photo: PathBuf,
    /// The panel (photo | re-render | error, and the material map with several materials),
    /// relative to the folder of `report.json`.
    pub file: String,
    /// Relative error of the re-render over the image's observed pixels.
    pub fit_error: f64,
    /// The chosen model's error on this image while it (or its blocks) was held out.
    pub held_out_error: Option<f64>,
    pub observed_pixels: usize,
    /// With several materials: per material (in the order of `materials.materials`), its
    /// pixels in this image and their error; the panel then has a fourth image, the material
    /// map. Absent for one material, and in reports written before it existed.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub materials: Vec<super::compare::MaterialFit>,
}

/// The panel file of light image `index`, relative to the output folder.
pub fn comparison_file(index: usize) -> String {
    format!("compare/view_{index:02}.png")
}

/// Time spent in one stage.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StageTiming {
    pub stage: String,
    pub seconds: f64,
}

/// The basis the reconstruction used.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BasisReport {
    pub materials: usize,
    pub excluded: Vec<String>,
    pub stride: [usize; 3],
    pub rows: usize,
    pub components: usize,
    /// Whether it came from the cache, and where (`None` for a basis handed in).
    pub cache: Option<String>,
    /// Where the prior comes from (`output::PROVENANCE`): shown beside the result.
    pub note: String,
}

/// The settings the reconstruction ran with.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SettingsReport {
    pub observe: ObserveSettings,
    pub core: CoreSettings,
    pub nielsen: NielsenSettings,
    pub png_scale: f32,
    pub saturation: Option<f64>,
}

/// The whole `report.json`.
#[derive(Serialize, Deserialize)]
pub struct Report {
    /// [`REPORT_FORMAT_VERSION`].
    #[serde(default = "version_1")]
    pub format_version: u32,
    /// The job file, absolute.
    pub job: PathBuf,
    pub settings: SettingsReport,
    pub basis: BasisReport,
    pub mesh_vertices: usize,
    pub mesh_faces: usize,
    pub images: Vec<ImageCounts>,
    pub dropped: DropCounts,
    pub observed_pixels: usize,
    pub reliable_pixels: usize,
    pub dropped_by_curvature: usize,
    pub curvature_threshold: Option<f64>,
    pub components: ComponentChoice,
    pub trials: Vec<Trial>,
    pub chosen_trial: usize,
    /// The model reported and why (`reconstruct::ladder`).
    pub model: ModelReport,
    /// Every rung's held-out score; `None` when the ladder did not run (a fixed k).
    pub ladder: Option<Ladder>,
    /// What the plausibility step found and did (`reconstruct::plausible`).
    pub plausibility: Plausibility,
    /// Per light image: the photo beside its re-render (`compare/view_NN.png`, relative to
    /// this file's folder) and the errors.
    pub comparisons: Vec<ComparisonReport>,
    /// How far the result can be trusted, and why not (`reconstruct::confidence`).
    pub confidence: Confidence,
    /// What the normal refinement did (`reconstruct::refine`); `None` when it was off.
    pub normals: Option<RefineReport>,
    /// What the segmentation found when it ran (`--materials`; `reconstruct::materials`): the
    /// content of `materials.json`, with no per-material entries when it found one material.
    /// Absent in reports written before it existed.
    #[serde(default)]
    pub materials: Option<super::materials::MaterialsFile>,
    pub timings: Vec<StageTiming>,
    pub peak_memory_bytes: Option<u64>,
    pub warnings: Vec<String>,
}

/// Reads `DIR/report.json`.
pub fn read(dir: &Path) -> Result<Report, FormatError> {
    FORMAT.read(&dir.join(REPORT_FILE))
}

/// Writes `DIR/report.json` atomically.
pub fn write(dir: &Path, report: &Report) -> Result<(), FormatError> {
    FORMAT.write(&dir.join(REPORT_FILE), report)
}
