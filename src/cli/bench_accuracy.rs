//! `brdf-rig bench accuracy`: the paper's simulation grid (METHOD.md section 7), written as
//! markdown tables and raw JSON under `--out` (docs/eval by default). Thin over
//! `eval::bench::accuracy`: parses the arguments into its options and prints.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, bail};
use clap::Args;

use super::ranges::int_in;
use brdf_rig::brdf::basis::GridStride;
use brdf_rig::eval::accuracy::Rig;
use brdf_rig::eval::bench::accuracy::{
    self, AccuracyBenchOptions, SceneOptions, materials_or_paper,
};

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
    /// Study knob: the held-out error the ladder's choice reads: `log` (the default), `pareto`,
    /// `pareto-patches`, `front`, `patches`, `both` or `linear` (as `bench external --held-out`).
    #[arg(long, value_parser = super::bench_external::parse_metric)]
    pub held_out: Option<brdf_rig::reconstruct::ladder::HeldOutMetric>,
    #[command(flatten)]
    pub knobs: super::bench_knobs::FitKnobs,
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
    /// Refine the SfM-like mesh's normals from the images, as `reconstruct` does by default
    /// (`--no-refine-normals`: not); with the refinement the pipeline also runs on the
    /// unrefined normals and the normal error against the truth is reported.
    #[command(flatten)]
    pub refine: super::reconstruct::RefineSwitch,
    /// When the normals are refined: what the refinement moves (`reconstruct --refine-unknowns`).
    #[arg(long, value_enum, default_value = "depth")]
    pub refine_unknowns: super::reconstruct::RefineUnknownsArg,
    /// Study knob: leave out of the normal refinement the pixels of another material's colour
    /// near the labels' boundary (`reconstruct --refine-colour-rule`).
    #[arg(long)]
    pub refine_colour_rule: bool,
    /// The SfM-like mesh's normal noise: standard deviation of each vertex's displacement along
    /// its normal, in mean edge lengths (`geometry::sfm_like`).
    #[arg(long, default_value_t = 0.05, value_parser = super::ranges::real_in(super::ranges::Closed(0.0), super::ranges::Closed(2.0)))]
    pub sfm_noise: f64,
    /// The SfM-like mesh's smoothing: Taubin iterations before the noise.
    #[arg(long, default_value_t = 10, value_parser = int_in(0usize, 1000))]
    pub sfm_smoothing: usize,
    /// Also reconstruct from the exact mesh (the reference for the refinement).
    #[arg(long)]
    pub exact_reference: bool,
}

/// `--rigs` (spread, one-light) with `--one-light-deg` (in (0, 90) degrees).
pub fn parse_rigs(rigs: &[String], one_light_deg: f64) -> anyhow::Result<Vec<Rig>> {
    if !(one_light_deg > 0.0 && one_light_deg < 90.0) {
        bail!("--one-light-deg must be in (0, 90) degrees, got {one_light_deg}");
    }
    rigs.iter()
        .map(|r| match r.as_str() {
            "spread" => Ok(Rig::Spread),
            "one-light" => Ok(Rig::OneLight {
                alpha_deg: one_light_deg,
            }),
            other => bail!("--rigs: unknown rig {other:?} (spread, one-light)"),
        })
        .collect()
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

impl EvalCommon {
    /// The options as the library takes them; the size and stride parsed.
    pub fn scene_options(&self) -> anyhow::Result<SceneOptions> {
        let (width, height) = parse_size(&self.size)?;
        let stride = parse_stride(&self.basis_stride)?;
        Ok(SceneOptions {
            meshes: self.meshes.clone(),
            trials: self.trials,
            samples: self.samples,
            width,
            height,
            stride,
            basis_components: self.basis_components,
            bin_step: self.bin_step,
            nbrdf_dir: self.nbrdf_dir.clone(),
            basis_cache: self.basis_cache.clone(),
            scratch: self.scratch.clone(),
            held_out: self.held_out,
            overrides: self.knobs.overrides(),
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
        }) + &self.knobs.args()
    }
}

pub fn run(a: BenchAccuracyArgs) -> anyhow::Result<ExitCode> {
    let scene = a.common.scene_options()?;
    let materials = materials_or_paper(&a.materials);
    let rigs = parse_rigs(&a.rigs, a.one_light_deg)?;
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
    command += &a
        .refine_unknowns
        .command_args(a.refine.on(), a.refine_colour_rule);
    if a.exact_reference {
        command += " --exact-reference";
    }
    if a.sfm_noise != 0.05 || a.sfm_smoothing != 10 {
        command += &format!(
            " --sfm-noise {} --sfm-smoothing {}",
            a.sfm_noise, a.sfm_smoothing
        );
    }
    command += &format!(" --out {}", a.out.display());
    let options = AccuracyBenchOptions {
        scene,
        views: a.common.views,
        materials,
        seeds: a.seeds,
        rigs,
        no_ablation: a.no_ablation,
        refine: a
            .refine_unknowns
            .settings(a.refine.on(), a.refine_colour_rule),
        sfm_noise_rel: a.sfm_noise,
        sfm_iterations: a.sfm_smoothing,
        exact_reference: a.exact_reference,
        out: a.out.clone(),
        command,
    };
    let bench = accuracy::run(&options, &mut super::bench_notes::printer())?;
    outln!("{}", bench.markdown);
    errln!("wrote {}/accuracy.md and accuracy.json", a.out.display());
    Ok(ExitCode::SUCCESS)
}
