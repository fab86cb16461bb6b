//! `brdf-rig bench render`: rasterisation, shadow rays, curvature, SfM-like smoothing and
//! shading of the Stanford Bunny at 640x480 (docs/benchmarks-render.md). Thin over
//! `eval::bench::render`: parses the arguments into its options and prints.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;

use super::ranges::int_in;
use brdf_rig::eval::bench::render::{self, RenderBenchOptions};

#[derive(Args, Debug)]
pub struct BenchRenderArgs {
    /// Repetitions of each timed step (the median is reported).
    #[arg(long, default_value_t = 5, value_parser = int_in(1usize, 1000))]
    pub runs: usize,
    /// Also write the markdown page here (e.g. docs/benchmarks-render.md).
    #[arg(long)]
    pub write: Option<PathBuf>,
}

pub fn run(a: BenchRenderArgs) -> anyhow::Result<ExitCode> {
    let runs = a.runs.max(1);
    let mut command = format!("cargo run --release -- bench render --runs {runs}");
    if let Some(w) = &a.write {
        command += &format!(" --write {}", w.display());
    }
    let md = render::run(&RenderBenchOptions {
        runs,
        write: a.write,
        command,
    })?;
    out!("{md}");
    Ok(ExitCode::SUCCESS)
}
