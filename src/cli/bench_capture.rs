//! `brdf-rig bench capture`: shots per second of whole simulated captures and the controller's
//! overhead per shot (docs/benchmarks-capture.md). Thin over `eval::bench::capture`: parses the
//! arguments into its options and prints; the captures show on the terminal as `brdf-rig
//! capture`'s do.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::Args;

use brdf_rig::eval::bench::capture::{self, CaptureBenchOptions};

use super::capture::Terminal;
use super::ranges::int_in;

#[derive(Args, Debug)]
pub struct BenchCaptureArgs {
    /// Ambient views of the benchmark plan (single-light shots on every fourth view).
    #[arg(long, default_value_t = 12, value_parser = int_in(1usize, 3600))]
    pub views: usize,
    /// Image sizes to measure (WIDTHxHEIGHT), with the fast turntable.
    #[arg(long, value_delimiter = ',', default_value = "64x48,160x120,320x240")]
    pub sizes: Vec<String>,
    /// Also write the markdown page here (e.g. docs/benchmarks-capture.md).
    #[arg(long)]
    pub write: Option<PathBuf>,
    /// Also measure the lab page (`serve`): the live preview's frame rate at 640x480, and the
    /// 320x240 fast capture through the server with and without a headless Chromium showing
    /// the page (needs Debian's chromium).
    #[arg(long)]
    pub page: bool,
    /// Runs of each capture for --page (the median is reported); 1 to 20.
    #[arg(long, default_value_t = 3, value_parser = int_in(1usize, 20))]
    pub reps: usize,
}

pub fn run(args: BenchCaptureArgs) -> anyhow::Result<ExitCode> {
    let sizes = args
        .sizes
        .iter()
        .map(|size| {
            size.split_once('x')
                .and_then(|(w, h)| Some((w.parse().ok()?, h.parse().ok()?)))
                .with_context(|| format!("--sizes: {size:?} is not WIDTHxHEIGHT"))
        })
        .collect::<anyhow::Result<Vec<(usize, usize)>>>()?;
    // the command that makes the page, as it was run
    let mut command = String::from("brdf-rig bench capture");
    if args.views != 12 {
        let _ = write!(command, " --views {}", args.views);
    }
    if args.page {
        let _ = write!(command, " --page --reps {}", args.reps);
    }
    if let Some(path) = &args.write {
        let _ = write!(command, " --write {}", path.display());
    }
    let bench = capture::run(
        &CaptureBenchOptions {
            views: args.views,
            sizes,
            page: args.page,
            reps: args.reps,
            write: args.write,
            command,
        },
        &mut Terminal,
    )?;
    outln!("{}", bench.table);
    if let Some(p) = &bench.page {
        outln!("{p}");
    }
    Ok(ExitCode::SUCCESS)
}
