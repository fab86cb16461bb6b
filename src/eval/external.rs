//! Evaluation on scenes the project did not render: the folders written by
//! `scripts/render_recon_scenes.py` (Mitsuba 3, materials outside the MERL set, exact and
//! degraded meshes; docs/independent-scenes.md). Each job of each scene is reconstructed as a
//! user would (`reconstruct::reconstruct_with_basis`, the full basis: the materials are not in
//! it), the Lambert and Lambert + GGX baselines are fitted to the same observed pixels, and all
//! three are scored against the scene's truth table with the errors of `Truth`.
//!
//! The scene folders are read, never written. An I/O edge.

use super::{Errors, EvalError, Truth};
use crate::brdf::basis::Basis;
use crate::brdf::merl::MerlTable;
use crate::eval::BrdfValues;
use crate::reconstruct::baselines::fit_baselines;
use crate::reconstruct::confidence::Level;
use crate::reconstruct::core::ModelReport;
use crate::reconstruct::{Job, Settings, reconstruct_with_basis};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// `index.json` of a scene set.
#[derive(Debug, Deserialize)]
pub struct SceneIndex {
    pub scenes: BTreeMap<String, SceneEntry>,
}

/// One scene of `index.json`.
#[derive(Debug, Deserialize)]
pub struct SceneEntry {
    pub mesh: String,
    pub rig: String,
    pub material: String,
    /// Job variant (exact, realistic, poor, ..._path) -> job file, relative to the scene folder.
    pub jobs: BTreeMap<String, String>,
    #[serde(default)]
    pub median_normal_error_deg: BTreeMap<String, f64>,
    pub truth_table: String,
    /// Materials the basis must leave out for this scene (a truth of the measured kind, a
    /// tabulated neural MERL fit, must not be in the basis that reconstructs it).
    #[serde(default)]
    pub basis_exclude: Vec<String>,
}

/// Reads `DIR/index.json`.
pub fn read_index(dir: &Path) -> Result<SceneIndex, EvalError> {
    let path = dir.join("index.json");
    let text = std::fs::read_to_string(&path).map_err(|source| EvalError::Scene {
        dir: path.clone(),
        source,
    })?;
    serde_json::from_str(&text).map_err(|e| EvalError::Scene {
        dir: path,
        source: std::io::Error::other(e),
    })
}

/// One job's outcome.
#[derive(Clone, Debug, Serialize)]
pub struct ExternalResult {
    pub scene: String,
    pub mesh: String,
    pub rig: String,
    pub material: String,
    pub job: String,
    /// The reconstruction's seed (trials and held-out folds).
    pub seed: u64,
    pub median_normal_error_deg: Option<f64>,
    // Result<_, String> on purpose: a failed run's message is data written to the results'
    // JSON, not an error returned to a caller.
    pub ours: Result<Errors, String>,
    pub model: Option<ModelReport>,
    pub confidence: Option<Level>,
    pub lambert: Option<Errors>,
    pub lambert_ggx: Option<Errors>,
    pub seconds: f64,
}

impl ExternalResult {
    /// The better baseline's environment error / ours (above 1: ours is better).
    pub fn ratio(&self) -> Option<f64> {
        let ours = self.ours.as_ref().ok()?.environment;
        let base = [self.lambert, self.lambert_ggx]
            .iter()
            .flatten()
            .map(|e| e.environment)
            .fold(f64::INFINITY, f64::min);
        (base.is_finite() && ours > 0.0).then_some(base / ours)
    }
}

/// The basis for a scene, given the materials it must leave out (built once per list by the
/// caller).
pub type BasisFor<'a> = dyn FnMut(&[String]) -> Result<std::rc::Rc<Basis>, crate::brdf::basis_cache::BasisCacheError>
    + 'a;

/// Runs every selected job of every scene under `dir`, once per seed (`settings`' own seed
/// when `seeds` is empty).
#[allow(clippy::too_many_arguments)]
pub fn run(
    dir: &Path,
    jobs: &[String],
    seeds: &[u64],
    settings: &Settings,
    basis_for: &mut BasisFor<'_>,
    bin_step: usize,
    progress: &mut dyn FnMut(&str),
    on_result: &mut dyn FnMut(&ExternalResult),
) -> Result<Vec<ExternalResult>, EvalError> {
    let index = read_index(dir)?;
    let mut out = Vec::new();
    for (name, entry) in &index.scenes {
        let scene_dir = dir.join(name);
        let basis = basis_for(&entry.basis_exclude).map_err(|source| EvalError::SceneBasis {
            scene: name.clone(),
            exclude: entry.basis_exclude.clone(),
            source,
        })?;
        let truth_path = scene_dir.join(&entry.truth_table);
        let table = MerlTable::read(&truth_path).map_err(|e| EvalError::Scene {
            dir: truth_path.clone(),
            source: std::io::Error::other(e),
        })?;
        let truth = Truth::new(&table, bin_step);
        let seeds = if seeds.is_empty() {
            vec![settings.core.trials.seed]
        } else {
            seeds.to_vec()
        };
        for (job_name, &seed) in jobs.iter().flat_map(|j| seeds.iter().map(move |s| (j, s))) {
            let Some(file) = entry.jobs.get(job_name) else {
                continue;
            };
            let mut settings = settings.clone();
            settings.core.trials.seed = seed;
            let settings = &settings;
            progress(&format!("{name}: {job_name}, seed {seed}"));
            let t = Instant::now();
            let job_path: PathBuf = scene_dir.join(file);
            let mut r = ExternalResult {
                scene: name.clone(),
                mesh: entry.mesh.clone(),
                rig: entry.rig.clone(),
                material: entry.material.clone(),
                job: job_name.clone(),
                seed,
                median_normal_error_deg: entry
                    .median_normal_error_deg
                    .get(job_name.trim_end_matches("_path"))
                    .copied(),
                ours: Err("not run".into()),
                model: None,
                confidence: None,
                lambert: None,
                lambert_ggx: None,
                seconds: 0.0,
            };
            match Job::from_file(&job_path)
                .map_err(|e| e.to_string())
                .and_then(|job| {
                    reconstruct_with_basis(&job, settings, &basis, &mut |_| {})
                        .map_err(|e| e.to_string())
                }) {
                Ok(o) => {
                    r.ours = Ok(truth.errors_of(&o.table));
                    r.model = Some(o.core.model.clone());
                    r.confidence = Some(o.core.confidence.level);
                    let (l, g) = fit_baselines(&o.observed.observations);
                    r.lambert = l.map(|b| truth.errors_of(&BrdfValues(&b)));
                    r.lambert_ggx = g.map(|b| truth.errors_of(&BrdfValues(&b)));
                }
                Err(e) => r.ours = Err(e),
            }
            r.seconds = t.elapsed().as_secs_f64();
            on_result(&r);
            out.push(r);
        }
    }
    Ok(out)
}

fn f3(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.3}")
    } else {
        "-".to_string()
    }
}

/// The markdown page of a run.
pub fn markdown(results: &[ExternalResult], command: &str, machine: &str) -> String {
    let mut s = String::new();
    s += "# Accuracy on scenes rendered by an independent renderer\n\n";
    s += "Generated by `brdf-rig bench external`; do not edit by hand. The scenes are \
          rendered by Mitsuba 3 (docs/independent-scenes.md), with materials that are not in the \
          MERL set or with MERL-format tables (`merl-NAME`: a neural MERL fit tabulated, read by \
          scripts/independent/merl_bsdf.py); their truth is the Mitsuba BSDF tabulated at the \
          MERL bin centres. The basis is the neural-fit basis (neural fits of the MERL \
          materials, Sztrajman et al. 2021: approximations, not measured MERL data), without \
          the materials a scene names in `basis_exclude` (its own, for a `merl-NAME` scene). Errors as in \
          docs/error-metrics.md; env = the rendered environment error (the headline).\n\n";
    s += &format!("Command: `{command}`\n\nMachine: {machine}\n\n");
    s += "## Ours against the better of Lambert and Lambert + GGX, per mesh\n\n";
    s += "| mesh given | jobs | ours better | ours worse by > 10 % | ratio geometric mean | min | max |\n|---|---|---|---|---|---|---|\n";
    let mut kinds: Vec<&str> = results.iter().map(|r| r.job.as_str()).collect();
    kinds.dedup();
    kinds.sort_unstable();
    kinds.dedup();
    for kind in kinds {
        let ratios: Vec<f64> = results
            .iter()
            .filter(|r| r.job == kind)
            .filter_map(ExternalResult::ratio)
            .collect();
        if ratios.is_empty() {
            continue;
        }
        let gm = (ratios.iter().map(|x| x.ln()).sum::<f64>() / ratios.len() as f64).exp();
        s += &format!(
            "| {kind} | {} | {} | {} | {} | {} | {} |\n",
            ratios.len(),
            ratios.iter().filter(|&&x| x > 1.0).count(),
            ratios.iter().filter(|&&x| x < 1.0 / 1.1).count(),
            f3(gm),
            f3(ratios.iter().copied().fold(f64::INFINITY, f64::min)),
            f3(ratios.iter().copied().fold(0.0, f64::max)),
        );
    }
    s += &per_scene(results);
    s += "\n## Per job\n\n| scene | mesh given | seed | median normal error deg | ours env | model | Lambert env | L+GGX env | ratio | ours lights | ours E_sa | ours log | confidence | seconds |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for r in results {
        let ours = r.ours.as_ref().ok();
        s += &format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.1} |\n",
            r.scene,
            r.job,
            r.seed,
            r.median_normal_error_deg
                .map_or("-".to_string(), |x| format!("{x:.1}")),
            match &r.ours {
                Ok(e) => f3(e.environment),
                Err(e) => format!("failed: {}", e.replace('|', "/")),
            },
            r.model.as_ref().map_or("-".to_string(), |m| match m.k {
                Some(k) => format!("{} k={k}", m.family),
                None => m.family.to_string(),
            }),
            r.lambert.map_or("-".to_string(), |e| f3(e.environment)),
            r.lambert_ggx.map_or("-".to_string(), |e| f3(e.environment)),
            r.ratio().map_or("-".to_string(), |x| format!("{x:.2}")),
            ours.map_or("-".to_string(), |e| f3(e.lights)),
            ours.map_or("-".to_string(), |e| f3(e.solid_angle)),
            ours.map_or("-".to_string(), |e| f3(e.log)),
            r.confidence.map_or("-".to_string(), |c| c.to_string()),
            r.seconds
        );
    }
    s
}

fn geometric_mean(xs: &[f64]) -> f64 {
    (xs.iter().map(|x| x.ln()).sum::<f64>() / xs.len().max(1) as f64).exp()
}

/// Per scene and job, over its seeds: the environment errors' means and the ratio's geometric
/// mean and minimum (empty with one seed per job).
fn per_scene(results: &[ExternalResult]) -> String {
    let mut keys: Vec<(&str, &str)> = results
        .iter()
        .map(|r| (r.scene.as_str(), r.job.as_str()))
        .collect();
    keys.sort_unstable();
    keys.dedup();
    if keys.len() == results.len() {
        return String::new();
    }
    let mut s = "\n## Per scene, over seeds\n\n| scene | mesh given | seeds | ours env mean | \
                 Lambert env mean | L+GGX env mean | ratio geometric mean | min |\n\
                 |---|---|---|---|---|---|---|---|\n"
        .to_string();
    let mut gms = Vec::new();
    for (scene, job) in keys {
        let rs: Vec<&ExternalResult> = results
            .iter()
            .filter(|r| r.scene == scene && r.job == job)
            .collect();
        let mean = |f: &dyn Fn(&ExternalResult) -> Option<f64>| -> String {
            let v: Vec<f64> = rs.iter().filter_map(|r| f(r)).collect();
            if v.is_empty() {
                "-".to_string()
            } else {
                f3(v.iter().sum::<f64>() / v.len() as f64)
            }
        };
        let ratios: Vec<f64> = rs.iter().filter_map(|r| r.ratio()).collect();
        let gm = geometric_mean(&ratios);
        if !ratios.is_empty() {
            gms.push(gm);
        }
        s += &format!(
            "| {scene} | {job} | {} | {} | {} | {} | {} | {} |\n",
            rs.len(),
            mean(&|r| r.ours.as_ref().ok().map(|e| e.environment)),
            mean(&|r| r.lambert.map(|e| e.environment)),
            mean(&|r| r.lambert_ggx.map(|e| e.environment)),
            if ratios.is_empty() {
                "-".to_string()
            } else {
                f3(gm)
            },
            f3(ratios.iter().copied().fold(f64::INFINITY, f64::min)),
        );
    }
    if !gms.is_empty() {
        s += &format!(
            "\nScenes' geometric means: geometric mean {}, min {}, scenes below 1/1.1: {} of {}.\n",
            f3(geometric_mean(&gms)),
            f3(gms.iter().copied().fold(f64::INFINITY, f64::min)),
            gms.iter().filter(|&&x| x < 1.0 / 1.1).count(),
            gms.len()
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_index_entry_names_what_the_basis_leaves_out_and_older_ones_leave_out_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let entry = |extra: &str| {
            format!(
                r#""mesh": "bunny", "rig": "1light", "material": "m", "jobs": {{"realistic": "j.toml"}}, "truth_table": "truth.binary"{extra}"#
            )
        };
        let text = format!(
            r#"{{"scenes": {{"old": {{{}}}, "merl": {{{}}}}}}}"#,
            entry(""),
            entry(r#", "basis_exclude": ["green-latex"]"#)
        );
        std::fs::write(dir.path().join("index.json"), text).unwrap();
        let index = read_index(dir.path()).unwrap();
        assert!(index.scenes["old"].basis_exclude.is_empty());
        assert_eq!(index.scenes["merl"].basis_exclude, vec!["green-latex"]);
        // A broken index names its file.
        std::fs::write(dir.path().join("index.json"), "{\"scenes\": 3}").unwrap();
        let e = read_index(dir.path()).unwrap_err().to_string();
        assert!(e.contains("index.json"), "{e}");
    }

    #[test]
    fn a_scene_whose_basis_cannot_be_built_is_named_with_what_it_leaves_out() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("index.json"),
            r#"{"scenes": {"bunny-x": {"mesh": "bunny", "rig": "1light", "material": "m",
                "jobs": {"realistic": "j.toml"}, "truth_table": "truth.binary",
                "basis_exclude": ["no-such-material"]}}}"#,
        )
        .unwrap();
        let mut asked = Vec::new();
        let mut basis_for = |exclude: &[String]| {
            asked.push(exclude.to_vec());
            Err(crate::brdf::basis_cache::BasisCacheError::Build(
                crate::brdf::basis::BasisError::UnknownExcluded(exclude[0].clone()),
            ))
        };
        let e = run(
            dir.path(),
            &["realistic".to_string()],
            &[1],
            &Settings::default(),
            &mut basis_for,
            5,
            &mut |_| {},
            &mut |_| {},
        )
        .unwrap_err();
        assert_eq!(asked, vec![vec!["no-such-material".to_string()]]);
        let chain = format!("{e}: {}", std::error::Error::source(&e).unwrap());
        assert!(chain.contains("bunny-x"), "{chain}");
        assert!(chain.contains("no-such-material"), "{chain}");
    }
}
