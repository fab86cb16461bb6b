//! `brdf-rig bench speed` and `brdf-rig bench stability`: one knob at a time around the
//! defaults on one simulated scene; tables, raw JSON and SVG charts under `--out`.
//! Thin over `eval::bench::sweeps`: parses the arguments into its options and prints.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;

use super::ranges::int_in;
use brdf_rig::eval::bench::sweeps::{self, SweepBenchOptions};

#[derive(Args, Debug)]
pub struct BenchSweepArgs {
    /// Target material (neural MERL fit name).
    #[arg(long, default_value = "green-latex")]
    pub material: String,
    /// Mesh by name (spot, bunny) or path.
    #[arg(long, default_value = "spot")]
    pub mesh: String,
    /// Seeds per setting (SfM-like noise, trials; for stability also image noise and light error).
    #[arg(long, default_value_t = 3, value_parser = int_in(1u64, 1000))]
    pub seeds: u64,
    /// Materials of the "flat BRDF" sweep (stability only).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "green-latex,pink-fabric,pink-fabric2"
    )]
    pub flat: Vec<String>,
    /// Only these sweeps (names as in the table, substring match).
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    #[arg(long, default_value_t = 5, value_parser = int_in(1usize, 1000))]
    pub bin_step: usize,
    #[arg(long)]
    pub basis_cache: Option<PathBuf>,
    #[arg(long, default_value = "docs/eval")]
    pub out: PathBuf,
}

fn common_args(a: &BenchSweepArgs) -> String {
    let mut s = format!("--material {} --mesh {}", a.material, a.mesh);
    if !a.only.is_empty() {
        s += &format!(" --only {}", a.only.join(","));
    }
    s += &format!(" --out {}", a.out.display());
    s
}

fn options(a: BenchSweepArgs, command: String) -> SweepBenchOptions {
    SweepBenchOptions {
        material: a.material,
        mesh: a.mesh,
        seeds: a.seeds,
        flat: a.flat,
        only: a.only,
        bin_step: a.bin_step,
        basis_cache: a.basis_cache,
        out: a.out,
        command,
    }
}

pub fn speed(a: BenchSweepArgs) -> anyhow::Result<ExitCode> {
    let command = format!(
        "cargo run --release -- bench speed --seeds {} {}",
        a.seeds,
        common_args(&a)
    );
    let md = sweeps::speed(&options(a, command), &mut super::bench_notes::printer())?;
    out!("{md}");
    Ok(ExitCode::SUCCESS)
}

pub fn stability(a: BenchSweepArgs) -> anyhow::Result<ExitCode> {
    let command = format!(
        "cargo run --release -- bench stability --seeds {} --flat {} {}",
        a.seeds,
        a.flat.join(","),
        common_args(&a)
    );
    let md = sweeps::stability(&options(a, command), &mut super::bench_notes::printer())?;
    out!("{md}");
    Ok(ExitCode::SUCCESS)
}
