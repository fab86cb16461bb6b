//! The multi-material study (issue #17): simulated objects of two or three of the paper's
//! materials (the mesh split into slabs along its height, `geometry::labels::split_by_planes`),
//! rendered by `sim::job_scene::write_scene_materials`, reconstructed as `brdf-rig reconstruct
//! --materials auto` does (`reconstruct::materials`), and scored against the truth: the share
//! of the visible surface area whose found material is the true one (`area_agreement`), the
//! chosen count, and each found material's rendered error against its true material beside
//! Lambert and Lambert + GGX fitted to the same pixels. One-material objects check that the
//! count stays 1. The time is compared with the one-material reconstruction of the same pixels.
//! Writes the scenes (I/O edge of the evaluation, like `eval::accuracy`).

use super::accuracy::Rig;
use super::{EvalError, Truth, baseline_errors, find_material, load_case, refine_case};
use crate::brdf::basis_cache;
use crate::brdf::nbrdf::Nbrdf;
use crate::brdf::{BinValues, Brdf};
use crate::geometry::labels::{FaceLabels, area_agreement, split_by_planes};
use crate::geometry::mesh::Mesh;
use crate::geometry::sfm_like::{SfmLikeParams, sfm_like};
use crate::geometry::zbuffer::face_buffer;
use crate::reconstruct::core::{CoreSettings, reconstruct_observations};
use crate::reconstruct::materials::reconstruct_materials;
use crate::reconstruct::nielsen::{NielsenPrior, NielsenSettings};
use crate::reconstruct::observation::Observation;
use crate::reconstruct::observe::{NO_FACE, ObserveSettings};
use crate::reconstruct::prepare::observe_scene;
use crate::reconstruct::refine::TableBins;
use crate::reconstruct::segment::{SegmentSettings, fit_groups};
use crate::sim::job_scene::{view_geometry, write_scene_materials};
use nalgebra::Vector3;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// What to run.
#[derive(Clone, Debug, Serialize)]
pub struct MaterialsSpec {
    /// Objects: each a list of material names (one name: a one-material object).
    pub objects: Vec<Vec<String>>,
    #[serde(skip)]
    pub meshes: Vec<(String, Mesh)>,
    pub mesh_names: Vec<String>,
    pub views: usize,
    pub width: usize,
    pub height: usize,
    #[serde(skip)]
    pub basis: crate::brdf::basis::BasisSettings,
    pub core: CoreSettings,
    pub segment: SegmentSettings,
    pub seeds: u64,
    pub rigs: Vec<Rig>,
    pub bin_step: usize,
    /// Refine the SfM-like mesh's normals from the images before finding the materials, as
    /// `reconstruct --refine-normals` does (`None`: off). The baselines are then fitted to the
    /// unrefined pixels of each found material (the mesh the user was given), as in
    /// `eval::accuracy`.
    pub refine: Option<crate::reconstruct::refine::RefineSettings>,
    /// How many times each object's two reconstructions (its materials, then one material)
    /// are timed, one after the other in turn; the least time of each is kept (other work on
    /// the machine only ever adds time). At least 1; the results are the first run's (every
    /// run gives the same).
    pub time_repeats: usize,
    /// Also time the whole command a user runs, both ways (`reconstruct --materials auto` and
    /// the one-material default): the basis from the cache, the job loaded from disk and
    /// observed (and refined), the cores, the photo/re-render comparison and every file
    /// written; the least of `time_repeats` timings of each, in turn ([`time_commands`]).
    pub time_command: bool,
    /// The neural fits' folder the whole command reads (`None`: the data folder's), as
    /// `reconstruct --nbrdf-dir`.
    #[serde(skip)]
    pub nbrdf_dir: Option<std::path::PathBuf>,
}

/// One found material against its true one.
#[derive(Clone, Debug, Serialize)]
pub struct MaterialScore {
    /// The true material it matched (most of its pixels' true label).
    pub truth: String,
    pub found: String,
    pub pixels: usize,
    /// Share of its pixels whose true material is `truth`.
    pub purity: f64,
    pub model: String,
    pub confidence: String,
    /// Environment errors against the true material.
    pub ours: f64,
    pub lambert: Option<f64>,
    pub lambert_ggx: Option<f64>,
}

impl MaterialScore {
    /// The better baseline's error over ours (above 1: ours is better).
    pub fn ratio(&self) -> Option<f64> {
        let base = match (self.lambert, self.lambert_ggx) {
            (Some(a), Some(b)) => a.min(b),
            (a, b) => a.or(b)?,
        };
        Some(base / self.ours)
    }

    /// The page's cell: `found: truth (purity), model, ours / Lambert / L+GGX, ratio`.
    pub fn cell(&self) -> String {
        format!(
            "{}: {} ({:.2}), {}, {} / {} / {}, {}",
            self.found,
            self.truth,
            self.purity,
            self.model,
            f3(self.ours),
            self.lambert.map_or("-".into(), f3),
            self.lambert_ggx.map_or("-".into(), f3),
            self.ratio().map_or("-".into(), |x| format!("{x:.2}"))
        )
    }
}

/// One object's result.
#[derive(Clone, Debug, Serialize)]
pub struct ObjectResult {
    pub mesh: String,
    pub materials: Vec<String>,
    pub rig: Rig,
    pub seed: u64,
    pub count: usize,
    pub reason: String,
    /// Every count tried, with its held-out error.
    pub count_scores: Vec<crate::reconstruct::segment::CountScore>,
    /// Share of the visible surface area labelled with its true material (best renaming).
    pub agreement: f64,
    pub scores: Vec<MaterialScore>,
    pub observed_pixels: usize,
    /// Segmentation plus the per-material fits, and the one-material fit of the same pixels.
    pub seconds: f64,
    /// Of `seconds`, finding the materials (the count's held-out fits included).
    pub segment_seconds: f64,
    pub seconds_one: f64,
    /// With [`MaterialsSpec::time_command`]: the whole command's seconds with
    /// `--materials auto` and with one material.
    pub command_seconds: Option<(f64, f64)>,
    /// With `refine`: the median vertex-normal error against the truth before and after, in
    /// degrees, and whether the refinement was accepted.
    pub normals: Option<NormalsChange>,
}

/// What the normal refinement did to one object's normals.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct NormalsChange {
    pub median_before_deg: f64,
    pub median_after_deg: f64,
    pub accepted: bool,
    /// Reflectance tables the refinement fitted (one per material found before it).
    pub tables: usize,
    /// Their shape, and the fitting samples per observed cell of the finer one that chose it
    /// (`RefineReport::table_bins`, `table_samples_per_cell`).
    pub table_bins: TableBins,
    pub table_samples_per_cell: Option<f64>,
}

/// What [`score_found`] scores, per found material: name, table as written, model and
/// confidence; one entry named `one` (`table`, `core`) when one material was found.
pub fn found_tables<'a>(
    results: &'a [crate::reconstruct::materials::MaterialResult],
    table: &'a dyn BinValues,
    core: &crate::reconstruct::core::CoreOutput,
) -> Vec<(String, &'a dyn BinValues, String, String)> {
    if results.is_empty() {
        return vec![(
            "one".to_string(),
            table,
            core.model.family.to_string(),
            core.confidence.level.to_string(),
        )];
    }
    results
        .iter()
        .map(|r| {
            (
                r.name.clone(),
                &r.table as &dyn BinValues,
                r.model.family.to_string(),
                r.confidence.level.to_string(),
            )
        })
        .collect()
}

/// Scores one found material (name, table as written, model, confidence) against the true
/// material most of its pixels `own` have (`truth_faces`: the true label of each face; `names`
/// and `truths` in label order), beside Lambert and Lambert + GGX fitted to `baseline_pixels`
/// (its own pixels, or the same faces' unrefined ones). Shared by `bench materials` and
/// `bench external`.
pub fn score_found(
    found: (String, &dyn BinValues, String, String),
    own: &[Observation],
    baseline_pixels: &[Observation],
    truth_faces: &[u32],
    names: &[String],
    truths: &[Truth],
) -> MaterialScore {
    let (name, table, model, confidence) = found;
    let mut votes = vec![0usize; truths.len().min(names.len())];
    for o in own {
        if o.face != NO_FACE
            && let Some(&l) = truth_faces.get(o.face as usize)
            && let Some(v) = votes.get_mut(l as usize)
        {
            *v += 1;
        }
    }
    let (t, &n) = votes
        .iter()
        .enumerate()
        .max_by_key(|(_, n)| **n)
        .unwrap_or((0, &0));
    let (lambert, lambert_ggx) = match truths.get(t) {
        Some(truth) => baseline_errors(truth, baseline_pixels),
        None => (None, None),
    };
    MaterialScore {
        truth: names.get(t).cloned().unwrap_or_default(),
        found: name,
        pixels: own.len(),
        purity: n as f64 / own.len().max(1) as f64,
        model,
        confidence,
        ours: truths
            .get(t)
            .map_or(f64::NAN, |tr| tr.errors_of(table).environment),
        lambert: lambert.map(|e| e.environment),
        lambert_ggx: lambert_ggx.map(|e| e.environment),
    }
}

/// Faces of `mesh` seen by any view of the scene.
fn visible_faces(mesh: &Mesh, spec: &crate::sim::job_scene::SceneSpec) -> Vec<bool> {
    let mut seen = vec![false; mesh.faces().len()];
    for i in 0..spec.views {
        let (k, pose, _) = view_geometry(mesh, spec, i);
        if let Some(fb) = face_buffer(mesh, &k, &pose) {
            for y in 0..fb.height() {
                for &f in fb.row(y) {
                    if let Some(s) = seen.get_mut(f as usize) {
                        *s = true;
                    }
                }
            }
        }
    }
    seen
}

/// Runs every object. `scratch` receives the scene folders.
pub fn run(
    spec: &MaterialsSpec,
    materials: &[(String, Nbrdf)],
    cache_dir: &Path,
    scratch: &Path,
    progress: &mut dyn FnMut(&str),
    on_object: &mut dyn FnMut(&ObjectResult),
) -> Result<Vec<ObjectResult>, EvalError> {
    let mut results = Vec::new();
    for names in &spec.objects {
        let brdfs: Vec<&Nbrdf> = names
            .iter()
            .map(|n| find_material(materials, n))
            .collect::<Result<_, _>>()?;
        let mut bs = spec.basis.clone();
        bs.exclude = names.clone();
        let object = names.join("+");
        progress(&format!("{object}: basis without them (cache or build)"));
        let (basis, _) = basis_cache::load_or_build(&bs, materials, cache_dir)?;
        let truths: Vec<Truth> = brdfs
            .iter()
            .map(|b| Truth::new(*b, spec.bin_step))
            .collect();
        let prior = NielsenPrior {
            basis: &basis,
            settings: NielsenSettings::default(),
        };
        for (mesh_name, mesh) in &spec.meshes {
            for rig in &spec.rigs {
                for seed in 0..spec.seeds.max(1) {
                    let t0 = Instant::now();
                    let scene = rig.scene(spec.views, spec.width, spec.height);
                    let dir = scratch.join(format!("{mesh_name}-{object}-{}-{seed}", rig.tag()));
                    progress(&format!(
                        "{object} on {mesh_name}, {}, seed {seed}: rendering",
                        rig.label()
                    ));
                    // slabs along the mesh's up axis (+y, the scenes' world up)
                    let truth_labels = split_by_planes(mesh, Vector3::y(), names.len() as u32);
                    let job_mesh = sfm_like(
                        mesh,
                        &SfmLikeParams {
                            seed: 7 + seed,
                            ..SfmLikeParams::default()
                        },
                    );
                    let dyn_brdfs: Vec<&dyn Brdf> = brdfs.iter().map(|b| *b as &dyn Brdf).collect();
                    let job = write_scene_materials(
                        &dir,
                        mesh,
                        &job_mesh,
                        &dyn_brdfs,
                        &truth_labels,
                        names,
                        &scene,
                    )
                    .map_err(|source| EvalError::Scene {
                        dir: dir.clone(),
                        source,
                    })?;
                    let observe = ObserveSettings::default();
                    let loaded = load_case(&job, &observe, &super::Perturb::default())?;
                    let seg_mesh = loaded.mesh.clone();
                    let (obs, unrefined, normals) = match &spec.refine {
                        Some(rs) => {
                            progress(&format!("{object} on {mesh_name}: refining the normals"));
                            let c = refine_case(loaded, &observe, rs, Some(spec.segment), mesh);
                            let normals = c.study.map(|n| NormalsChange {
                                median_before_deg: n.median_before_deg,
                                median_after_deg: n.median_after_deg,
                                accepted: n.report.accepted,
                                tables: n.report.materials,
                                table_bins: n.report.table_bins,
                                table_samples_per_cell: n.report.table_samples_per_cell,
                            });
                            (c.observations, Some(c.unrefined), normals)
                        }
                        None => (observe_scene(&loaded, &observe).observations, None, None),
                    };
                    let mut core = spec.core.clone();
                    core.trials.seed += seed;
                    progress(&format!("{object} on {mesh_name}: materials"));
                    let several = || {
                        reconstruct_materials(
                            &seg_mesh,
                            &obs,
                            None,
                            &prior,
                            &core,
                            &spec.segment,
                            &mut |_| {},
                        )
                    };
                    let single = || reconstruct_observations(&obs, &prior, &core, &mut |_| {});
                    let t = Instant::now();
                    let (m, cores) = several()?;
                    let mut seconds = t.elapsed().as_secs_f64();
                    let t = Instant::now();
                    let one = single()?;
                    let mut seconds_one = t.elapsed().as_secs_f64();
                    for _ in 1..spec.time_repeats.max(1) {
                        let t = Instant::now();
                        drop(several()?);
                        seconds = seconds.min(t.elapsed().as_secs_f64());
                        let t = Instant::now();
                        drop(single()?);
                        seconds_one = seconds_one.min(t.elapsed().as_secs_f64());
                    }
                    let command_seconds = if spec.time_command {
                        progress(&format!(
                            "{object} on {mesh_name}: the whole commands, timed"
                        ));
                        Some(time_commands(&job, spec, &core, (&bs, cache_dir), &dir)?)
                    } else {
                        None
                    };
                    let found =
                        FaceLabels::from_vertex_labels(&seg_mesh, &m.segmentation.vertex_labels);
                    let visible = visible_faces(mesh, &scene);
                    let agreement = area_agreement(mesh, &truth_labels, &found, Some(&visible));
                    // each found material against the true material most of its pixels have
                    let mut scores = Vec::new();
                    // (results and cores are both empty when one material was found)
                    let tables = found_tables(&m.results, &one.table, &one);
                    // the pixels each material's fit had (the baselines get the same)
                    let (mut groups, _) = fit_groups(&seg_mesh, &m.segmentation, &obs, &m.settings);
                    // with a refinement the baselines get the same faces' unrefined pixels
                    let mut base_groups = unrefined
                        .as_ref()
                        .map(|u| fit_groups(&seg_mesh, &m.segmentation, u, &m.settings).0);
                    for (i, (name, table, model, confidence)) in tables.into_iter().enumerate() {
                        let own: Vec<Observation> = if cores.is_empty() {
                            obs.to_vec()
                        } else {
                            groups.get_mut(i).map(std::mem::take).unwrap_or_default()
                        };
                        let base_own: Option<Vec<Observation>> = match &mut base_groups {
                            None => None,
                            Some(_) if cores.is_empty() => unrefined.clone(),
                            Some(g) => Some(g.get_mut(i).map(std::mem::take).unwrap_or_default()),
                        };
                        scores.push(score_found(
                            (name, table, model, confidence),
                            &own,
                            base_own.as_deref().unwrap_or(&own),
                            &truth_labels.labels,
                            names,
                            &truths,
                        ));
                    }
                    let r = ObjectResult {
                        mesh: mesh_name.clone(),
                        materials: names.clone(),
                        rig: *rig,
                        seed,
                        count: m.segmentation.count,
                        reason: m.segmentation.reason.clone(),
                        count_scores: m.segmentation.scores.clone(),
                        agreement,
                        scores,
                        observed_pixels: obs.len(),
                        seconds,
                        segment_seconds: m.segment_seconds,
                        seconds_one,
                        command_seconds,
                        normals,
                    };
                    progress(&format!(
                        "  {} materials found, agreement {:.3}, {:.1} s ({:.1} s one-material) [{:.0} s]",
                        r.count,
                        r.agreement,
                        r.seconds,
                        r.seconds_one,
                        t0.elapsed().as_secs_f64()
                    ));
                    on_object(&r);
                    results.push(r);
                }
            }
        }
    }
    Ok(results)
}

/// The whole `reconstruct` a user runs on `job`, timed with `--materials auto` and with one
/// material, in turn, `spec.time_repeats` times; the least of each. Each run makes the library
/// calls the command makes after reading its arguments: `reconstruct::reconstruct` (load,
/// observe, refine with `spec.refine`, the neural fits' folder and the basis from the cache,
/// the cores, the photo/re-render comparison) and `output::write` into a folder under `dir`,
/// removed after.
pub fn time_commands(
    job: &crate::reconstruct::Job,
    spec: &MaterialsSpec,
    core: &CoreSettings,
    (basis, cache_dir): (&crate::brdf::basis::BasisSettings, &Path),
    dir: &Path,
) -> Result<(f64, f64), EvalError> {
    use crate::reconstruct::{Settings, output, reconstruct};
    let settings = |several: bool| {
        let mut s = Settings {
            core: core.clone(),
            basis: basis.clone(),
            basis_cache: Some(cache_dir.to_path_buf()),
            refine: spec.refine.clone(),
            materials: several.then_some(spec.segment),
            ..Settings::default()
        };
        if let Some(d) = &spec.nbrdf_dir {
            s.nbrdf_dir = d.clone();
        }
        s
    };
    let (auto, one) = (settings(true), settings(false));
    let once = |settings: &Settings, name: &str| -> Result<f64, EvalError> {
        let out = dir.join(name);
        let t = Instant::now();
        let o = reconstruct(job, settings, &mut |_| {})?;
        output::write(&out, &o).map_err(|source| EvalError::Output {
            dir: out.clone(),
            source,
        })?;
        let s = t.elapsed().as_secs_f64();
        // 40-140 MB of tables per run: not kept
        let _ = std::fs::remove_dir_all(&out);
        Ok(s)
    };
    let (mut a, mut b) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..spec.time_repeats.max(1) {
        a = a.min(once(&auto, "command-auto")?);
        b = b.min(once(&one, "command-one")?);
    }
    Ok((a, b))
}

/// Three decimals; "-" for a value that is not finite (no error to show).
fn f3(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.3}")
    } else {
        "-".to_string()
    }
}

/// The geometric mean (1 for no values).
fn gm(v: &[f64]) -> f64 {
    (v.iter().map(|x| x.ln()).sum::<f64>() / v.len().max(1) as f64).exp()
}

/// One object's times, for the page's time row: materials found, seconds of the
/// several-material fit (finding the materials included), of finding the materials, and of
/// the one-material fit of the same pixels.
struct Timing {
    found: usize,
    seconds: f64,
    segment: f64,
    one: f64,
}

/// The summary's time row: the ratio of each object's several-material time to its
/// one-material time (geometric mean, max, how many within 2x), the summed seconds and their
/// ratio, finding the materials' share, and the ratio by the number of materials found.
fn time_row(label: &str, t: &[Timing], repeats: usize) -> String {
    let ratio = |x: &Timing| x.seconds / x.one;
    let times: Vec<f64> = t.iter().map(ratio).collect();
    let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
    let (seconds, one) = (
        t.iter().map(|x| x.seconds).sum::<f64>(),
        t.iter().map(|x| x.one).sum::<f64>(),
    );
    let mut counts: Vec<usize> = t.iter().map(|x| x.found).collect();
    counts.sort_unstable();
    counts.dedup();
    let by_count: Vec<String> = counts
        .iter()
        .map(|&c| {
            let v: Vec<f64> = t.iter().filter(|x| x.found == c).map(ratio).collect();
            format!(
                "{c}: gm {} (max {}) over {}",
                f3(gm(&v)),
                f3(max(&v)),
                v.len()
            )
        })
        .collect();
    let segment: Vec<f64> = t.iter().map(|x| x.segment / x.one).collect();
    format!(
        "| {label} | gm {}, max {}, within 2x {} of {}; summed {:.1} s / {:.1} s = {}{}; by materials found, {}{} |\n",
        f3(gm(&times)),
        f3(max(&times)),
        times.iter().filter(|&&r| r <= 2.0).count(),
        times.len(),
        seconds,
        one,
        f3(seconds / one),
        if segment.iter().all(|x| x.is_finite()) {
            format!(
                " (finding the materials: gm {} of the one-material time)",
                f3(gm(&segment))
            )
        } else {
            String::new()
        },
        by_count.join("; "),
        if repeats > 1 {
            format!("; each the least of {repeats} timings")
        } else {
            String::new()
        }
    )
}

/// The markdown page.
pub fn markdown(
    spec: &MaterialsSpec,
    results: &[ObjectResult],
    command: &str,
    machine: &str,
) -> String {
    let mut s = String::from("# Objects of several materials (`brdf-rig bench materials`)\n\n");
    s += &format!("Command: `{command}`\n\nMachine: {machine}\n\n");
    s += "Ground truth: neural fits of the MERL materials (Sztrajman et al. 2021), smooth \
          approximations of the measurements, not measured MERL data; the basis leaves out every \
          material of the object. Each object: the mesh cut into equal slabs along its height, \
          one material per slab, rendered with `sim::job_scene`; the reconstruction sees an \
          SfM-like mesh and runs `--materials auto`. Agreement: share of the visible surface \
          area whose found material is the true one (best renaming). Per found material: \
          environment error of ours and of Lambert / Lambert + GGX fitted to the same pixels \
          against the true material most of its pixels have; ratio = better baseline / ours.\n\n";
    let multi: Vec<&ObjectResult> = results.iter().filter(|r| r.materials.len() > 1).collect();
    let single: Vec<&ObjectResult> = results.iter().filter(|r| r.materials.len() == 1).collect();
    let ratios: Vec<f64> = multi
        .iter()
        .flat_map(|r| r.scores.iter().filter_map(|m| m.ratio()))
        .collect();
    s += "## Summary\n\n| | value |\n|---|---|\n";
    s += &format!(
        "| objects of several materials | {} |\n| count right | {} of {} |\n| agreement >= 0.9 | {} of {} (min {}) |\n",
        multi.len(),
        multi
            .iter()
            .filter(|r| r.count == r.materials.len())
            .count(),
        multi.len(),
        multi.iter().filter(|r| r.agreement >= 0.9).count(),
        multi.len(),
        f3(multi
            .iter()
            .map(|r| r.agreement)
            .fold(f64::INFINITY, f64::min))
    );
    s += &format!(
        "| found materials: ratio gm | {} over {} (worse by > 10 %: {}) |\n",
        f3(gm(&ratios)),
        ratios.len(),
        ratios.iter().filter(|&&r| r < 1.0 / 1.1).count()
    );
    s += &format!(
        "| one-material objects: count 1 | {} of {} |\n",
        single.iter().filter(|r| r.count == 1).count(),
        single.len()
    );
    let normals: Vec<&NormalsChange> = results.iter().filter_map(|r| r.normals.as_ref()).collect();
    if spec.refine.is_some() {
        s += &format!(
            "| normals refined first (a reflectance table per material): median vertex-normal error after / before | gm {} over {} objects, accepted in {}; the finer table (RefineSettings::table_bins) in {} |\n",
            f3(gm(&normals
                .iter()
                .map(|n| n.median_after_deg / n.median_before_deg)
                .collect::<Vec<_>>())),
            normals.len(),
            normals.iter().filter(|n| n.accepted).count(),
            normals
                .iter()
                .filter(|n| spec
                    .refine
                    .as_ref()
                    .is_some_and(|rs| n.table_bins == rs.table_bins))
                .count()
        );
    }
    let timings: Vec<Timing> = multi
        .iter()
        .map(|r| Timing {
            found: r.count,
            seconds: r.seconds,
            segment: r.segment_seconds,
            one: r.seconds_one,
        })
        .collect();
    s += &time_row(
        "time / one-material time (several materials; the cores, from the observed pixels)",
        &timings,
        spec.time_repeats,
    );
    let commands: Vec<Timing> = multi
        .iter()
        .filter_map(|r| {
            r.command_seconds.map(|(seconds, one)| Timing {
                found: r.count,
                seconds,
                segment: f64::NAN,
                one,
            })
        })
        .collect();
    if !commands.is_empty() {
        s += &time_row(
            "the whole `reconstruct` a user runs, `--materials auto` / one material (the basis from the cache, the job from disk, every file written)",
            &commands,
            spec.time_repeats,
        );
    }
    s += "\n";
    s += "## Objects\n\n| mesh | materials | rig | seed | count | agreement | found: truth (purity), model, ours / Lambert / L+GGX, ratio | s: all (materials; one-material) |\n|---|---|---|---|---|---|---|---|\n";
    for r in results {
        let per: Vec<String> = r.scores.iter().map(MaterialScore::cell).collect();
        s += &format!(
            "| {} | {} | {} | {} | {} | {} | {} | {:.1} ({:.1}; {:.1}) |\n",
            r.mesh,
            r.materials.join(" + "),
            r.rig.label(),
            r.seed,
            r.count,
            f3(r.agreement),
            per.join("<br>"),
            r.seconds,
            r.segment_seconds,
            r.seconds_one
        );
    }
    let _ = spec;
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_time_row_gives_the_ratios_overall_summed_and_by_materials_found() {
        let t = |found, seconds, one| Timing {
            found,
            seconds,
            segment: 0.1 * one,
            one,
        };
        // ratios 1.5 and 6 (two materials found), 3 (three)
        let row = time_row("time", &[t(2, 3.0, 2.0), t(3, 3.0, 1.0), t(2, 6.0, 1.0)], 2);
        assert!(row.starts_with("| time | gm 3.000,"), "{row}");
        assert!(row.contains("max 6.000, within 2x 1 of 3;"), "{row}");
        assert!(row.contains("summed 12.0 s / 4.0 s = 3.000"), "{row}");
        assert!(row.contains("finding the materials: gm 0.100 of"), "{row}");
        assert!(
            row.contains("by materials found, 2: gm 3.000 (max 6.000) over 2; 3: gm 3.000 (max 3.000) over 1; each the least of 2 timings |"),
            "{row}"
        );
        assert!(!time_row("time", &[t(2, 3.0, 2.0)], 1).contains("least of"));
        // no segmentation share for timings without one (the whole command's)
        let whole = Timing {
            segment: f64::NAN,
            ..t(2, 3.0, 2.0)
        };
        let row = time_row("command", &[whole], 1);
        assert!(
            row.contains("= 1.500; by materials found, 2: gm 1.500"),
            "{row}"
        );
        assert!(!row.contains("finding the materials"), "{row}");
    }
}
