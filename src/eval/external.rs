//! Evaluation on scenes the project did not render: the folders written by
//! `scripts/render_recon_scenes.py` (Mitsuba 3, materials outside the MERL set, exact and
//! degraded meshes; docs/independent-scenes.md). Each job of each scene is reconstructed as a
//! user would (`reconstruct::reconstruct_with_basis`, the full basis: the materials are not in
//! it), the Lambert and Lambert + GGX baselines are fitted to the same observed pixels, and all
//! three are scored against the scene's truth table with the errors of `Truth`.
//!
//! A scene of several materials (`--split` of the script: `materials`, `truth_tables` and
//! per-vertex truth `labels` in its entry) is reconstructed with `--materials auto`: the count
//! found, the share of the visible surface whose found material is the true one, and each
//! found material's table against the truth most of its pixels have, beside Lambert and
//! Lambert + GGX fitted to the same pixels (as `bench materials` scores its simulated objects).
//!
//! The scene folders are read, never written. An I/O edge.

use super::materials::{MaterialScore, found_tables, score_found};
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
    /// The truth of a one-material scene (absent for a scene of several materials).
    #[serde(default)]
    pub truth_table: Option<String>,
    /// A scene of several materials: their names, in label order.
    #[serde(default)]
    pub materials: Vec<String>,
    /// Per material (label order): its truth table (`null` when the script wrote none).
    #[serde(default, deserialize_with = "null_as_empty")]
    pub truth_tables: Vec<String>,
    /// Mesh variant (exact, realistic, ...) -> per-vertex truth labels of that variant's mesh,
    /// one integer per line.
    #[serde(default)]
    pub labels: BTreeMap<String, String>,
    /// Materials the basis must leave out for this scene (a truth of the measured kind, a
    /// tabulated neural MERL fit, must not be in the basis that reconstructs it).
    #[serde(default)]
    pub basis_exclude: Vec<String>,
}

fn null_as_empty<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<String>, D::Error> {
    Ok(Option::<Vec<String>>::deserialize(d)?.unwrap_or_default())
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
    /// The ladder that chose `model` (every rung's held-out errors by fold), so that a study of
    /// the choice needs no re-run (scripts/heldout_vs_render.py).
    pub ladder: Option<crate::reconstruct::ladder::Ladder>,
    /// The confidence's share of a render of the result from cells no pixel observed.
    pub unseen_energy: Option<f64>,
    pub lambert: Option<Errors>,
    pub lambert_ggx: Option<Errors>,
    /// A scene of several materials: what was found (`ours`, `lambert`, `lambert_ggx` are then
    /// unset; each found material has its own).
    pub split: Option<SplitResult>,
    pub seconds: f64,
}

/// What `--materials auto` found on a scene of several materials, against its truth.
#[derive(Clone, Debug, Serialize)]
pub struct SplitResult {
    pub truth_count: usize,
    pub count: usize,
    /// Share of the visible surface area (faces some pixel sees) whose found material is the
    /// true one, under the best renaming.
    pub agreement: f64,
    /// Each found material against the true material most of its pixels have (as `bench
    /// materials` scores its objects).
    pub materials: Vec<MaterialScore>,
}

/// Reads a label file: one non-negative integer per line, `expected` lines.
pub fn read_labels(path: &Path, expected: usize) -> Result<Vec<u32>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let labels: Vec<u32> = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            l.trim().parse::<u32>().map_err(|e| {
                format!(
                    "{} line {}: {:?} is not a label ({e})",
                    path.display(),
                    i + 1,
                    l.trim()
                )
            })
        })
        .collect::<Result<_, _>>()?;
    if labels.len() != expected {
        return Err(format!(
            "{}: {} labels for {expected} vertices",
            path.display(),
            labels.len()
        ));
    }
    Ok(labels)
}

/// Scores a reconstruction of a scene of several materials: `truth_vertex` labels the vertices
/// of the mesh the reconstruction was given, `names` and `truths` are the materials in label
/// order.
pub fn score_split(
    output: &crate::reconstruct::Output,
    truth_vertex: &[u32],
    names: &[String],
    truths: &[Truth],
) -> Result<SplitResult, String> {
    use crate::geometry::labels::{FaceLabels, area_agreement};
    use crate::reconstruct::segment::fit_groups;
    let m = output
        .materials
        .as_ref()
        .ok_or("the reconstruction did not look for materials")?;
    if truths.is_empty() || names.len() != truths.len() {
        return Err(format!(
            "{} material names for {} truths",
            names.len(),
            truths.len()
        ));
    }
    let mesh = &m.mesh;
    if truth_vertex.len() != mesh.positions().len() {
        return Err(format!(
            "{} truth labels for a mesh of {} vertices",
            truth_vertex.len(),
            mesh.positions().len()
        ));
    }
    let observations = &output.observed.observations;
    let truth_faces = FaceLabels::from_vertex_labels(mesh, truth_vertex);
    let found_faces = FaceLabels::from_vertex_labels(mesh, &m.segmentation.vertex_labels);
    let mut visible = vec![false; mesh.faces().len()];
    for o in observations {
        if let Some(v) = visible.get_mut(o.face as usize) {
            *v = true;
        }
    }
    let agreement = area_agreement(mesh, &truth_faces, &found_faces, Some(&visible));
    let count = m.segmentation.count;
    // each found material's pixels: those its fit had (one material: every pixel)
    let groups: Vec<Vec<crate::reconstruct::observation::Observation>> = if m.results.is_empty() {
        vec![observations.clone()]
    } else {
        fit_groups(mesh, &m.segmentation, observations, &m.settings).0
    };
    let found = found_tables(&m.results, &output.table, &output.core);
    let materials = found
        .into_iter()
        .zip(&groups)
        .map(|(f, own)| score_found(f, own, own, &truth_faces.labels, names, truths))
        .collect();
    Ok(SplitResult {
        truth_count: truths.len(),
        count,
        agreement,
        materials,
    })
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
        let read_truth = |file: &str| {
            let path = scene_dir.join(file);
            MerlTable::read(&path)
                .map(|t| Truth::new(&t, bin_step))
                .map_err(|e| EvalError::Scene {
                    dir: path,
                    source: std::io::Error::other(e),
                })
        };
        let split = !entry.materials.is_empty() || !entry.truth_tables.is_empty();
        let missing = |what: &str| EvalError::Scene {
            dir: dir.join("index.json"),
            source: std::io::Error::other(format!("scene {name}: {what}")),
        };
        // what the index names is checked first; the files are read once the basis is there
        let truth_file = match (&entry.truth_table, split) {
            (Some(file), false) => Some(file),
            (_, true) if entry.truth_tables.len() != entry.materials.len() => {
                return Err(missing(&format!(
                    "{} materials but {} `truth_tables` (rendered without `--truth full`?)",
                    entry.materials.len(),
                    entry.truth_tables.len()
                )));
            }
            (_, true) => None,
            (None, false) => {
                return Err(missing("neither `truth_table` nor `truth_tables`"));
            }
        };
        let basis = basis_for(&entry.basis_exclude).map_err(|source| EvalError::SceneBasis {
            scene: name.clone(),
            exclude: entry.basis_exclude.clone(),
            source,
        })?;
        let truth = truth_file.map(|f| read_truth(f)).transpose()?;
        let truths: Vec<Truth> = entry
            .truth_tables
            .iter()
            .map(|file| read_truth(file))
            .collect::<Result<_, _>>()?;
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
            if split && settings.materials.is_none() {
                // a user who knows the object has several materials asks for them
                settings.materials = Some(Default::default());
            }
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
                ladder: None,
                unseen_energy: None,
                lambert: None,
                lambert_ggx: None,
                split: None,
                seconds: 0.0,
            };
            match Job::from_file(&job_path)
                .map_err(|e| e.to_string())
                .and_then(|job| {
                    reconstruct_with_basis(&job, settings, &basis, &mut |_| {})
                        .map_err(|e| e.to_string())
                }) {
                Ok(o) => {
                    r.model = Some(o.core.model.clone());
                    r.confidence = Some(o.core.confidence.level);
                    r.ladder = o.core.ladder.clone();
                    r.unseen_energy = Some(o.core.confidence.unseen_energy);
                    match &truth {
                        Some(truth) => {
                            r.ours = Ok(truth.errors_of(&o.table));
                            let (l, g) = fit_baselines(&o.observed.observations);
                            r.lambert = l.map(|b| truth.errors_of(&BrdfValues(&b)));
                            r.lambert_ggx = g.map(|b| truth.errors_of(&BrdfValues(&b)));
                        }
                        None => {
                            let variant = job_name.trim_end_matches("_path");
                            let scored = match (entry.labels.get(variant), &o.materials) {
                                (None, _) => Err(format!("no truth labels for the {variant} mesh")),
                                (_, None) => Err("no materials were looked for".to_string()),
                                (Some(file), Some(m)) => {
                                    read_labels(&scene_dir.join(file), m.mesh.positions().len())
                                        .and_then(|labels| {
                                            score_split(&o, &labels, &entry.materials, &truths)
                                        })
                                }
                            };
                            match scored {
                                Ok(s) => {
                                    r.ours = Err("several materials: see `split`".to_string());
                                    r.split = Some(s);
                                }
                                Err(e) => r.ours = Err(e),
                            }
                        }
                    }
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
    let one_material: Vec<ExternalResult> = results
        .iter()
        .filter(|r| r.split.is_none())
        .cloned()
        .collect();
    if !one_material.is_empty() {
        let results = one_material.as_slice();
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
    }
    s += &per_scene(results);
    s += &split_section(results);
    if one_material.is_empty() {
        return s;
    }
    s += "\n## Per job\n\n| scene | mesh given | seed | median normal error deg | ours env | model | Lambert env | L+GGX env | ratio | ours lights | ours E_sa | ours log | confidence | seconds |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for r in &one_material {
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

/// The scenes of several materials: counts, agreement and each found material's ratio.
fn split_section(results: &[ExternalResult]) -> String {
    let split: Vec<(&ExternalResult, &SplitResult)> = results
        .iter()
        .filter_map(|r| r.split.as_ref().map(|s| (r, s)))
        .collect();
    if split.is_empty() {
        return String::new();
    }
    let ratios: Vec<f64> = split
        .iter()
        .flat_map(|(_, s)| s.materials.iter().filter_map(MaterialScore::ratio))
        .collect();
    let mut s = "\n## Objects of several materials (`--materials auto`)\n\n".to_string();
    s += "Agreement: share of the visible surface area whose found material is the true one \
          (best renaming). Each found material is scored against the true material most of its \
          pixels have, beside Lambert and Lambert + GGX fitted to the same pixels; ratio = the \
          better baseline's environment error / ours.\n\n";
    s += &format!(
        "| | value |\n|---|---|\n| runs | {} |\n| count right | {} of {} |\n| agreement >= 0.9 | {} of {} (min {}) |\n| found materials: ratio gm | {} over {} (min {}; worse by > 10 %: {}) |\n\n",
        split.len(),
        split
            .iter()
            .filter(|(_, x)| x.count == x.truth_count)
            .count(),
        split.len(),
        split.iter().filter(|(_, x)| x.agreement >= 0.9).count(),
        split.len(),
        f3(split
            .iter()
            .map(|(_, x)| x.agreement)
            .fold(f64::INFINITY, f64::min)),
        f3(geometric_mean(&ratios)),
        ratios.len(),
        f3(ratios.iter().copied().fold(f64::INFINITY, f64::min)),
        ratios.iter().filter(|&&x| x < 1.0 / 1.1).count(),
    );
    s += "| scene | mesh given | seed | count (truth) | agreement | found: truth (purity), model, ours / Lambert / L+GGX env, ratio | seconds |\n|---|---|---|---|---|---|---|\n";
    for (r, x) in split {
        let found: Vec<String> = x.materials.iter().map(MaterialScore::cell).collect();
        s += &format!(
            "| {} | {} | {} | {} ({}) | {} | {} | {:.1} |\n",
            r.scene,
            r.job,
            r.seed,
            x.count,
            x.truth_count,
            f3(x.agreement),
            found.join("<br>"),
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
    let results: Vec<ExternalResult> = results
        .iter()
        .filter(|r| r.split.is_none())
        .cloned()
        .collect();
    let results = results.as_slice();
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
        assert_eq!(
            index.scenes["old"].truth_table.as_deref(),
            Some("truth.binary")
        );
        assert!(index.scenes["old"].truth_tables.is_empty());
        // a scene of several materials: truths and labels per material, no `truth_table`
        std::fs::write(
            dir.path().join("index.json"),
            r#"{"scenes": {"split": {"mesh": "spot", "rig": "3lights", "material": "a+b",
                "materials": ["a", "b"], "jobs": {"realistic": "j.toml"},
                "truth_tables": null, "truth_table": null,
                "labels": {"realistic": "labels_realistic.txt"}}}}"#,
        )
        .unwrap();
        let index = read_index(dir.path()).unwrap();
        let split = &index.scenes["split"];
        assert!(
            split.truth_tables.is_empty(),
            "written without full truth tables"
        );
        std::fs::write(
            dir.path().join("index.json"),
            r#"{"scenes": {"split": {"mesh": "spot", "rig": "3lights", "material": "a+b",
                "materials": ["a", "b"], "jobs": {"realistic": "j.toml"},
                "truth_tables": ["truth_0.binary", "truth_1.binary"],
                "labels": {"realistic": "labels_realistic.txt"}}}}"#,
        )
        .unwrap();
        let index = read_index(dir.path()).unwrap();
        let split = &index.scenes["split"];
        assert_eq!(split.truth_table, None);
        assert_eq!(split.materials, vec!["a", "b"]);
        assert_eq!(split.truth_tables.len(), 2);
        assert_eq!(split.labels["realistic"], "labels_realistic.txt");
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

    #[test]
    fn label_files_are_read_one_per_line_and_bad_ones_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("labels_realistic.txt");
        std::fs::write(&path, "0\n1\n 1 \n0\n").unwrap();
        assert_eq!(read_labels(&path, 4).unwrap(), vec![0, 1, 1, 0]);
        let e = read_labels(&path, 5).unwrap_err();
        assert!(
            e.contains("labels_realistic.txt") && e.contains("4 labels for 5"),
            "{e}"
        );
        std::fs::write(&path, "0\nx\n").unwrap();
        let e = read_labels(&path, 2).unwrap_err();
        assert!(e.contains("line 2") && e.contains("\"x\""), "{e}");
        std::fs::write(&path, "0\n-1\n").unwrap();
        assert!(read_labels(&path, 2).unwrap_err().contains("line 2"));
        let e = read_labels(&dir.path().join("missing.txt"), 1).unwrap_err();
        assert!(e.contains("missing.txt"), "{e}");
    }

    #[test]
    fn a_scene_without_any_truth_is_an_error_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("index.json"),
            r#"{"scenes": {"bare": {"mesh": "spot", "rig": "3lights", "material": "m",
                "jobs": {"realistic": "j.toml"}}}}"#,
        )
        .unwrap();
        let e = run(
            dir.path(),
            &["realistic".to_string()],
            &[1],
            &Settings::default(),
            &mut |_: &[String]| -> Result<std::rc::Rc<Basis>, _> {
                Err(crate::brdf::basis_cache::BasisCacheError::Build(
                    crate::brdf::basis::BasisError::UnknownExcluded("not asked".into()),
                ))
            },
            5,
            &mut |_| {},
            &mut |_| {},
        )
        .unwrap_err();
        let chain = format!("{e}: {}", std::error::Error::source(&e).unwrap());
        assert!(
            chain.contains("bare") && chain.contains("truth_tables"),
            "{chain}"
        );
    }
}
