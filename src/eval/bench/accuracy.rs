//! `brdf-rig bench accuracy`: the paper's simulation grid (METHOD.md section 7) run through
//! [`crate::eval::accuracy`], written as accuracy.md and accuracy.json under the output folder
//! (after every scene, so a long run cut short still reports).

use std::path::PathBuf;
use std::time::Instant;

use super::{BenchError, Note, Scratch, create_dir, load_materials, write_file};
use crate::brdf::basis::{BasisSettings, GridStride};
use crate::brdf::basis_cache;
use crate::brdf::nbrdf::Nbrdf;
use crate::eval::PAPER_MATERIALS;
use crate::eval::accuracy::{self, AccuracySpec, Rig, SceneResult, Variant};
use crate::geometry::mesh::Mesh;
use crate::reconstruct::core::CoreSettings;
use crate::reconstruct::ladder::HeldOutMetric;
use crate::reconstruct::nielsen::NielsenSettings;

/// Options every evaluation on simulated scenes shares: scene, basis and reconstruction size.
#[derive(Clone, Debug)]
pub struct SceneOptions {
    /// Meshes by name (`spot`, `bunny`) or path.
    pub meshes: Vec<String>,
    pub trials: usize,
    pub samples: usize,
    /// Light image size.
    pub width: usize,
    pub height: usize,
    pub stride: GridStride,
    pub basis_components: usize,
    /// Errors over every N-th MERL bin.
    pub bin_step: usize,
    /// The neural MERL fits (`None`: the data folder's).
    pub nbrdf_dir: Option<PathBuf>,
    /// The basis cache (`None`: [`basis_cache::default_cache_dir`]).
    pub basis_cache: Option<PathBuf>,
    /// Where the scenes are written (`None`: a temporary folder, removed after).
    pub scratch: Option<PathBuf>,
    /// The held-out error the ladder's choice reads (`None`: the library's default).
    pub held_out: Option<HeldOutMetric>,
    /// Study overrides of the core's settings (each `None`: the library's default).
    pub overrides: crate::reconstruct::overrides::CoreOverrides,
}

/// [`SceneOptions`] with their meshes, materials and folders loaded.
pub struct Resolved {
    pub meshes: Vec<(String, Mesh)>,
    pub materials: Vec<(String, Nbrdf)>,
    pub core: CoreSettings,
    pub cache: PathBuf,
    pub scratch: Scratch,
}

impl SceneOptions {
    pub fn resolve(&self) -> Result<Resolved, BenchError> {
        if self.trials == 0 || self.samples == 0 {
            return Err(BenchError::Invalid(
                "--trials, --samples and --views must be at least 1".into(),
            ));
        }
        let meshes = self
            .meshes
            .iter()
            .map(|m| {
                crate::eval::meshes::load_named_mesh(m).map_err(|source| BenchError::Mesh {
                    name: m.clone(),
                    source,
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let materials = load_materials(self.nbrdf_dir.as_deref())?;
        let mut core = CoreSettings::default();
        core.trials.trials = self.trials;
        core.trials.samples = self.samples;
        if let Some(m) = self.held_out {
            core.ladder.metric = m;
        }
        self.overrides.apply(&mut core);
        let scratch = Scratch::new(self.scratch.as_deref())?;
        Ok(Resolved {
            meshes,
            materials,
            core,
            cache: self
                .basis_cache
                .clone()
                .unwrap_or_else(basis_cache::default_cache_dir),
            scratch,
        })
    }
}

/// The options of `bench accuracy`.
#[derive(Clone, Debug)]
pub struct AccuracyBenchOptions {
    pub scene: SceneOptions,
    /// Single-light images per scene.
    pub views: usize,
    /// Target materials (see [`materials_or_paper`]).
    pub materials: Vec<String>,
    /// Seeds per scene (at least 1).
    pub seeds: u64,
    pub rigs: Vec<Rig>,
    /// Only "all three assumptions" (no ablation).
    pub no_ablation: bool,
    /// Refine the SfM-like mesh's normals from the images (`None`: off).
    pub refine: Option<crate::reconstruct::refine::RefineSettings>,
    /// The SfM-like mesh (`geometry::sfm_like`): noise in mean edge lengths, Taubin iterations.
    pub sfm_noise_rel: f64,
    pub sfm_iterations: usize,
    pub exact_reference: bool,
    /// Folder of accuracy.md and accuracy.json.
    pub out: PathBuf,
    /// The command as typed, quoted by the pages.
    pub command: String,
}

/// The materials given, or the paper's six when none is.
pub fn materials_or_paper(given: &[String]) -> Vec<String> {
    if given.is_empty() {
        PAPER_MATERIALS.iter().map(|s| s.to_string()).collect()
    } else {
        given.to_vec()
    }
}

/// What the grid gave: every scene, and the markdown page written.
pub struct AccuracyBench {
    pub results: Vec<SceneResult>,
    pub markdown: String,
}

/// One scene's summary lines, as the run reports them.
pub fn scene_summary(r: &SceneResult) -> String {
    let mut lines = Vec::new();
    if let Some(a) = r.all() {
        lines.push(format!(
            "  {} on {} ({}): ours env {:.3} ({}), Lambert {:.3}, Lambert+GGX {:.3}, ratio {:.2}",
            r.material,
            r.mesh,
            r.rig.label(),
            a.chosen.environment,
            a.model.family,
            r.lambert.map_or(f64::NAN, |e| e.environment),
            r.lambert_ggx.map_or(f64::NAN, |e| e.environment),
            accuracy::ratio(r).unwrap_or(f64::NAN)
        ));
    }
    if let Some(n) = &r.normals {
        lines.push(format!(
            "  normals: median error {:.2} -> {:.2} deg (pixels {:.2} -> {:.2}; {}, {} iteration(s), mean tilt {:.2} deg); unrefined env {:.3}, exact env {:.3}",
            n.median_before_deg,
            n.median_after_deg,
            n.pixel_median_before_deg,
            n.pixel_median_after_deg,
            if n.report.accepted { "accepted" } else { "refused" },
            n.report.chosen_iterations,
            n.report.mean_tilt_deg,
            r.unrefined.as_ref().and_then(|x| x.as_ref().ok()).map_or(f64::NAN, |a| a.chosen.environment),
            r.exact.as_ref().and_then(|x| x.as_ref().ok()).map_or(f64::NAN, |a| a.chosen.environment),
        ));
        for it in &n.report.iterations {
            lines.push(format!(
                "    iteration {}: tilt mean {:.2} max {:.2} deg, train {:.4}, held-out {:.4}, {:.2} s",
                it.iteration,
                it.mean_tilt_deg,
                it.max_tilt_deg,
                it.train_error,
                it.held_out_error,
                it.seconds
            ));
        }
    }
    lines.join("\n")
}

/// Runs the grid, writing accuracy.md and accuracy.json under `o.out` after every scene.
pub fn run(
    o: &AccuracyBenchOptions,
    note: &mut dyn FnMut(Note<'_>),
) -> Result<AccuracyBench, BenchError> {
    if o.views == 0 {
        return Err(BenchError::Invalid(
            "--trials, --samples and --views must be at least 1".into(),
        ));
    }
    let c = o.scene.resolve()?;
    let materials = materials_or_paper(&o.materials);
    for m in &materials {
        if !c.materials.iter().any(|(n, _)| n == m) {
            return Err(BenchError::Invalid(format!(
                "--materials: {m:?} is not among the neural MERL fits"
            )));
        }
    }
    let variants = if o.no_ablation {
        vec![Variant::ALL]
    } else {
        Variant::ablation()
    };
    let stride = o.scene.stride;
    let spec = AccuracySpec {
        materials: materials.clone(),
        mesh_names: c.meshes.iter().map(|(n, _)| n.clone()).collect(),
        meshes: c.meshes,
        views: o.views,
        width: o.scene.width,
        height: o.scene.height,
        basis: BasisSettings {
            stride,
            basis_components: o.scene.basis_components,
            exclude: Vec::new(),
        },
        basis_stride: [stride.theta_h, stride.theta_d, stride.phi_d],
        basis_components: o.scene.basis_components,
        core: c.core,
        nielsen: NielsenSettings::default(),
        sfm_iterations: o.sfm_iterations,
        sfm_noise_rel: o.sfm_noise_rel,
        variants,
        bin_step: o.scene.bin_step,
        seeds: o.seeds.max(1),
        rigs: o.rigs.clone(),
        refine: o.refine.clone(),
        exact_reference: o.exact_reference,
    };
    let command = &o.command;
    let machine = crate::eval::host::machine();
    create_dir(&o.out)?;
    let start = Instant::now();
    let mut done = Vec::new();
    let write = |results: &[SceneResult], secs: f64| -> Result<(), BenchError> {
        let mut md = accuracy::markdown(&spec, results, command, &machine);
        md += &format!("\nTotal wall time: {secs:.0} s.\n");
        write_file(&o.out.join("accuracy.md"), md)?;
        write_file(
            &o.out.join(accuracy::RATIO_CHART),
            accuracy::ratio_chart(&accuracy::ratios_by_rig(&spec, results))?,
        )?;
        let json = serde_json::json!({
            "note": "ground truth: neural fits of the MERL materials (Sztrajman et al. 2021), smooth approximations, not measured MERL data",
            "command": command,
            "machine": machine,
            "spec": spec,
            "scenes": results,
            "seconds": secs,
        });
        write_file(
            &o.out.join("accuracy.json"),
            serde_json::to_string_pretty(&json)?,
        )
    };
    let mut write_err = None;
    // both callbacks report through `note`
    let note = std::cell::RefCell::new(note);
    let results = accuracy::run(
        &spec,
        &c.materials,
        &c.cache,
        c.scratch.path(),
        &mut |line| (note.borrow_mut())(Note::Step(line)),
        &mut |r| {
            let summary = scene_summary(r);
            if !summary.is_empty() {
                (note.borrow_mut())(Note::Detail(&summary));
            }
            done.push(r.clone());
            // Partial results on disk after every scene: a long run cut short still reports.
            if let Err(e) = write(&done, start.elapsed().as_secs_f64()) {
                write_err = Some(e);
            }
        },
    )
    .map_err(|e| BenchError::step("running the accuracy grid", e))?;
    if let Some(e) = write_err {
        return Err(e);
    }
    write(&results, start.elapsed().as_secs_f64())?;
    let markdown = accuracy::markdown(&spec, &results, command, &machine);
    Ok(AccuracyBench { results, markdown })
}
