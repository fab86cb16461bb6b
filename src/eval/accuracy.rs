//! The paper's simulation grid (METHOD.md section 7): each target material on each mesh, seen
//! through an SfM-like mesh, reconstructed with a basis that leaves the target out; the
//! ablation of the three assumptions (paper Fig. 5), the Lambert and Lambert+GGX baselines fitted
//! to the same pixels, and the rank of the chosen trial among all trials (paper Fig. 6).

use super::{
    Errors, EvalError, Perturb, RunResult, Truth, baseline_errors, find_material, observe_case,
    run_core, write_case,
};
use crate::brdf::basis::BasisSettings;
use crate::brdf::basis_cache;
use crate::brdf::nbrdf::Nbrdf;
use crate::geometry::mesh::Mesh;
use crate::geometry::sfm_like::SfmLikeParams;
use crate::reconstruct::core::CoreSettings;
use crate::reconstruct::nielsen::NielsenSettings;
use crate::reconstruct::observe::ObserveSettings;
use crate::reconstruct::reliable::ReliableSettings;
use crate::reconstruct::synthetic::SceneSpec;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// An ablation variant: which of the three assumptions are on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Variant {
    pub curvature: bool,
    pub monotonicity: bool,
    pub brightest: bool,
}

impl Variant {
    pub const ALL: Variant = Variant {
        curvature: true,
        monotonicity: true,
        brightest: true,
    };

    /// Paper Fig. 5: none, each alone, all three.
    pub fn ablation() -> Vec<Variant> {
        let v = |c, m, b| Variant {
            curvature: c,
            monotonicity: m,
            brightest: b,
        };
        vec![
            v(false, false, false),
            v(true, false, false),
            v(false, true, false),
            v(false, false, true),
            Variant::ALL,
        ]
    }

    pub fn label(&self) -> String {
        let on: Vec<&str> = [
            (self.curvature, "curvature"),
            (self.monotonicity, "monotonicity"),
            (self.brightest, "brightest"),
        ]
        .iter()
        .filter(|(b, _)| *b)
        .map(|(_, n)| *n)
        .collect();
        match on.len() {
            0 => "none".to_string(),
            3 => "all three".to_string(),
            _ => on.join(" + "),
        }
    }

    pub fn apply(&self, r: &mut ReliableSettings) {
        r.use_curvature = self.curvature;
        r.use_monotonicity = self.monotonicity;
        r.use_brightest = self.brightest;
    }
}

/// What the grid runs.
#[derive(Clone, Debug, Serialize)]
pub struct AccuracySpec {
    pub materials: Vec<String>,
    /// (name, mesh in its own units)
    #[serde(skip)]
    pub meshes: Vec<(String, Mesh)>,
    pub mesh_names: Vec<String>,
    pub views: usize,
    pub width: usize,
    pub height: usize,
    #[serde(skip)]
    pub basis: BasisSettings,
    pub basis_stride: [usize; 3],
    pub basis_components: usize,
    pub core: CoreSettings,
    #[serde(skip)]
    pub nielsen: NielsenSettings,
    pub sfm_iterations: usize,
    pub sfm_noise_rel: f64,
    pub variants: Vec<Variant>,
    pub bin_step: usize,
    /// Seeds per scene (each moves the SfM-like noise and the trials' pixel draws).
    pub seeds: u64,
}

/// One scene: a material on a mesh.
#[derive(Clone, Debug, Serialize)]
pub struct SceneResult {
    pub material: String,
    pub mesh: String,
    pub seed: u64,
    pub observed_pixels: usize,
    /// Materials in the basis used, and whether the target was among them (must be false).
    pub basis_materials: usize,
    pub target_in_basis: bool,
    /// (variant, result) in the order of `AccuracySpec::variants`.
    pub variants: Vec<(Variant, Result<RunResult, String>)>,
    pub lambert: Option<Errors>,
    pub lambert_ggx: Option<Errors>,
    pub seconds: f64,
}

impl SceneResult {
    /// The run with all three assumptions, when it ran and succeeded.
    pub fn all(&self) -> Option<&RunResult> {
        self.variants
            .iter()
            .find(|(v, _)| *v == Variant::ALL)
            .and_then(|(_, r)| r.as_ref().ok())
    }
}

/// Runs the grid. `scratch` receives the scene folders; `progress` gets one line per step.
pub fn run(
    spec: &AccuracySpec,
    materials: &[(String, Nbrdf)],
    cache_dir: &Path,
    scratch: &Path,
    progress: &mut dyn FnMut(&str),
    on_scene: &mut dyn FnMut(&SceneResult),
) -> Result<Vec<SceneResult>, EvalError> {
    let mut results = Vec::new();
    for name in &spec.materials {
        let truth_brdf = find_material(materials, name)?;
        let mut bs = spec.basis.clone();
        bs.exclude = vec![name.clone()];
        progress(&format!("{name}: basis without {name} (cache or build)"));
        let t = Instant::now();
        let (basis, status) = basis_cache::load_or_build(&bs, materials, cache_dir)?;
        progress(&format!(
            "{name}: basis ready in {:.1} s ({status:?})",
            t.elapsed().as_secs_f64()
        ));
        let truth = Truth::new(truth_brdf, spec.bin_step);
        for ((mesh_name, mesh), seed) in spec
            .meshes
            .iter()
            .flat_map(|m| (0..spec.seeds.max(1)).map(move |s| (m, s)))
        {
            let t = Instant::now();
            let dir = scratch.join(format!("{mesh_name}-{name}-{seed}"));
            let sfm = SfmLikeParams {
                iterations: spec.sfm_iterations,
                noise_rel: spec.sfm_noise_rel,
                seed: 7 + seed,
                ..SfmLikeParams::default()
            };
            let scene = SceneSpec {
                views: spec.views,
                width: spec.width,
                height: spec.height,
                ..SceneSpec::default()
            };
            progress(&format!(
                "{name} on {mesh_name}, seed {seed}: rendering the scene"
            ));
            let job = write_case(&dir, mesh, &sfm, truth_brdf, &scene)?;
            let obs = observe_case(&job, &ObserveSettings::default(), &Perturb::default())?;
            let (lambert, lambert_ggx) = baseline_errors(&truth, &obs);
            let mut variants = Vec::new();
            for v in &spec.variants {
                progress(&format!("{name} on {mesh_name}: {}", v.label()));
                let mut core = spec.core.clone();
                core.trials.seed += seed;
                v.apply(&mut core.reliable);
                let r =
                    run_core(&truth, &obs, &basis, &core, spec.nielsen).map_err(|e| e.to_string());
                variants.push((*v, r));
            }
            let r = SceneResult {
                material: name.clone(),
                mesh: mesh_name.clone(),
                seed,
                observed_pixels: obs.len(),
                basis_materials: basis.materials().len(),
                target_in_basis: basis.materials().iter().any(|m| m == name),
                variants,
                lambert,
                lambert_ggx,
                seconds: t.elapsed().as_secs_f64(),
            };
            on_scene(&r);
            results.push(r);
        }
    }
    Ok(results)
}

fn f3(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.3}")
    } else {
        "-".to_string()
    }
}

/// The material, with the seed when the grid has several.
fn scene_label(spec: &AccuracySpec, r: &SceneResult) -> String {
    if spec.seeds > 1 {
        format!("{} (seed {})", r.material, r.seed)
    } else {
        r.material.clone()
    }
}

/// Per (mesh, material): means over seeds of ours and the baselines, and the confidence given.
fn means_over_seeds(results: &[SceneResult]) -> String {
    let mut keys: Vec<(&str, &str)> = Vec::new();
    for r in results {
        if !keys.contains(&(r.mesh.as_str(), r.material.as_str())) {
            keys.push((r.mesh.as_str(), r.material.as_str()));
        }
    }
    let mut s = "\n## Means over seeds\n\nE_c mean +- sd over the seeds; the ratios are of the means \
                 (a Lambert+GGX mean above 1.5 means its least-squares fit diverged in some seed); \
                 off-peak = E_c over theta_h >= 2 degrees, all but the specular peak, means; \
                 confidence = how often the pipeline called its result low / medium / high.\n\n\
                 | mesh | material | seeds | ours E_c | Lambert E_c | Lambert+GGX E_c | ratio Lambert | ratio L+GGX | ours E_c off-peak | L+GGX E_c off-peak | confidence low/medium/high |\n\
                 |---|---|---|---|---|---|---|---|---|---|---|\n"
        .to_string();
    for (mesh, material) in keys {
        let rs: Vec<&SceneResult> = results
            .iter()
            .filter(|r| r.mesh == mesh && r.material == material)
            .collect();
        let ours: Vec<f64> = rs
            .iter()
            .filter_map(|r| r.all().map(|a| a.chosen.cosine_weighted))
            .collect();
        let lam: Vec<f64> = rs
            .iter()
            .filter_map(|r| r.lambert.map(|e| e.cosine_weighted))
            .collect();
        let ggx: Vec<f64> = rs
            .iter()
            .filter_map(|r| r.lambert_ggx.map(|e| e.cosine_weighted))
            .collect();
        let ours_off: Vec<f64> = rs
            .iter()
            .filter_map(|r| r.all().map(|a| a.chosen.cosine_weighted_off_peak))
            .collect();
        let ggx_off: Vec<f64> = rs
            .iter()
            .filter_map(|r| r.lambert_ggx.map(|e| e.cosine_weighted_off_peak))
            .collect();
        let mut conf = [0usize; 3];
        for r in &rs {
            if let Some(a) = r.all() {
                conf[a.confidence.level as usize] += 1;
            }
        }
        let (m, sd) = super::mean_sd(&ours);
        let (ml, _) = super::mean_sd(&lam);
        let (mg, _) = super::mean_sd(&ggx);
        s += &format!(
            "| {mesh} | {material} | {} | {} +- {} | {} | {} | {} | {} | {} | {} | {}/{}/{} |\n",
            rs.len(),
            f3(m),
            f3(sd),
            f3(ml),
            f3(mg),
            f3(ml / m),
            f3(mg / m),
            f3(super::mean_sd(&ours_off).0),
            f3(super::mean_sd(&ggx_off).0),
            conf[0],
            conf[1],
            conf[2]
        );
    }
    s
}

fn opt(e: Option<&Errors>, f: impl Fn(&Errors) -> f64) -> String {
    e.map_or_else(|| "-".to_string(), |e| f3(f(e)))
}

/// The markdown tables of a grid run.
pub fn markdown(
    spec: &AccuracySpec,
    results: &[SceneResult],
    command: &str,
    machine: &str,
) -> String {
    let mut s = String::new();
    s += "# Accuracy on simulated scenes\n\n";
    s += "Generated by `brdf-rig bench accuracy`; do not edit by hand.\n\n";
    s += "**Ground truth is the neural fits of the MERL materials (Sztrajman et al. 2021): smooth \
          approximations of the MERL measurements, not measured MERL data.** Each target is left \
          out of the basis it is reconstructed with.\n\n";
    s += &format!("Command: `{command}`\n\nMachine: {machine}\n\n");
    s += &format!(
        "Scenes: {} views of {}x{} px, light-view angle spread 10-150 degrees; reconstruction from an \
         SfM-like mesh (Taubin smoothing, {} iterations, normal noise {} of the mean edge); basis \
         stride {:?}, {} components; {} trials of {} samples; errors over every {}th MERL bin \
         (docs/error-metrics.md).\n\n",
        spec.views,
        spec.width,
        spec.height,
        spec.sfm_iterations,
        spec.sfm_noise_rel,
        spec.basis_stride,
        spec.basis_components,
        spec.core.trials.trials,
        spec.core.trials.samples,
        spec.bin_step
    );

    s += "## Errors: ours (all three assumptions) against the baselines\n\n";
    s += "Cosine-weighted relative error E_c (relative error E, near-specular error E_s). \
          Ratio = baseline E_c / our E_c; the target is >= 2.\n\n";
    s += "| mesh | material | seed | ours E_c | Lambert E_c | Lambert+GGX E_c | ratio Lambert | ratio L+GGX | ours E | ours E_s | L+GGX E | L+GGX E_s | k | pixels | confidence (trial disagreement) |\n";
    s += "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for r in results {
        let all = r.all();
        let ours = all.map(|a| a.chosen);
        let ratio = |b: Option<Errors>| match (b, ours) {
            (Some(b), Some(o)) if o.cosine_weighted > 0.0 => {
                format!("{:.2}", b.cosine_weighted / o.cosine_weighted)
            }
            _ => "-".to_string(),
        };
        s += &format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
            r.mesh,
            r.material,
            r.seed,
            opt(ours.as_ref(), |e| e.cosine_weighted),
            opt(r.lambert.as_ref(), |e| e.cosine_weighted),
            opt(r.lambert_ggx.as_ref(), |e| e.cosine_weighted),
            ratio(r.lambert),
            ratio(r.lambert_ggx),
            opt(ours.as_ref(), |e| e.relative),
            opt(ours.as_ref(), |e| e.near_specular),
            opt(r.lambert_ggx.as_ref(), |e| e.relative),
            opt(r.lambert_ggx.as_ref(), |e| e.near_specular),
            all.map_or("-".to_string(), |a| a.k.to_string()),
            r.observed_pixels,
            all.map_or("-".to_string(), |a| format!(
                "{} ({})",
                a.confidence.level,
                a.confidence
                    .trial_disagreement
                    .map_or("-".to_string(), |d| format!("{d:.2}"))
            ))
        );
    }

    if spec.seeds > 1 {
        s += &means_over_seeds(results);
    }

    if spec.variants.len() > 1 {
        s += "\n## Ablation (paper Fig. 5): cosine-weighted error of the chosen trial\n\n";
        s += "Relative error in brackets. A failed run shows its reason.\n\n| mesh | material |";
        for v in &spec.variants {
            s += &format!(" {} |", v.label());
        }
        s += "\n|---|---|";
        for _ in &spec.variants {
            s += "---|";
        }
        s += "\n";
        for r in results {
            s += &format!("| {} | {} |", r.mesh, scene_label(spec, r));
            for (_, res) in &r.variants {
                match res {
                    Ok(a) => {
                        s += &format!(
                            " {} ({}) |",
                            f3(a.chosen.cosine_weighted),
                            f3(a.chosen.relative)
                        )
                    }
                    Err(e) => s += &format!(" failed: {} |", e.replace('|', "/")),
                }
            }
            s += "\n";
        }
        // Mean over scenes per variant.
        s += "| **mean** | |";
        for i in 0..spec.variants.len() {
            let xs: Vec<f64> = results
                .iter()
                .filter_map(|r| r.variants.get(i).and_then(|(_, x)| x.as_ref().ok()))
                .map(|a| a.chosen.cosine_weighted)
                .collect();
            let (m, _) = super::mean_sd(&xs);
            s += &format!(" {} |", f3(m));
        }
        s += "\n";
    }

    s += "\n## Similarity against error (paper Fig. 6): rank of the chosen trial\n\n";
    s += "All three assumptions on. Rank 1 = the chosen trial (highest cosine similarity with the \
          images) has the lowest cosine-weighted error of all trials.\n\n";
    s += "| mesh | material | chosen trial | rank | trials fitted | best trial E_c | chosen E_c | worst trial E_c |\n|---|---|---|---|---|---|---|---|\n";
    let mut top3 = 0;
    let mut n = 0;
    for r in results {
        if let Some(a) = r.all() {
            let es: Vec<f64> = a
                .trials
                .iter()
                .filter_map(|(_, e)| e.map(|e| e.cosine_weighted))
                .collect();
            let best = es.iter().copied().fold(f64::INFINITY, f64::min);
            let worst = es.iter().copied().fold(0.0, f64::max);
            n += 1;
            if a.chosen_rank <= 3 {
                top3 += 1;
            }
            s += &format!(
                "| {} | {} | {} | {} | {} | {} | {} | {} |\n",
                r.mesh,
                scene_label(spec, r),
                a.chosen_trial,
                a.chosen_rank,
                es.len(),
                f3(best),
                f3(a.chosen.cosine_weighted),
                f3(worst)
            );
        }
    }
    s += &format!(
        "\nChosen trial among the 3 most accurate in {top3} of {n} scenes (paper: 5 of 6).\n"
    );
    s += "\n## Time per scene\n\n| mesh | material | seconds (render + observe + all variants) |\n|---|---|---|\n";
    for r in results {
        s += &format!(
            "| {} | {} | {:.1} |\n",
            r.mesh,
            scene_label(spec, r),
            r.seconds
        );
    }
    s
}
