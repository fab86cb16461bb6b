//! The report of a reconstruction and the files written for it: `brdf.binary` (MERL),
//! `report.json` (its format is owned by `report_file`; [`report_of`] fills it from what the
//! stages made), sphere renders of the result (`sphere.exr`, linear; `sphere.png`, preview),
//! the photo/re-render panels, and `mesh_refined.ply` when the normals were refined.
//!
//! The sphere is seen by a camera on +z looking at the origin, lit from 45 degrees above-right in
//! the camera's plane (a fixed, documented view, so reports compare across runs).
//! Files are written atomically (`atomic::write_atomic`); with several materials `brdf.binary`
//! is a link to (or copy of) the largest material's file (`atomic::link_or_copy_atomic`).

use super::compare::Comparison;
use super::core::CoreOutput;
use super::job::Job;
use super::prepare::{Observed, Scene, Settings};
use super::report_file::{
    self, BRDF_FILE, BasisReport, ComparisonReport, REPORT_FORMAT_VERSION, Report, SettingsReport,
    StageTiming, comparison_file,
};
use super::trials::Trial;
use crate::brdf::basis::Basis;
use crate::brdf::merl::MerlTable;
use crate::geometry::camera::{Intrinsics, Pose};
use crate::geometry::mesh::Mesh;
use crate::geometry::mesh_io::{PlyEncoding, write_ply};
use crate::imageio::{self, ExrPrecision};
use crate::render::image::LinearImage;
use crate::render::light::DirectionalLight;
use crate::render::sphere::{Sphere, render_sphere};
use nalgebra::{Point3, Vector3};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Said wherever a result made from the neural fits is reported.
pub const PROVENANCE: &str = "basis built from neural fits of the MERL materials (Sztrajman et al. 2021), smooth approximations of the measurements, not measured MERL data";

/// The report of a reconstruction, from what each stage made.
// One argument per stage whose output the report records; a struct would only rename them.
#[allow(clippy::too_many_arguments)]
pub(super) fn report_of(
    job: &Job,
    settings: &Settings,
    basis: &Basis,
    scene: &Scene,
    observed: &Observed,
    core: &CoreOutput,
    comparisons: &[super::compare::Comparison],
    normals: Option<super::refine::RefineReport>,
    timings: Vec<(String, f64)>,
    materials: Option<&super::materials::Materials>,
) -> Report {
    let s = basis.settings().stride;
    let mut warnings = scene.warnings.clone();
    if let Some(note) = &core.components.note {
        warnings.push(format!("components: {note}"));
    }
    Report {
        format_version: REPORT_FORMAT_VERSION,
        // Absolute, so the report finds the job (and its session) from any folder: a path
        // relative to the caller's folder means nothing beside report.json.
        job: std::path::absolute(&job.source).unwrap_or_else(|_| job.source.clone()),
        settings: SettingsReport {
            observe: settings.observe,
            core: settings.core.clone(),
            nielsen: settings.nielsen,
            png_scale: settings.png_scale,
            saturation: settings.saturation,
        },
        basis: BasisReport {
            materials: basis.materials().len(),
            excluded: basis.settings().exclude.clone(),
            stride: [s.theta_h, s.theta_d, s.phi_d],
            rows: basis.n_rows(),
            components: basis.basis_components(),
            cache: None,
            note: PROVENANCE.to_string(),
        },
        materials: materials.map(super::materials::MaterialsFile::of),
        mesh_vertices: scene.mesh.positions().len(),
        mesh_faces: scene.mesh.faces().len(),
        images: observed.images.clone(),
        dropped: observed.dropped,
        observed_pixels: observed.observations.len(),
        reliable_pixels: core.reliable_pixels,
        dropped_by_curvature: core.dropped_by_curvature,
        curvature_threshold: core.curvature_threshold,
        components: core.components.clone(),
        trials: core
            .trials
            .iter()
            .map(|t| Trial {
                index: t.index,
                similarity: t.similarity,
                rejected_by_monotonicity: t.rejected_by_monotonicity,
                fitted_samples: t.fitted_samples,
                samples: t.samples.clone(),
                candidate: None,
            })
            .collect(),
        chosen_trial: core.chosen_trial,
        model: core.model.clone(),
        ladder: core.ladder.clone(),
        plausibility: core.plausibility.clone(),
        comparisons: comparisons
            .iter()
            .map(|c| ComparisonReport {
                image: c.image,
                photo: scene
                    .views
                    .iter()
                    .find(|v| v.index == c.image)
                    .map(|v| v.file.clone())
                    .unwrap_or_default(),
                file: comparison_file(c.image),
                fit_error: c.error,
                held_out_error: core
                    .ladder
                    .as_ref()
                    .and_then(|l| l.chosen().image_errors.get(c.image).copied().flatten()),
                observed_pixels: c.observed,
                materials: c.materials.clone(),
            })
            .collect(),
        confidence: core.confidence.clone(),
        normals,
        timings: timings
            .into_iter()
            .map(|(stage, seconds)| StageTiming { stage, seconds })
            .collect(),
        peak_memory_bytes: peak_memory_bytes(),
        warnings,
    }
}

/// The result of a reconstruction, before anything is written.
pub struct Output {
    /// The result (`brdf.binary`); with several materials, the largest material's (the core's
    /// table, shared).
    pub table: Arc<MerlTable>,
    /// What the segmentation found, when it ran (`Settings::materials`); the per-material
    /// results when it found more than one (`materials/`, `materials.json`,
    /// `material_map.ply`).
    pub materials: Option<super::materials::Materials>,
    pub core: CoreOutput,
    pub observed: Observed,
    pub report: Report,
    /// Per light image: the photo beside its re-render (written by `output::write`).
    pub comparisons: Vec<Comparison>,
    /// The mesh with its refined normals, when a normal refinement was accepted
    /// (`mesh_refined.ply`).
    pub refined_mesh: Option<Mesh>,
}

/// Peak resident memory of this process (VmHWM), bytes; `None` where /proc is unavailable.
pub fn peak_memory_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(transparent)]
    Merl(#[from] crate::brdf::merl::MerlError),
    #[error(transparent)]
    Image(#[from] imageio::ImageIoError),
    #[error(transparent)]
    Mesh(#[from] crate::geometry::mesh_io::MeshIoError),
    #[error(transparent)]
    Report(#[from] crate::format::FormatError),
    #[error(transparent)]
    Materials(#[from] super::materials::MaterialsWriteError),
}

/// A preview of a BRDF on a sphere (see the module header), `size` pixels square.
pub fn sphere_preview(table: &MerlTable, size: usize) -> LinearImage {
    let f = size as f64 * 1.6;
    let k = Intrinsics::pinhole(size, size, f, f, size as f64 / 2.0, size as f64 / 2.0);
    let pose = Pose::look_at(Point3::new(0.0, 0.0, 4.0), Point3::origin(), Vector3::y());
    let to_light = Vector3::new(1.0, 1.0, std::f64::consts::SQRT_2).normalize();
    let sphere = Sphere {
        centre: Point3::origin(),
        radius: 1.0,
    };
    match DirectionalLight::new(to_light, [1.0; 3]) {
        Some(light) => render_sphere(&sphere, table, &light, &k, &pose, [0.0; 3]),
        None => LinearImage::new(size, size),
    }
}

/// Writes `brdf.binary`, `report.json`, `sphere.exr`, `sphere.png` and the comparison panels
/// `compare/view_NN.png` into `dir` (created).
pub fn write(dir: &Path, output: &Output) -> Result<(), OutputError> {
    std::fs::create_dir_all(dir).map_err(|source| OutputError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    // With several materials `brdf.binary` is the largest material's table: its file, written
    // first, is linked there (a copy where the file system has no links), not written twice.
    let mut linked = None;
    if let Some(m) = output.materials.as_ref().filter(|m| !m.results.is_empty()) {
        super::materials::write(dir, m)?;
        linked = m
            .results
            .iter()
            .find(|r| Arc::ptr_eq(&r.table, &output.table))
            .map(|r| dir.join(super::materials::material_file(&r.name)));
    }
    let brdf = dir.join(BRDF_FILE);
    match linked {
        Some(src) => crate::atomic::link_or_copy_atomic(&src, &brdf)
            .map_err(|source| OutputError::Io { path: brdf, source })?,
        None => output.table.write(&brdf)?,
    }
    report_file::write(dir, &output.report)?;
    let sphere = sphere_preview(&output.table, 256);
    imageio::write_exr(&dir.join("sphere.exr"), &sphere, ExrPrecision::F32)?;
    imageio::write_preview_png(&dir.join("sphere.png"), &sphere, 0.0)?;
    if let Some(mesh) = &output.refined_mesh {
        write_ply(
            &dir.join("mesh_refined.ply"),
            mesh,
            PlyEncoding::BinaryLittleEndian,
        )?;
    }
    if !output.comparisons.is_empty() {
        let cdir = dir.join("compare");
        std::fs::create_dir_all(&cdir).map_err(|source| OutputError::Io {
            path: cdir.clone(),
            source,
        })?;
        for c in &output.comparisons {
            imageio::write_preview_png(&dir.join(comparison_file(c.image)), &c.panel, 0.0)?;
        }
    }
    Ok(())
}
