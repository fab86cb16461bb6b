//! Several materials on one object (issue #17): the segmentation (`segment`), with the
//! materials the job's label masks give fixed where they give them (`mask_labels`), one BRDF
//! per material by the whole core (model ladder, trials, plausibility, confidence), and the
//! owner of `materials.json`, its name, version and the names of the files beside it. The
//! per-material fits are pure; only [`write`] and [`read`] touch files.
//!
//! `materials.json` version 1 gained `mask_labels` (top level) and `mask_label`,
//! `mask_vertices` (per material) when label masks came; they read as "no label mask" when
//! absent, which is what a file written before them means, and a reader that predates them
//! ignores them, so the version stayed 1. Likewise `boundary_pixels` (per material) and
//! `settings.fit_interior_only` (session 27): absent, they read as 0 and `false`, what a file
//! written before them did (every labelled pixel in its material's fit); and
//! `settings.merge_same_body` (session 34): absent, `false` (no merge by body colour). And
//! `ladder` and `plausibility` (per material, session 37: every rung's held-out score and what
//! the plausibility step did, as `report.json` gives them for the whole result): absent, `None`.

use super::confidence::Confidence;
use super::core::{CoreError, CoreOutput, CoreSettings, ModelReport, reconstruct_observations};
use super::ladder::Ladder;
use super::mask_labels::FixedLabels;
use super::observation::Observation;
use super::plausible::Plausibility;
use super::prior::Prior;
use super::segment::{CountScore, SegmentSettings, Segmentation, fit_groups, segment_with_labels};
use crate::brdf::merl::MerlTable;
use crate::format::{FormatError, Versioned};
use crate::geometry::mesh::Mesh;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::sync::Arc;

/// The per-material summary, in the result folder.
pub const MATERIALS_FILE: &str = "materials.json";
/// The folder of the per-material MERL tables, in the result folder.
pub const MATERIALS_DIR: &str = "materials";
/// The mesh with a per-vertex material label, in the result folder.
pub const MATERIAL_MAP_FILE: &str = "material_map.ply";
/// Version of `materials.json`; a reader refuses any other.
pub const MATERIALS_FORMAT_VERSION: u32 = 1;

const FORMAT: Versioned = Versioned {
    what: "materials file (materials.json)",
    version: MATERIALS_FORMAT_VERSION,
    remedy: "re-run `brdf-rig reconstruct` with this version",
};

/// The name of material `i` (0-based): `material-1`, `material-2`, ...
pub fn material_name(i: usize) -> String {
    format!("material-{}", i + 1)
}

/// The MERL file of a material, relative to the result folder.
pub fn material_file(name: &str) -> String {
    format!("{MATERIALS_DIR}/{name}.binary")
}

/// One material's result.
pub struct MaterialResult {
    pub name: String,
    /// Its observations (pixels).
    pub observed_pixels: usize,
    /// Of those, the pixels on faces across a boundary and those of another material's colour
    /// near it, left out of its fit ([`SegmentSettings::fit_interior_only`],
    /// [`SegmentSettings::foreign_colour_rings`]).
    pub boundary_pixels: usize,
    /// Mesh vertices observed with this label.
    pub observed_vertices: usize,
    /// Mean chromaticity of its pixels (r, g, b shares).
    pub chromaticity: [f64; 3],
    /// The label the job's masks give it (`None`: found by the segmentation).
    pub mask_label: Option<u32>,
    /// Vertices the masks fixed to it.
    pub mask_vertices: usize,
    /// Its result as written (`materials/NAME.binary`; its core's, shared).
    pub table: Arc<MerlTable>,
    pub model: ModelReport,
    /// Its model ladder (every rung's held-out score); `None` when the ladder did not run.
    pub ladder: Option<Ladder>,
    /// What the plausibility step found and did to its table.
    pub plausibility: Plausibility,
    pub confidence: Confidence,
}

/// The segmentation and, when it found more than one material, a result per material,
/// largest first (by observed pixels; the labels are renumbered to that order).
pub struct Materials {
    pub segmentation: Segmentation,
    /// Per material of `segmentation` (its order): the label the job's masks give it, `None`
    /// for a material the segmentation found.
    pub mask_labels: Vec<Option<u32>>,
    pub results: Vec<MaterialResult>,
    /// Seconds spent finding the materials (not fitting them).
    pub segment_seconds: f64,
    pub settings: SegmentSettings,
    /// The mesh the labels belong to (`material_map.ply`).
    pub mesh: Mesh,
}

/// Finds the materials of `mesh` from `observations`, the vertices `fixed` by the job's label
/// masks kept on their materials; when there is more than one, runs the core on each
/// material's pixels and returns the cores too (in the order of `results`). With one material
/// `results` is empty: the caller runs the core on every pixel as without segmentation.
pub fn reconstruct_materials(
    mesh: &Mesh,
    observations: &[Observation],
    fixed: Option<&FixedLabels>,
    prior: &dyn Prior,
    core_settings: &CoreSettings,
    settings: &SegmentSettings,
    progress: &mut dyn FnMut(&str),
) -> Result<(Materials, Vec<CoreOutput>), MaterialError> {
    let t = std::time::Instant::now();
    progress("materials (segmentation, count chosen on held-out images)");
    let mut segmentation = segment_with_labels(
        mesh,
        observations,
        settings,
        fixed.map_or(&[][..], |f| &f.vertex[..]),
    );
    let segment_seconds = t.elapsed().as_secs_f64();
    let mut mask_labels: Vec<Option<u32>> = (0..segmentation.count)
        .map(|i| {
            let given = i < segmentation.given;
            fixed.and_then(|f| f.mask_labels.get(i).copied().filter(|_| given))
        })
        .collect();
    let mut results = Vec::new();
    let mut cores = Vec::new();
    if segmentation.count > 1 {
        let (mut groups, mut boundary) = fit_groups(mesh, &segmentation, observations, settings);
        // largest first, labels renumbered to match
        let mut order: Vec<usize> = (0..groups.len()).collect();
        order.sort_by_key(|&i| std::cmp::Reverse(groups[i].len() + boundary[i]));
        let mut new_label = vec![0u32; order.len()];
        for (new, &old) in order.iter().enumerate() {
            new_label[old] = new as u32;
        }
        for l in &mut segmentation.vertex_labels {
            *l = new_label[*l as usize];
        }
        segmentation.observed_vertices = order
            .iter()
            .map(|&i| segmentation.observed_vertices[i])
            .collect();
        segmentation.chromaticity = order
            .iter()
            .map(|&i| segmentation.chromaticity[i])
            .collect();
        segmentation.fixed_vertices = order
            .iter()
            .map(|&i| segmentation.fixed_vertices[i])
            .collect();
        mask_labels = order.iter().map(|&i| mask_labels[i]).collect();
        boundary = order.iter().map(|&i| boundary[i]).collect();
        let groups: Vec<Vec<Observation>> = order
            .iter()
            .map(|&i| std::mem::take(&mut groups[i]))
            .collect();
        let named = |i: usize| match mask_labels[i] {
            Some(l) => format!("{} (mask label {l})", material_name(i)),
            None => material_name(i),
        };
        // A given material whose every pixel was dropped (labels drawn only where the object
        // is in shadow, say) has nothing to fit: said before any core runs, not after.
        if let Some(i) = groups.iter().position(Vec::is_empty) {
            return Err(MaterialError::Core {
                name: named(i),
                source: CoreError::NoObservations,
            });
        }
        // The materials' cores are independent: they run side by side (each is parallel
        // inside too), each saying its progress into its own list, replayed in order after.
        progress(&format!(
            "fitting {} materials side by side: {}",
            groups.len(),
            groups
                .iter()
                .enumerate()
                .map(|(i, obs)| format!("{} {} pixels", named(i), obs.len()))
                .collect::<Vec<_>>()
                .join(", ")
        ));
        let fitted: Vec<(Vec<String>, Result<CoreOutput, CoreError>)> = groups
            .par_iter()
            .map(|obs| {
                let mut said = Vec::new();
                let core = reconstruct_observations(obs, prior, core_settings, &mut |m: &str| {
                    said.push(m.to_string())
                });
                (said, core)
            })
            .collect();
        for (i, ((said, core), obs)) in fitted.into_iter().zip(&groups).enumerate() {
            let name = material_name(i);
            let named = named(i);
            for m in &said {
                progress(&format!("{named}: {m}"));
            }
            let core = core.map_err(|source| MaterialError::Core {
                name: named,
                source,
            })?;
            results.push(MaterialResult {
                name,
                observed_pixels: obs.len() + boundary[i],
                boundary_pixels: boundary[i],
                observed_vertices: segmentation.observed_vertices[i],
                chromaticity: segmentation.chromaticity[i],
                mask_label: mask_labels[i],
                mask_vertices: segmentation.fixed_vertices[i],
                table: Arc::clone(&core.table),
                model: core.model.clone(),
                ladder: core.ladder.clone(),
                plausibility: core.plausibility.clone(),
                confidence: core.confidence.clone(),
            });
            cores.push(core);
        }
    }
    Ok((
        Materials {
            segmentation,
            mask_labels,
            results,
            segment_seconds,
            settings: *settings,
            mesh: mesh.clone(),
        },
        cores,
    ))
}

#[derive(Debug, thiserror::Error)]
pub enum MaterialError {
    #[error("{name}: {source}")]
    Core {
        name: String,
        #[source]
        source: CoreError,
    },
}

/// One material in `materials.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MaterialEntry {
    pub name: String,
    /// Its MERL table, relative to the folder of `materials.json`.
    pub file: String,
    pub observed_pixels: usize,
    /// Of `observed_pixels`, those on faces across a boundary and (since session 51) those of
    /// another material's colour near it, left out of its fit (0 in a file written before they
    /// were).
    #[serde(default)]
    pub boundary_pixels: usize,
    pub observed_vertices: usize,
    /// Mean chromaticity of its pixels (r, g, b shares).
    pub chromaticity: [f64; 3],
    /// The label the job's label masks give it; `None` when the segmentation found it.
    #[serde(default)]
    pub mask_label: Option<u32>,
    /// Vertices the label masks fixed to it (the rest joined it by the segmentation).
    #[serde(default)]
    pub mask_vertices: usize,
    /// The model the ladder chose (its label) and why.
    pub model: String,
    pub model_reason: String,
    /// The verdict (`high`, `medium`, `low`) and its reasons.
    pub confidence: String,
    pub confidence_reasons: Vec<String>,
    pub held_out_error: Option<f64>,
    /// Its model ladder, every rung's held-out score (`None` in a file written before it was
    /// kept, or when the ladder did not run).
    #[serde(default)]
    pub ladder: Option<Ladder>,
    /// What the plausibility step found and did to its table (`None` in a file written before
    /// it was kept).
    #[serde(default)]
    pub plausibility: Option<Plausibility>,
}

/// `materials.json`: how many materials and why, and one entry per material.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MaterialsFile {
    pub format_version: u32,
    pub count: usize,
    /// Why this count (one sentence).
    pub reason: String,
    /// Every count tried, with its held-out image error.
    pub scores: Vec<CountScore>,
    pub settings: SegmentSettings,
    /// The labels the job's label masks give (ascending), each a material; empty without
    /// label masks.
    #[serde(default)]
    pub mask_labels: Vec<u32>,
    /// The mesh with a per-vertex `label` (0-based, the order of `materials`), relative to
    /// the folder of `materials.json`.
    pub material_map: String,
    pub materials: Vec<MaterialEntry>,
}

impl MaterialsFile {
    /// The file's content for these materials (`results` must be non-empty to list any).
    pub fn of(m: &Materials) -> Self {
        Self {
            format_version: MATERIALS_FORMAT_VERSION,
            count: m.segmentation.count,
            reason: m.segmentation.reason.clone(),
            scores: m.segmentation.scores.clone(),
            settings: m.settings,
            mask_labels: {
                let mut l: Vec<u32> = m.mask_labels.iter().flatten().copied().collect();
                l.sort_unstable();
                l
            },
            material_map: MATERIAL_MAP_FILE.to_string(),
            materials: m
                .results
                .iter()
                .map(|r| MaterialEntry {
                    name: r.name.clone(),
                    file: material_file(&r.name),
                    observed_pixels: r.observed_pixels,
                    boundary_pixels: r.boundary_pixels,
                    observed_vertices: r.observed_vertices,
                    chromaticity: r.chromaticity,
                    mask_label: r.mask_label,
                    mask_vertices: r.mask_vertices,
                    model: model_label(&r.model),
                    model_reason: r.model.reason.clone(),
                    confidence: r.confidence.level.to_string(),
                    confidence_reasons: r.confidence.reasons.clone(),
                    held_out_error: r.confidence.held_out_error,
                    ladder: r.ladder.clone(),
                    plausibility: Some(r.plausibility.clone()),
                })
                .collect(),
        }
    }
}

fn model_label(m: &ModelReport) -> String {
    match (m.k, m.eta) {
        (Some(k), Some(eta)) => format!("{} (k = {k}, eta = {eta})", m.family),
        _ => m.family.to_string(),
    }
}

/// Writes `materials.json`, the per-material tables and the labelled mesh into `dir`.
pub fn write(dir: &Path, m: &Materials) -> Result<(), MaterialsWriteError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| MaterialsWriteError::Io { path, source }
    };
    let mdir = dir.join(MATERIALS_DIR);
    std::fs::create_dir_all(&mdir).map_err(io(&mdir))?;
    // side by side: each table's encoding and writing overlap the others'
    m.results
        .par_iter()
        .try_for_each(|r| r.table.write(&dir.join(material_file(&r.name))))?;
    crate::geometry::mesh_io::write_ply_labelled(
        &dir.join(MATERIAL_MAP_FILE),
        &m.mesh,
        &m.segmentation.vertex_labels,
        crate::geometry::mesh_io::PlyEncoding::BinaryLittleEndian,
    )?;
    FORMAT.write(&dir.join(MATERIALS_FILE), &MaterialsFile::of(m))?;
    Ok(())
}

#[derive(Debug, thiserror::Error)]
pub enum MaterialsWriteError {
    #[error("{path}: {source}")]
    Io {
        path: std::path::PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Format(#[from] FormatError),
    #[error(transparent)]
    Table(#[from] crate::brdf::merl::MerlError),
    #[error(transparent)]
    Mesh(#[from] crate::geometry::mesh_io::MeshIoError),
}

/// Reads `dir/materials.json`; `Ok(None)` when the folder has none (one material, or a
/// reconstruction without `--materials`).
pub fn read(dir: &Path) -> Result<Option<MaterialsFile>, FormatError> {
    match FORMAT.read(&dir.join(MATERIALS_FILE)) {
        Ok(f) => Ok(Some(f)),
        Err(e) if e.is_not_found() => Ok(None),
        Err(e) => Err(e),
    }
}

#[cfg(test)]
mod tests {
    use super::super::prior::synthetic::CosinePrior;
    use super::super::segment::tests::{ggx, grid, scene};
    use super::*;

    #[test]
    fn a_file_written_before_boundary_pixels_reads_back_with_every_pixel_fitted() {
        let entry = MaterialEntry {
            name: material_name(0),
            file: material_file(&material_name(0)),
            observed_pixels: 10,
            boundary_pixels: 3,
            observed_vertices: 4,
            chromaticity: [1.0 / 3.0; 3],
            mask_label: None,
            mask_vertices: 0,
            model: "basis".into(),
            model_reason: String::new(),
            confidence: "high".into(),
            confidence_reasons: Vec::new(),
            held_out_error: None,
            ladder: None,
            plausibility: None,
        };
        let file = MaterialsFile {
            format_version: MATERIALS_FORMAT_VERSION,
            count: 2,
            reason: String::new(),
            scores: Vec::new(),
            settings: SegmentSettings::default(),
            mask_labels: Vec::new(),
            material_map: MATERIAL_MAP_FILE.into(),
            materials: vec![entry],
        };
        assert!(
            file.settings.fit_interior_only,
            "the default leaves them out"
        );
        let mut old = serde_json::to_value(&file).unwrap();
        assert!(
            old["settings"]
                .as_object_mut()
                .unwrap()
                .remove("fit_interior_only")
                .is_some()
        );
        for key in [
            "merge_same_body",
            "boundary_rings",
            "foreign_colour_rings",
            "relabel_passes",
        ] {
            assert!(
                old["settings"]
                    .as_object_mut()
                    .unwrap()
                    .remove(key)
                    .is_some(),
                "{key}"
            );
        }
        assert!(
            old["materials"][0]
                .as_object_mut()
                .unwrap()
                .remove("boundary_pixels")
                .is_some()
        );
        for key in ["ladder", "plausibility"] {
            assert!(
                old["materials"][0]
                    .as_object_mut()
                    .unwrap()
                    .remove(key)
                    .is_some()
            );
        }
        let back: MaterialsFile = serde_json::from_value(old).unwrap();
        assert!(back.materials[0].ladder.is_none() && back.materials[0].plausibility.is_none());
        assert!(!back.settings.fit_interior_only);
        assert!(!back.settings.merge_same_body);
        // written before session 51: no ring margin and no colour rule
        assert_eq!(back.settings.boundary_rings, 0);
        assert_eq!(back.settings.foreign_colour_rings, 0);
        assert_ne!(SegmentSettings::default().foreign_colour_rings, 0);
        // written before session 52: the labels' boundary as the smoothing left it
        assert_eq!(back.settings.relabel_passes, 0);
        assert_eq!(back.materials[0].boundary_pixels, 0);
        assert_eq!(back.materials[0].observed_pixels, 10);
    }

    #[test]
    fn a_mask_material_without_pixels_is_an_error_naming_it_before_any_fit() {
        // Pixels only on the left of a 16 x 16 grid; the masks give material 1 to the left and
        // material 2 to vertices no pixel shows (the label drawn where the object is in shadow).
        let mesh = grid(16);
        let obs: Vec<Observation> = scene(
            &mesh,
            &[ggx([0.6, 0.2, 0.1], 0.3), ggx([0.1, 0.3, 0.6], 0.3)],
            6.0,
            8,
        )
        .into_iter()
        .filter(|o| o.position.x < 9.0)
        .collect();
        let vertex: Vec<Option<u32>> = mesh
            .positions()
            .iter()
            .map(|p| match p.x {
                x if x < 4.0 => Some(0),
                x if x > 12.5 => Some(1),
                _ => None,
            })
            .collect();
        let fixed = FixedLabels {
            vertex,
            mask_labels: vec![1, 2],
            ties: 0,
        };
        let mut said = Vec::new();
        let result = reconstruct_materials(
            &mesh,
            &obs,
            Some(&fixed),
            &CosinePrior { k: 3 },
            &CoreSettings::default(),
            &SegmentSettings::default(),
            &mut |m: &str| said.push(m.to_string()),
        );
        let Err(e) = result else {
            panic!("fitted a material no pixel shows");
        };
        let MaterialError::Core { name, source } = &e;
        assert_eq!(source, &CoreError::NoObservations, "{e}");
        assert!(name.contains("mask label 2"), "{e}");
        assert!(
            !said.iter().any(|m| m.contains("fitting")),
            "no core ran: {said:?}"
        );
    }
}
