//! A whole reconstruction, from a job to its [`Output`]: load and observe the job
//! (`prepare`), the basis (cache or build), the pure core, the photo/re-render comparison
//! per light image, and the report (`output::report_of`). Writes nothing; `output::write` does.

use super::compare::{Comparison, compare_image};
use super::core::reconstruct_observations;
use super::job::Job;
use super::nielsen::NielsenPrior;
use super::observe::Observation;
use super::output::{Output, report_of};
use super::prepare::{Observed, Prepared, ReconstructError, Scene, Settings, load_basis, prepare};
use crate::brdf::basis::Basis;
use crate::brdf::basis_cache::CacheStatus;
use crate::brdf::merl::MerlTable;
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
    let core = reconstruct_observations(&observed.observations, &prior, &settings.core, progress)
        .map_err(|source| ReconstructError::Core {
        job: job.source.clone(),
        source,
    })?;
    timings.extend(core.timings.iter().cloned());
    let table = core.table.clone();
    let t = Instant::now();
    progress("photo against re-render, per light image");
    let comparisons = comparisons(&scene, &observed, &table);
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
    );
    let refined_mesh = report
        .normals
        .as_ref()
        .is_some_and(|r| r.accepted)
        .then_some(scene.mesh);
    Ok(Output {
        table,
        refined_mesh,
        core,
        observed,
        report,
        comparisons,
    })
}

/// Every light image beside its re-render (`compare`).
fn comparisons(scene: &Scene, observed: &Observed, table: &MerlTable) -> Vec<Comparison> {
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
            Some(compare_image(v.index, thumb.as_ref()?, &obs, table))
        })
        .collect()
}
