//! A whole reconstruction, from a job to its [`Output`]: load and observe the job
//! (`prepare`), the basis (cache or build), the pure core, the photo/re-render comparison
//! per light image, and the report (`output::report_of`). Writes nothing; `output::write` does.

use super::compare::{Comparison, Thumbnail, compare_image_materials, compare_image_with};
use super::core::reconstruct_observations;
use super::job::Job;
use super::materials::{MaterialError, Materials, material_name, reconstruct_materials};
use super::nielsen::NielsenPrior;
use super::observe::Observation;
use super::output::{Output, report_of};
use super::prepare::{
    Observed, Prepared, ReconstructError, Scene, Settings, load_basis, prepare, segmentation_for,
};
use crate::brdf::basis::Basis;
use crate::brdf::basis_cache::CacheStatus;
use crate::brdf::merl::MerlTable;
use std::sync::Arc;
use std::time::Instant;

/// Reconstructs the BRDF of a job: loads and checks the job, then the basis (cache or build).
pub fn reconstruct(
    job: &Job,
    settings: &Settings,
    progress: &mut dyn FnMut(&str),
) -> Result<Output, ReconstructError> {
    let mut prepared = prepare(job, settings, progress)?;
    let t = Instant::now();
    progress("basis (cache or build)");
    let (basis, status) = load_basis(settings)?;
    prepared
        .timings
        .push(("basis".to_string(), t.elapsed().as_secs_f64()));
    let mut out = finish(job, settings, &basis, prepared, progress)?;
    out.report.basis.cache = Some(match status {
        CacheStatus::Hit(p) => format!("hit {}", p.display()),
        CacheStatus::Built(p) => format!("built {}", p.display()),
        CacheStatus::Rebuilt { path, reason } => format!("rebuilt {} ({reason})", path.display()),
    });
    Ok(out)
}

/// Reconstructs with a basis already in memory (benchmarks and ablations share one).
pub fn reconstruct_with_basis(
    job: &Job,
    settings: &Settings,
    basis: &Basis,
    progress: &mut dyn FnMut(&str),
) -> Result<Output, ReconstructError> {
    let prepared = prepare(job, settings, progress)?;
    finish(job, settings, basis, prepared, progress)
}

/// The core on a prepared job, then the MERL table and the report.
pub fn finish(
    job: &Job,
    settings: &Settings,
    basis: &Basis,
    prepared: Prepared,
    progress: &mut dyn FnMut(&str),
) -> Result<Output, ReconstructError> {
    let Prepared {
        scene,
        observed,
        refinement,
        mut timings,
    } = prepared;
    let prior = NielsenPrior {
        basis,
        settings: settings.nielsen,
    };
    let core_err = |source| ReconstructError::Core {
        job: job.source.clone(),
        source,
    };
    let mut materials = None;
    let mut material_cores = Vec::new();
    let fixed = observed.label_votes.fixed(scene.mesh.positions().len());
    // Label masks split the object into their materials even with one material asked (the
    // default): a user who drew labels wants them. Nothing is added to them then.
    let segment_settings = segmentation_for(settings.materials, fixed.is_some());
    if let Some(seg) = &segment_settings {
        let (m, cores) = reconstruct_materials(
            &scene.mesh,
            &observed.observations,
            fixed.as_ref(),
            &prior,
            &settings.core,
            seg,
            progress,
        )
        .map_err(|e| match e {
            MaterialError::Core { name, source } => ReconstructError::Material {
                job: job.source.clone(),
                name,
                source,
            },
        })?;
        timings.push(("materials".to_string(), m.segment_seconds));
        materials = Some(m);
        material_cores = cores;
    }
    // With several materials the report's main result is the largest material's (first).
    let mut cores = material_cores.into_iter();
    let core = match cores.next() {
        Some(c) => c,
        None => reconstruct_observations(&observed.observations, &prior, &settings.core, progress)
            .map_err(core_err)?,
    };
    for (i, c) in std::iter::once(&core).chain(cores.as_slice()).enumerate() {
        let prefix = match &materials {
            Some(m) if !m.results.is_empty() => format!("{}: ", material_name(i)),
            _ => String::new(),
        };
        timings.extend(c.timings.iter().map(|(s, t)| (format!("{prefix}{s}"), *t)));
    }
    let table = Arc::clone(&core.table);
    let t = Instant::now();
    progress("photo against re-render, per light image");
    let comparisons = match materials.as_ref().filter(|m| !m.results.is_empty()) {
        Some(m) => comparisons_materials(&scene, &observed, m),
        None => comparisons(&scene, &observed, &table),
    };
    timings.push(("compare".to_string(), t.elapsed().as_secs_f64()));
    let report = report_of(
        job,
        settings,
        basis,
        &scene,
        &observed,
        &core,
        &comparisons,
        refinement,
        timings,
        materials.as_ref(),
    );
    let refined_mesh = report
        .normals
        .as_ref()
        .is_some_and(|r| r.accepted)
        .then_some(scene.mesh);
    Ok(Output {
        table,
        materials,
        refined_mesh,
        core,
        observed,
        report,
        comparisons,
    })
}

/// Every light image beside its re-render, each pixel by its own material's table, with the
/// material map (`compare::compare_image_materials`).
fn comparisons_materials(scene: &Scene, observed: &Observed, m: &Materials) -> Vec<Comparison> {
    let tables: Vec<&MerlTable> = m.results.iter().map(|r| &*r.table).collect();
    comparisons_with(scene, observed, |index, thumb, obs| {
        compare_image_materials(index, thumb, obs, &tables, |o| {
            m.segmentation.label_of(&scene.mesh, o)
        })
    })
}

/// Every light image beside its re-render (`compare`).
fn comparisons(scene: &Scene, observed: &Observed, table: &MerlTable) -> Vec<Comparison> {
    comparisons_with(scene, observed, |index, thumb, obs| {
        compare_image_with(index, thumb, obs, |o| table.get(o.bin).unwrap_or([0.0; 3]))
    })
}

/// Every light image with a thumbnail, compared by `compare(index, thumbnail, its pixels)`.
fn comparisons_with(
    scene: &Scene,
    observed: &Observed,
    compare: impl Fn(usize, &Thumbnail, &[&Observation]) -> Comparison,
) -> Vec<Comparison> {
    scene
        .views
        .iter()
        .zip(&observed.thumbnails)
        .filter_map(|(v, thumb)| {
            let obs: Vec<&Observation> = observed
                .observations
                .iter()
                .filter(|o| o.image == v.index)
                .collect();
            Some(compare(v.index, thumb.as_ref()?, &obs))
        })
        .collect()
}
