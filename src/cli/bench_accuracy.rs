//! `brdf-rig bench accuracy`: the paper's simulation grid (METHOD.md section 7), written as
//! markdown tables and raw JSON under `--out` (docs/eval by default). Thin over `eval::accuracy`.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, bail};
use clap::Args;

use super::ranges::int_in;
use brdf_rig::brdf::basis::{BasisSettings, GridStride};
use brdf_rig::brdf::{basis_cache, nbrdf};
use brdf_rig::eval::PAPER_MATERIALS;
use brdf_rig::eval::accuracy::{self, AccuracySpec, Rig, Variant};
use brdf_rig::geometry::mesh::Mesh;
use brdf_rig::reconstruct::core::CoreSettings;
use brdf_rig::reconstruct::nielsen::NielsenSettings;

/// Options every evaluation command shares: scene, basis and reconstruction size.
#[derive(Args, Debug, Clone)]
pub struct EvalCommon {
    /// Meshes by name (spot, bunny) or path to a PLY/OBJ.
    #[arg(long, value_delimiter = ',', default_value = "spot,bunny")]
    pub meshes: Vec<String>,
    /// Trials per reconstruction.
    #[arg(long, default_value_t = 10, value_parser = int_in(1usize, 1000))]
    pub trials: usize,
    /// Sample pixels per trial.
    #[arg(long, default_value_t = 80, value_parser = int_in(1usize, 100_000))]
    pub samples: usize,
    /// Light image size, WxH.
    #[arg(long, default_value = "128x96")]
    pub size: String,
    /// Single-light images per scene.
    #[arg(long, default_value_t = 11, value_parser = int_in(1usize, 360))]
    pub views: usize,
    /// Basis grid stride theta_h,theta_d,phi_d (1,2,2 is the reconstruction default).
    #[arg(long, default_value = "1,2,2")]
    pub basis_stride: String,
    /// Basis components kept.
    #[arg(long, default_value_t = 64, value_parser = int_in(1usize, 300))]
    pub basis_components: usize,
    /// Errors over every N-th MERL bin.
    #[arg(long, default_value_t = 5, value_parser = int_in(1usize, 1000))]
    pub bin_step: usize,
    /// Folder of the neural MERL fits.
    #[arg(long)]
    pub nbrdf_dir: Option<PathBuf>,
    /// Basis cache folder (default: $BRDF_RIG_CACHE or ~/.cache/brdf-rig).
    #[arg(long)]
    pub basis_cache: Option<PathBuf>,
    /// Where the simulated scenes are written (default: a temporary folder, removed after).
    #[arg(long)]
    pub scratch: Option<PathBuf>,
    /// Study knob: the held-out error the ladder's choice reads: `pareto` (the default),
    /// `pareto-patches`, `patches`, `both`, `log` or `linear` (as `bench external --held-out`).
    #[arg(long, value_parser = super::bench_external::parse_metric)]
    pub held_out: Option<brdf_rig::reconstruct::ladder::HeldOutMetric>,
}

#[derive(Args, Debug)]
pub struct BenchAccuracyArgs {
    #[command(flatten)]
    pub common: EvalCommon,
    /// Target materials (neural MERL fit names); default: the paper's six.
    #[arg(long, value_delimiter = ',')]
    pub materials: Vec<String>,
    /// Seeds per scene (SfM-like noise and the trials' pixel draws).
    #[arg(long, default_value_t = 1, value_parser = int_in(1u64, 1000))]
    pub seeds: u64,
    /// Run only "all three assumptions" (no ablation).
    #[arg(long)]
    pub no_ablation: bool,
    /// Light rigs: `spread` (light-view angle over 10-150 degrees, many theta_d) and
    /// `one-light` (one light fixed beside the camera, one theta_d).
    #[arg(long, value_delimiter = ',', default_value = "spread,one-light")]
    pub rigs: Vec<String>,
    /// The one-light rig's angle between the light and the optical axis, degrees.
    #[arg(long, default_value_t = 30.0)]
    pub one_light_deg: f64,
    /// Output folder for accuracy.md and accuracy.json.
    #[arg(long, default_value = "docs/eval")]
    pub out: PathBuf,
    /// Refine the SfM-like mesh's normals from the images; also runs the pipeline on the
    /// unrefined normals and reports the normal error against the truth.
    #[arg(long)]
    pub refine_normals: bool,
    /// Also reconstruct from the exact mesh (the reference for the refinement).
    #[arg(long)]
    pub exact_reference: bool,
}

pub fn parse_size(s: &str) -> anyhow::Result<(usize, usize)> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .with_context(|| format!("--size {s:?}: expected WxH, e.g. 128x96"))?;
    let w: usize = w
        .trim()
        .parse()
        .with_context(|| format!("--size {s:?}: width"))?;
    let h: usize = h
        .trim()
        .parse()
        .with_context(|| format!("--size {s:?}: height"))?;
    if w < 8 || h < 8 {
        bail!("--size {s:?}: at least 8x8");
    }
    Ok((w, h))
}

pub fn parse_stride(s: &str) -> anyhow::Result<GridStride> {
    let v: Vec<usize> = s
        .split(',')
        .map(|p| p.trim().parse::<usize>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--basis-stride {s:?}: expected three integers, e.g. 1,2,2"))?;
    match v.as_slice() {
        [h, d, p] if *h > 0 && *d > 0 && *p > 0 => Ok(GridStride {
            theta_h: *h,
            theta_d: *d,
            phi_d: *p,
        }),
        _ => bail!("--basis-stride {s:?}: expected three positive integers, e.g. 1,2,2"),
    }
}

/// Resolved common options.
pub struct Common {
    pub meshes: Vec<(String, Mesh)>,
    pub materials: Vec<(String, nbrdf::Nbrdf)>,
    pub width: usize,
    pub height: usize,
    pub stride: GridStride,
    pub core: CoreSettings,
    pub cache: PathBuf,
    pub scratch: Scratch,
}

/// The scene folder: given, or a temporary one removed on drop.
pub enum Scratch {
    Given(PathBuf),
    Temp(tempfile::TempDir),
}

impl Scratch {
    pub fn path(&self) -> &Path {
        match self {
            Scratch::Given(p) => p,
            Scratch::Temp(t) => t.path(),
        }
    }
}

impl EvalCommon {
    pub fn resolve(&self) -> anyhow::Result<Common> {
        let (width, height) = parse_size(&self.size)?;
        let stride = parse_stride(&self.basis_stride)?;
        if self.trials == 0 || self.samples == 0 || self.views == 0 {
            bail!("--trials, --samples and --views must be at least 1");
        }
        let meshes = self
            .meshes
            .iter()
            .map(|m| {
                brdf_rig::eval::meshes::load_named_mesh(m)
                    .with_context(|| format!("loading mesh {m}"))
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        let dir = self.nbrdf_dir.clone().unwrap_or_else(nbrdf::default_dir);
        let materials = nbrdf::load_dir(&dir)
            .with_context(|| format!("loading the neural MERL fits from {}", dir.display()))?;
        let mut core = CoreSettings::default();
        core.trials.trials = self.trials;
        core.trials.samples = self.samples;
        if let Some(m) = self.held_out {
            core.ladder.metric = m;
        }
        let scratch = match &self.scratch {
            Some(p) => {
                std::fs::create_dir_all(p).with_context(|| format!("creating {}", p.display()))?;
                Scratch::Given(p.clone())
            }
            None => Scratch::Temp(tempfile::tempdir().context("creating a temporary folder")?),
        };
        Ok(Common {
            meshes,
            materials,
            width,
            height,
            stride,
            core,
            cache: self
                .basis_cache
                .clone()
                .unwrap_or_else(basis_cache::default_cache_dir),
            scratch,
        })
    }

    /// The options as they would be typed, for the "command" line of a generated page.
    pub fn command_args(&self) -> String {
        format!(
            "--meshes {} --trials {} --samples {} --size {} --views {} --basis-stride {} --basis-components {} --bin-step {}",
            self.meshes.join(","),
            self.trials,
            self.samples,
            self.size,
            self.views,
            self.basis_stride,
            self.basis_components,
            self.bin_step
        ) + &self.held_out.map_or(String::new(), |m| {
            format!(" --held-out {}", super::bench_external::metric_name(m))
        })
    }
}

pub fn run(a: BenchAccuracyArgs) -> anyhow::Result<ExitCode> {
    let c = a.common.resolve()?;
    let materials: Vec<String> = if a.materials.is_empty() {
        PAPER_MATERIALS.iter().map(|s| s.to_string()).collect()
    } else {
        a.materials.clone()
    };
    for m in &materials {
        if !c.materials.iter().any(|(n, _)| n == m) {
            bail!("--materials: {m:?} is not among the neural MERL fits");
        }
    }
    if !(a.one_light_deg > 0.0 && a.one_light_deg < 90.0) {
        bail!(
            "--one-light-deg must be in (0, 90) degrees, got {}",
            a.one_light_deg
        );
    }
    let rigs = a
        .rigs
        .iter()
        .map(|r| match r.as_str() {
            "spread" => Ok(Rig::Spread),
            "one-light" => Ok(Rig::OneLight {
                alpha_deg: a.one_light_deg,
            }),
            other => bail!("--rigs: unknown rig {other:?} (spread, one-light)"),
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let variants = if a.no_ablation {
        vec![Variant::ALL]
    } else {
        Variant::ablation()
    };
    let spec = AccuracySpec {
        materials: materials.clone(),
        mesh_names: c.meshes.iter().map(|(n, _)| n.clone()).collect(),
        meshes: c.meshes,
        views: a.common.views,
        width: c.width,
        height: c.height,
        basis: BasisSettings {
            stride: c.stride,
            basis_components: a.common.basis_components,
            exclude: Vec::new(),
        },
        basis_stride: [c.stride.theta_h, c.stride.theta_d, c.stride.phi_d],
        basis_components: a.common.basis_components,
        core: c.core,
        nielsen: NielsenSettings::default(),
        sfm_iterations: 10,
        sfm_noise_rel: 0.05,
        variants,
        bin_step: a.common.bin_step,
        seeds: a.seeds.max(1),
        rigs,
        refine: a
            .refine_normals
            .then(brdf_rig::reconstruct::refine::RefineSettings::default),
        exact_reference: a.exact_reference,
    };
    let mut command = format!(
        "cargo run --release -- bench accuracy --materials {} {}",
        materials.join(","),
        a.common.command_args()
    );
    if a.seeds > 1 {
        command += &format!(" --seeds {}", a.seeds);
    }
    if a.no_ablation {
        command += " --no-ablation";
    }
    command += &format!(
        " --rigs {} --one-light-deg {}",
        a.rigs.join(","),
        a.one_light_deg
    );
    if a.refine_normals {
        command += " --refine-normals";
    }
    if a.exact_reference {
        command += " --exact-reference";
    }
    command += &format!(" --out {}", a.out.display());
    let machine = brdf_rig::eval::host::machine();
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let start = std::time::Instant::now();
    let mut done = Vec::new();
    let out_dir = a.out.clone();
    let write = |results: &[accuracy::SceneResult], secs: f64| -> anyhow::Result<()> {
        let mut md = accuracy::markdown(&spec, results, &command, &machine);
        md += &format!("\nTotal wall time: {secs:.0} s.\n");
        let md_path = out_dir.join("accuracy.md");
        std::fs::write(&md_path, md).with_context(|| format!("writing {}", md_path.display()))?;
        let json = serde_json::json!({
            "note": "ground truth: neural fits of the MERL materials (Sztrajman et al. 2021), smooth approximations, not measured MERL data",
            "command": command,
            "machine": machine,
            "spec": spec,
            "scenes": results,
            "seconds": secs,
        });
        let json_path = out_dir.join("accuracy.json");
        std::fs::write(&json_path, serde_json::to_string_pretty(&json)?)
            .with_context(|| format!("writing {}", json_path.display()))?;
        Ok(())
    };
    let mut write_err = None;
    let results = accuracy::run(
        &spec,
        &c.materials,
        &c.cache,
        c.scratch.path(),
        &mut |line| eprintln!("[{:7.1} s] {line}", start.elapsed().as_secs_f64()),
        &mut |r| {
            if let Some(a) = r.all() {
                eprintln!(
                    "  {} on {} ({}): ours env {:.3} ({}), Lambert {:.3}, Lambert+GGX {:.3}, ratio {:.2}",
                    r.material,
                    r.mesh,
                    r.rig.label(),
                    a.chosen.environment,
                    a.model.family,
                    r.lambert.map_or(f64::NAN, |e| e.environment),
                    r.lambert_ggx.map_or(f64::NAN, |e| e.environment),
                    accuracy::ratio(r).unwrap_or(f64::NAN)
                );
            }
            if let Some(n) = &r.normals {
                eprintln!(
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
                );
                for it in &n.report.iterations {
                    eprintln!(
                        "    iteration {}: tilt mean {:.2} max {:.2} deg, train {:.4}, held-out {:.4}, {:.2} s",
                        it.iteration, it.mean_tilt_deg, it.max_tilt_deg, it.train_error, it.held_out_error, it.seconds
                    );
                }
            }
            done.push(r.clone());
            // Partial results on disk after every scene: a long run cut short still reports.
            if let Err(e) = write(&done, start.elapsed().as_secs_f64()) {
                write_err = Some(e);
            }
        },
    )
    .context("running the accuracy grid")?;
    if let Some(e) = write_err {
        return Err(e);
    }
    write(&results, start.elapsed().as_secs_f64())?;
    println!(
        "{}",
        accuracy::markdown(&spec, &results, &command, &machine)
    );
    eprintln!("wrote {}/accuracy.md and accuracy.json", a.out.display());
    Ok(ExitCode::SUCCESS)
}
