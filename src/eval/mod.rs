//! Evaluation of the reconstruction on simulated scenes (METHOD.md section 7): the accuracy
//! grid of the paper (materials x meshes, leave-one-out basis, ablation of the three
//! assumptions, analytic baselines, rank of the chosen trial), and the speed and stability
//! sweeps. The `brdf-rig bench accuracy|speed|stability` commands are thin over this module.
//!
//! Ground truth is the neural fits of the MERL materials (Sztrajman et al. 2021): smooth
//! approximations of the MERL measurements, **not measured MERL data**. Every table this module
//! writes says so.
//!
//! Conventions: errors are those of `brdf::metrics` (docs/error-metrics.md), computed over every
//! `bin_step`-th MERL bin (bins below the horizon skipped); the target material is always left
//! out of the basis (`BasisSettings::exclude`). A scene is written once (`sim::job_scene`)
//! and loaded once; perturbations (image noise, clipping, light-direction error) are applied in
//! memory to the loaded images and light directions before observation, so every variant of a
//! scene sees the same pixels. An I/O edge: writes scene folders.

pub mod accuracy;
pub mod bench;
pub mod confidence;
pub mod external;
pub mod host;
pub mod materials;
pub mod meshes;
pub mod rig;
pub mod sweeps;

use crate::brdf::basis::Basis;
use crate::brdf::coords::MerlBin;
use crate::brdf::metrics::{ErrorReport, compare_values};
use crate::brdf::nbrdf::Nbrdf;
use crate::brdf::{BinValues, Brdf};
use crate::geometry::mesh::Mesh;
use crate::geometry::sfm_like::{SfmLikeParams, sfm_like};
use crate::reconstruct::core::{CoreError, CoreSettings, reconstruct_observations};
use crate::reconstruct::ladder::Family;
use crate::reconstruct::nielsen::{NielsenPrior, NielsenSettings};
use crate::reconstruct::observe::{Observation, ObserveSettings};
use crate::reconstruct::prepare::{
    Prepared, ReconstructError, Scene, Settings, load_scene, material_labels, observe_scene,
    observe_scene_and_pixels, refine_prepared,
};
use crate::reconstruct::refine::{
    RefineReport, RefineSettings, normal_error_deg, pixel_normal_error_deg,
};
use crate::reconstruct::segment::SegmentSettings;
use crate::reconstruct::{Job, prior::Candidate};
use crate::render::probe::{
    ProbeRenders, ProbeSettings, RenderedErrors, SphereProbe, compare as compare_rendered,
};
use crate::sim::job_scene::{SceneSpec, write_scene};
use nalgebra::{Rotation3, Unit, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::path::Path;
use std::sync::OnceLock;
use std::time::Instant;

/// The paper's six target materials (METHOD.md section 7).
pub const PAPER_MATERIALS: [&str; 6] = [
    "alum-bronze",
    "fruitwood-241",
    "pink-fabric",
    "blue-acrylic",
    "pink-fabric2",
    "green-latex",
];

/// Failures of an evaluation run.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    #[error("material {0:?} is not among the neural MERL fits")]
    UnknownMaterial(String),
    #[error("writing the simulated scene in {dir}: {source}")]
    Scene {
        dir: std::path::PathBuf,
        source: std::io::Error,
    },
    #[error(transparent)]
    Reconstruct(#[from] ReconstructError),
    #[error("reconstruction core: {0}")]
    Core(#[from] CoreError),
    #[error(transparent)]
    Material(#[from] crate::reconstruct::materials::MaterialError),
    #[error("basis: {0}")]
    Basis(#[from] crate::brdf::basis_cache::BasisCacheError),
    #[error("writing the reconstruction to {dir}: {source}")]
    Output {
        dir: std::path::PathBuf,
        source: crate::reconstruct::output::OutputError,
    },
    #[error("scene {scene} of index.json: the basis without {exclude:?} (its basis_exclude)")]
    SceneBasis {
        scene: String,
        exclude: Vec<String>,
        #[source]
        source: crate::brdf::basis_cache::BasisCacheError,
    },
}

/// The errors of docs/error-metrics.md, serialisable: rendered (the headline:
/// `environment`) and tabulated.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Errors {
    /// Relative L2 error of the sphere rendered under the standard environment
    /// (`render::probe`): the headline number.
    pub environment: f64,
    /// The same under the probe's five novel directional lights.
    pub lights: f64,
    /// PSNR of the environment render after the probe's fixed tone map, dB.
    pub environment_psnr_db: f64,
    pub relative: f64,
    pub cosine_weighted: f64,
    pub near_specular: f64,
    /// `cosine_weighted` over theta_h >= 2 degrees (everything but the peak).
    pub cosine_weighted_off_peak: f64,
    /// Solid-angle weighted table error (docs/error-metrics.md).
    pub solid_angle: f64,
    /// Solid-angle weighted log-space error.
    pub log: f64,
}

impl Errors {
    fn from_parts(e: ErrorReport, r: RenderedErrors) -> Self {
        Self {
            environment: r.environment,
            lights: r.lights,
            environment_psnr_db: r.environment_psnr_db,
            relative: e.relative,
            cosine_weighted: e.cosine_weighted,
            near_specular: e.near_specular,
            cosine_weighted_off_peak: e.cosine_weighted_off_peak,
            solid_angle: e.solid_angle,
            log: e.log,
        }
    }
}

/// The sphere probe of every evaluation (built once per process: its quadrature does not
/// depend on the BRDF).
pub fn probe() -> &'static SphereProbe {
    static PROBE: OnceLock<SphereProbe> = OnceLock::new();
    PROBE.get_or_init(|| SphereProbe::standard_serial(ProbeSettings::default()))
}

/// The ground truth tabulated at the evaluation bins and rendered by the probe once, compared
/// with many candidates.
pub struct Truth {
    pub bins: Vec<usize>,
    pub values: Vec<[f64; 3]>,
    pub renders: ProbeRenders,
}

impl Truth {
    /// Every `bin_step`-th MERL bin (the metric skips those below the horizon), and the probe.
    pub fn new(brdf: &dyn BinValues, bin_step: usize) -> Self {
        let bins: Vec<usize> = (0..90 * 90 * 180).step_by(bin_step.max(1)).collect();
        let values = brdf.values_at(&bins);
        Self {
            bins,
            values,
            renders: probe().render(brdf),
        }
    }

    pub fn errors_of(&self, rec: &dyn BinValues) -> Errors {
        let table = compare_values(&self.bins, &self.values, &rec.values_at(&self.bins));
        let rendered = compare_rendered(&self.renders, &probe().render(rec));
        Errors::from_parts(table, rendered)
    }

    pub fn errors_of_candidate(&self, c: &dyn Candidate) -> Errors {
        self.errors_of(&CandidateValues(c))
    }
}

/// The mean of several candidates, as bin values.
struct MeanOf<'a>(&'a [&'a dyn Candidate]);

impl BinValues for MeanOf<'_> {
    fn values_at(&self, bins: &[usize]) -> Vec<[f64; 3]> {
        let n = self.0.len().max(1) as f64;
        bins.iter()
            .map(|&b| {
                let mut v = [0.0; 3];
                for c in self.0 {
                    let f = c.eval_bin(b);
                    for k in 0..3 {
                        v[k] += f[k] / n;
                    }
                }
                v
            })
            .collect()
    }
}

pub use crate::reconstruct::prior::CandidateValues;

/// An analytic BRDF seen as bin values (evaluated at the bin centres).
pub struct BrdfValues<'a>(pub &'a dyn Brdf);

impl BinValues for BrdfValues<'_> {
    fn values_at(&self, bins: &[usize]) -> Vec<[f64; 3]> {
        bins.iter()
            .map(|&b| match MerlBin::from_index(b) {
                Some(bin) if bin.is_above_horizon() => {
                    let (wi, wo) = bin.centre_directions();
                    self.0.eval_local(&wi, &wo)
                }
                _ => [0.0; 3],
            })
            .collect()
    }
}

/// Lambert and Lambert+GGX fitted by least squares to the same observed pixels the
/// reconstruction sees; their errors against the truth.
pub fn baseline_errors(truth: &Truth, obs: &[Observation]) -> (Option<Errors>, Option<Errors>) {
    let (lambert, ggx) = crate::reconstruct::baselines::fit_baselines(obs);
    (
        lambert.map(|b| truth.errors_of(&BrdfValues(&b))),
        ggx.map(|b| truth.errors_of(&BrdfValues(&b))),
    )
}

/// Loads a neural MERL fit by name from the loaded set.
pub fn find_material<'a>(
    materials: &'a [(String, Nbrdf)],
    name: &str,
) -> Result<&'a Nbrdf, EvalError> {
    materials
        .iter()
        .find(|(n, _)| n == name)
        .map(|(_, m)| m)
        .ok_or_else(|| EvalError::UnknownMaterial(name.to_string()))
}

/// Writes a simulated scene: `truth_mesh` rendered with `brdf`, the job naming an SfM-like copy.
pub fn write_case(
    dir: &Path,
    truth_mesh: &Mesh,
    sfm: &SfmLikeParams,
    brdf: &dyn Brdf,
    spec: &SceneSpec,
) -> Result<Job, EvalError> {
    let job_mesh = sfm_like(truth_mesh, sfm);
    write_scene(dir, truth_mesh, &job_mesh, brdf, spec).map_err(|source| EvalError::Scene {
        dir: dir.to_path_buf(),
        source,
    })
}

/// Perturbations applied to a loaded scene before observation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Perturb {
    /// Gaussian image noise, standard deviation as a fraction of each image's brightest value.
    pub image_noise: f64,
    /// Clip each image at this fraction of its brightest value and declare that level saturated
    /// (the observation step drops clipped pixels); 1.0 = no clipping.
    pub clip_fraction: f64,
    /// Light-direction error, degrees: each view's light is turned by this angle about a random
    /// axis perpendicular to it.
    pub light_error_deg: f64,
    /// Use only the first `views` light images (all when `None`).
    pub views: Option<usize>,
    pub seed: u64,
}

impl Default for Perturb {
    fn default() -> Self {
        Self {
            image_noise: 0.0,
            clip_fraction: 1.0,
            light_error_deg: 0.0,
            views: None,
            seed: 0,
        }
    }
}

fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    // Box-Muller.
    let u1: f64 = rng.gen_range(f64::EPSILON..1.0);
    let u2: f64 = rng.r#gen();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// Loads a job, applies `perturb` and observes every light image.
pub fn observe_case(
    job: &Job,
    observe: &ObserveSettings,
    perturb: &Perturb,
) -> Result<Vec<Observation>, EvalError> {
    let scene = load_case(job, observe, perturb)?;
    Ok(observe_scene(&scene, observe).observations)
}

/// Loads a job and applies `perturb` to its images and lights.
pub fn load_case(
    job: &Job,
    observe: &ObserveSettings,
    perturb: &Perturb,
) -> Result<Scene, EvalError> {
    let settings = Settings {
        observe: *observe,
        ..Settings::default()
    };
    let mut scene = load_scene(job, &settings)?;
    if let Some(n) = perturb.views {
        scene.views.truncate(n.max(1));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(perturb.seed);
    for view in &mut scene.views {
        // `load_scene` holds every image
        let Some(image) = view.image.as_mut() else {
            continue;
        };
        let peak = image.data().iter().copied().fold(0.0f32, f32::max);
        if perturb.image_noise > 0.0 {
            let sd = perturb.image_noise * f64::from(peak);
            for v in image.data_mut() {
                *v = (f64::from(*v) + sd * gaussian(&mut rng)).max(0.0) as f32;
            }
        }
        if perturb.clip_fraction < 1.0 {
            let level = perturb.clip_fraction as f32 * peak;
            for v in image.data_mut() {
                *v = v.min(level);
            }
            view.saturation = Some(f64::from(level));
        }
        if perturb.light_error_deg > 0.0 {
            let l = view.light_world;
            let helper = if l.x.abs() < 0.9 {
                Vector3::x()
            } else {
                Vector3::y()
            };
            let u = l.cross(&helper).normalize();
            let w = l.cross(&u);
            let phi: f64 = rng.gen_range(0.0..std::f64::consts::TAU);
            let axis = Unit::new_normalize(u * phi.cos() + w * phi.sin());
            view.light_world =
                Rotation3::from_axis_angle(&axis, perturb.light_error_deg.to_radians()) * l;
        }
    }
    Ok(scene)
}

/// The normals of a scene's mesh against the truth, before and after a refinement.
#[derive(Clone, Debug, Serialize)]
pub struct NormalStudy {
    pub report: RefineReport,
    /// Vertices that some pixel shows (the errors are over these).
    pub seen_vertices: usize,
    /// Angle to the true vertex normal, degrees: median and mean.
    pub median_before_deg: f64,
    pub mean_before_deg: f64,
    pub median_after_deg: f64,
    pub mean_after_deg: f64,
    /// Angle between the normal a pixel gets (its face's corners blended) and the true one,
    /// over every refinement pixel, degrees: median before and after.
    pub pixel_median_before_deg: f64,
    pub pixel_median_after_deg: f64,
}

/// Observations of a loaded scene with its normals refined (`reconstruct::refine`), those
/// without, and the normals measured against `truth` (same vertices and faces as the scene's
/// mesh, as `geometry::sfm_like` makes them).
pub struct RefinedCase {
    /// With the refined normals when the refinement was accepted, else the unrefined ones.
    pub observations: Vec<Observation>,
    pub unrefined: Vec<Observation>,
    pub study: Option<NormalStudy>,
}

/// Refines the normals of `scene` and observes it both ways. `materials`: find the object's
/// materials first and give each its own reflectance table (`prepare::material_labels`), as
/// `reconstruct --materials auto --refine-normals` does.
pub fn refine_case(
    scene: Scene,
    observe: &ObserveSettings,
    refine: &RefineSettings,
    materials: Option<SegmentSettings>,
    truth: &Mesh,
) -> RefinedCase {
    let (observed, pixels) = observe_scene_and_pixels(&scene, observe, refine.edge_margin_px);
    let unrefined = observed.observations.clone();
    let before = scene.mesh.vertex_normals().to_vec();
    let mut prepared = Prepared {
        scene,
        observed,
        refinement: None,
        timings: Vec::new(),
    };
    let labels = material_labels(
        &prepared.scene.mesh,
        &prepared.observed,
        materials,
        &mut |_| {},
    );
    let seen = refine_prepared(
        &mut prepared,
        Some(pixels.clone()),
        observe,
        refine,
        &labels,
        &mut |_| {},
    );
    let after = prepared.scene.mesh.vertex_normals();
    let study = if truth.positions().len() == before.len() {
        let tn = truth.vertex_normals();
        let faces = prepared.scene.mesh.faces();
        match (
            normal_error_deg(&before, tn, &seen),
            normal_error_deg(after, tn, &seen),
            pixel_normal_error_deg(faces, &pixels, &before, tn),
            pixel_normal_error_deg(faces, &pixels, after, tn),
            prepared.refinement.clone(),
        ) {
            (Some(b), Some(a), Some(pb), Some(pa), Some(report)) => Some(NormalStudy {
                pixel_median_before_deg: pb.0,
                pixel_median_after_deg: pa.0,
                report,
                seen_vertices: seen.iter().filter(|s| **s).count(),
                median_before_deg: b.0,
                mean_before_deg: b.1,
                median_after_deg: a.0,
                mean_after_deg: a.1,
            }),
            _ => None,
        }
    } else {
        None
    };
    RefinedCase {
        observations: prepared.observed.observations,
        unrefined,
        study,
    }
}

/// Observations of a loaded scene with its mesh replaced by the exact one (the reference a
/// refinement is measured against).
pub fn exact_case(mut scene: Scene, observe: &ObserveSettings, truth: &Mesh) -> Vec<Observation> {
    scene.mesh = truth.clone();
    observe_scene(&scene, observe).observations
}

/// One reconstruction of one scene, scored.
#[derive(Clone, Debug, Serialize)]
pub struct RunResult {
    /// Errors of the chosen trial.
    pub chosen: Errors,
    pub chosen_trial: usize,
    /// Per trial (index order): similarity and error (`None` when the trial failed).
    pub trials: Vec<(f64, Option<Errors>)>,
    /// Rank (1 = lowest cosine-weighted error) of the chosen trial among the trials that fitted.
    pub chosen_rank: usize,
    pub k: usize,
    pub observed_pixels: usize,
    pub reliable_pixels: usize,
    /// Errors of the trial with the lowest relative pixel error over all observations (a
    /// diagnostic: would a scale-sensitive choice beat eq. 3's cosine similarity?).
    pub pixel_choice: Option<Errors>,
    /// Errors of the mean of all fitted trials (a diagnostic: would averaging beat choosing?).
    pub trial_mean: Option<Errors>,
    /// What the pipeline said of its own result (no truth involved).
    pub confidence: crate::reconstruct::confidence::Confidence,
    /// The model reported, and the ladder that chose it.
    pub model: crate::reconstruct::core::ModelReport,
    pub ladder: Option<crate::reconstruct::ladder::Ladder>,
    pub plausibility: crate::reconstruct::plausible::Plausibility,
    /// The chosen family's fit against the truth as fitted (before the plausibility step).
    pub chosen_fitted: Option<Errors>,
    /// Every other family's final fit against the truth (as fitted), when the settings keep
    /// them: would another rung have been better?
    pub alternatives: Vec<(Family, Errors)>,
    pub seconds: f64,
}

/// Runs the reconstruction core on observations and scores every trial against the truth.
pub fn run_core(
    truth: &Truth,
    observations: &[Observation],
    basis: &Basis,
    core: &CoreSettings,
    nielsen: NielsenSettings,
) -> Result<RunResult, EvalError> {
    let prior = NielsenPrior {
        basis,
        settings: nielsen,
    };
    // every trial is scored below, so every trial's fit is kept
    let core = &CoreSettings {
        keep_trial_fits: true,
        ..core.clone()
    };
    let t = Instant::now();
    let out = reconstruct_observations(observations, &prior, core, &mut |_| {})?;
    let seconds = t.elapsed().as_secs_f64();
    // What is written: the chosen model, tabulated and made plausible.
    let chosen = truth.errors_of(&out.table);
    // The chosen trial's candidate was moved out (into `out.brdf`, or replaced by the chosen
    // model); it is scored here as fitted, the other trials too.
    let chosen_basis = match out.model.family {
        Family::Basis => Some(truth.errors_of_candidate(out.brdf.as_ref())),
        _ => None,
    };
    let trials: Vec<(f64, Option<Errors>)> = out
        .trials
        .iter()
        .enumerate()
        .map(|(i, tr)| {
            let e = if i == out.chosen_trial {
                chosen_basis
            } else {
                tr.candidate
                    .as_ref()
                    .map(|c| truth.errors_of_candidate(c.as_ref()))
            };
            (tr.similarity, e)
        })
        .collect();
    let fitted: Vec<&dyn Candidate> = out
        .trials
        .iter()
        .filter_map(|t| t.candidate.as_deref())
        .chain((out.model.family == Family::Basis).then_some(out.brdf.as_ref()))
        .collect();
    let trial_mean = (fitted.len() > 1).then(|| truth.errors_of(&MeanOf(&fitted)));
    let pixel_choice = fitted
        .iter()
        .map(|c| {
            (
                crate::reconstruct::components::held_out_error(*c, observations),
                c,
            )
        })
        .filter(|(e, _)| e.is_finite())
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, c)| truth.errors_of_candidate(*c));
    let chosen_rank = 1 + trials
        .iter()
        .filter_map(|(_, e)| e.as_ref())
        .filter(|e| e.environment < chosen.environment)
        .count();
    let alternatives = out
        .alternatives
        .iter()
        .map(|(f, c)| (*f, truth.errors_of_candidate(c.as_ref())))
        .collect();
    Ok(RunResult {
        chosen,
        chosen_trial: out.chosen_trial,
        trials,
        chosen_rank,
        k: out.components.k,
        observed_pixels: observations.len(),
        reliable_pixels: out.reliable_pixels,
        trial_mean,
        pixel_choice,
        confidence: out.confidence.clone(),
        model: out.model.clone(),
        ladder: out.ladder.clone(),
        plausibility: out.plausibility.clone(),
        chosen_fitted: Some(truth.errors_of_candidate(out.brdf.as_ref())),
        alternatives,
        seconds,
    })
}

/// Mean and sample standard deviation.
pub fn mean_sd(xs: &[f64]) -> (f64, f64) {
    let n = xs.len() as f64;
    if xs.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let m = xs.iter().sum::<f64>() / n;
    let sd = if xs.len() > 1 {
        (xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
    } else {
        0.0
    };
    (m, sd)
}
