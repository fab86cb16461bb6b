//! `brdf-rig bench reconstruct`: time and peak memory of a paper-scale reconstruction and
//! optionally the accuracy study. Thin over `eval::bench::reconstruct`: parses the arguments
//! into its options (the timed child process is this binary) and prints.

use super::ranges::int_in;
use brdf_rig::brdf::basis::GridStride;
use brdf_rig::eval::bench::reconstruct::{self, ReconstructBenchOptions};
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Args, Debug)]
pub struct BenchReconstructArgs {
    /// Mesh to render (default: the Stanford Bunny in the data folder).
    #[arg(long)]
    pub mesh: Option<PathBuf>,
    /// Material of the timed run (always left out of its basis).
    #[arg(long, default_value = "alum-bronze")]
    pub material: String,
    #[arg(long, default_value_t = 11, value_parser = int_in(1usize, 360))]
    pub views: usize,
    #[arg(long, default_value_t = 640, value_parser = int_in(8usize, 8192))]
    pub width: usize,
    #[arg(long, default_value_t = 480, value_parser = int_in(8usize, 8192))]
    pub height: usize,
    /// Basis grid stride (theta_h, theta_d, phi_d).
    #[arg(
        long,
        value_delimiter = ',',
        default_values_t = [1usize, 2, 2],
        value_parser = int_in(1usize, 90)
    )]
    pub basis_stride: Vec<usize>,
    #[arg(long, default_value_t = 80, value_parser = int_in(1usize, 300))]
    pub basis_components: usize,
    /// Also run the accuracy study over these materials (comma-separated; `paper` = the six).
    #[arg(long, value_delimiter = ',')]
    pub study: Vec<String>,
    /// Image size of the study's scenes (smaller than the timed run: 6 materials x 5 runs).
    #[arg(
        long,
        value_delimiter = ',',
        default_values_t = [320usize, 240],
        value_parser = int_in(8usize, 8192)
    )]
    pub study_size: Vec<usize>,
    /// Write the markdown page here (e.g. docs/benchmarks-reconstruct.md).
    #[arg(long)]
    pub write: Option<PathBuf>,
    /// Keep the scene folders here instead of a temporary directory.
    #[arg(long)]
    pub keep: Option<PathBuf>,
    /// Time the reconstruction as `reconstruct` runs by default, with the normal refinement
    /// (`--no-refine-normals`: without it).
    #[command(flatten)]
    pub refine: super::reconstruct::RefineSwitch,
    /// When the normals are refined: what the refinement moves (`reconstruct --refine-unknowns`;
    /// default: its default).
    #[arg(long, value_enum)]
    pub refine_unknowns: Option<super::reconstruct::RefineUnknownsArg>,
    /// Time the reconstruction with `--all-pixels` (no reduction of redundant pixels).
    #[arg(long)]
    pub all_pixels: bool,
    /// What each basis fit is given, as `reconstruct --basis-fit` (default: its default).
    #[arg(long, value_parser = super::reconstruct::parse_basis_fit)]
    pub basis_fit: Option<brdf_rig::reconstruct::trials::BasisFit>,
    /// Seed of the timed run's trials (the spread over seeds is the run-to-run noise).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

pub fn run(a: BenchReconstructArgs) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(
        a.basis_stride.len() == 3 && a.study_size.len() == 2,
        "--basis-stride takes three numbers and --study-size two"
    );
    let s = &a.basis_stride;
    let mut command = format!(
        "cargo run --release -- bench reconstruct --material {} --views {} --width {} --height {} --basis-stride {},{},{} --basis-components {}",
        a.material, a.views, a.width, a.height, s[0], s[1], s[2], a.basis_components
    );
    if !a.study.is_empty() {
        command += &format!(
            " --study {} --study-size {},{}",
            a.study.join(","),
            a.study_size[0],
            a.study_size[1]
        );
    }
    if a.refine.on() {
        if let Some(u) = a.refine_unknowns {
            command += &format!(" --refine-unknowns {}", u.name());
        }
    } else {
        command += " --no-refine-normals";
    }
    if a.all_pixels {
        command += " --all-pixels";
    }
    if let Some(f) = a.basis_fit {
        command += &format!(" --basis-fit {}", f.name());
    }
    if a.seed != 1 {
        command += &format!(" --seed {}", a.seed);
    }
    if let Some(w) = &a.write {
        command += &format!(" --write {}", w.display());
    }
    let options = ReconstructBenchOptions {
        mesh: a.mesh.clone(),
        material: a.material.clone(),
        views: a.views,
        width: a.width,
        height: a.height,
        stride: GridStride {
            theta_h: s[0],
            theta_d: s[1],
            phi_d: s[2],
        },
        basis_components: a.basis_components,
        study: a.study.clone(),
        study_size: (a.study_size[0], a.study_size[1]),
        write: a.write.clone(),
        keep: a.keep.clone(),
        refine_normals: a.refine.on(),
        refine_unknowns: a.refine_unknowns.map(|u| u.name().to_string()),
        all_pixels: a.all_pixels,
        basis_fit: a.basis_fit,
        seed: a.seed,
        exe: std::env::current_exe()?,
        command,
    };
    let md = reconstruct::run(&options, &mut super::bench_notes::printer())?;
    out!("{md}");
    Ok(ExitCode::SUCCESS)
}
