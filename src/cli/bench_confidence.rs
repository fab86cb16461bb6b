//! `brdf-rig bench confidence`: tune the confidence verdict's thresholds on one mesh's half of
//! an accuracy grid and check them on the other; writes confidence.md. Thin over
//! `eval::bench::confidence`: parses the arguments into its options and prints.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;

use brdf_rig::eval::bench::confidence::{self, ConfidenceBenchOptions};

#[derive(Args, Debug)]
pub struct BenchConfidenceArgs {
    /// The accuracy grid's JSON (`bench accuracy`).
    #[arg(long, default_value = "docs/eval/accuracy.json")]
    pub from: PathBuf,
    /// The mesh whose runs tune the thresholds; the others check them.
    #[arg(long, default_value = "spot")]
    pub tune_on: String,
    /// Output folder for confidence.md.
    #[arg(long, default_value = "docs/eval")]
    pub out: PathBuf,
}

pub fn run(a: BenchConfidenceArgs) -> anyhow::Result<ExitCode> {
    let command = format!(
        "cargo run --release -- bench confidence --from {} --tune-on {} --out {}",
        a.from.display(),
        a.tune_on,
        a.out.display()
    );
    let bench = confidence::run(&ConfidenceBenchOptions {
        from: a.from,
        tune_on: a.tune_on,
        out: a.out,
        command,
    })?;
    outln!("{}", bench.markdown);
    outln!("tuned: {:?}", bench.tuned);
    Ok(ExitCode::SUCCESS)
}
