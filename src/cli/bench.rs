//! `brdf-rig bench ...`: measurements that produce the tables in `docs/benchmarks-*.md`, with
//! the command that made them. One subcommand per area.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Subcommand};

use super::ranges::{Closed, Open, int_in, real_in};
use brdf_rig::eval::bench::rig::RigPageOptions;
use brdf_rig::eval::rig::RigBenchOptions;

#[derive(Args, Debug)]
pub struct BenchArgs {
    #[command(subcommand)]
    pub command: BenchCommand,
}

#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// STATUS round trip and controller overhead per step, over a pty to the simulated firmware.
    Rig(BenchRigArgs),
    /// The paper's simulation grid: materials x meshes, ablation, baselines, chosen-trial rank.
    Accuracy(super::bench_accuracy::BenchAccuracyArgs),
    /// Error against time, one knob at a time (image size, samples, trials, k, basis grid).
    Speed(super::bench_sweeps::BenchSweepArgs),
    /// Error under perturbations (normal noise, image noise, clipping, views, light error).
    Stability(super::bench_sweeps::BenchSweepArgs),
    /// Rasterisation, shadows, curvature and shading of the bunny at 640x480.
    Render(super::bench_render::BenchRenderArgs),
    /// Shots per second of whole simulated captures and the controller's overhead per shot.
    Capture(super::bench_capture::BenchCaptureArgs),
    /// Time, peak memory and accuracy of reconstruction on a simulated Bunny scene.
    Reconstruct(super::bench_reconstruct::BenchReconstructArgs),
    /// The reconstruction on scenes rendered by Mitsuba 3 (scripts/render_recon_scenes.py).
    External(super::bench_external::BenchExternalArgs),
    /// Tune the confidence thresholds on one mesh of an accuracy grid, check on the other.
    Confidence(super::bench_confidence::BenchConfidenceArgs),
    /// Objects of several materials: segmentation against the truth, one BRDF per material.
    Materials(super::bench_materials::BenchMaterialsArgs),
}

#[derive(Args, Debug)]
pub struct BenchRigArgs {
    /// Rig profile with `port = "sim"` (default: the built-in simulated rig).
    #[arg(long)]
    pub profile: Option<PathBuf>,
    /// STATUS round trips to time (1 to 1000000).
    #[arg(long, default_value_t = 2000, value_parser = int_in(1usize, 1_000_000))]
    pub round_trips: usize,
    /// Turntable steps to time (1 to 100000).
    #[arg(long, default_value_t = 40, value_parser = int_in(1usize, 100_000))]
    pub steps: usize,
    /// Degrees per step, in (0, 360].
    #[arg(long, default_value_t = 1.0, value_parser = real_in(Open(0.0), Closed(360.0)))]
    pub step_deg: f64,
    /// Also write the markdown page here (e.g. docs/benchmarks-rig.md).
    #[arg(long)]
    pub write: Option<PathBuf>,
}

pub fn run(args: BenchArgs) -> anyhow::Result<ExitCode> {
    match args.command {
        BenchCommand::Rig(a) => rig(a),
        BenchCommand::Accuracy(a) => super::bench_accuracy::run(a),
        BenchCommand::Speed(a) => super::bench_sweeps::speed(a),
        BenchCommand::Stability(a) => super::bench_sweeps::stability(a),
        BenchCommand::Render(a) => super::bench_render::run(a),
        BenchCommand::Capture(a) => super::bench_capture::run(a),
        BenchCommand::Reconstruct(a) => super::bench_reconstruct::run(a),
        BenchCommand::External(a) => super::bench_external::run(a),
        BenchCommand::Confidence(a) => super::bench_confidence::run(a),
        BenchCommand::Materials(a) => super::bench_materials::run(a),
    }
}

fn rig(a: BenchRigArgs) -> anyhow::Result<ExitCode> {
    let bench = RigBenchOptions {
        round_trips: a.round_trips.max(1),
        steps: a.steps.max(1),
        step_deg: a.step_deg,
    };
    let mut command = String::from("cargo run --release -- bench rig");
    if let Some(p) = &a.profile {
        command += &format!(" --profile {}", p.display());
    }
    command += &format!(
        " --round-trips {} --steps {} --step-deg {}",
        bench.round_trips, bench.steps, bench.step_deg
    );
    if let Some(w) = &a.write {
        command += &format!(" --write {}", w.display());
    }
    let md = brdf_rig::eval::bench::rig::run(
        &RigPageOptions {
            profile: a.profile,
            bench,
            write: a.write,
            command,
        },
        &mut super::bench_notes::printer(),
    )?;
    out!("{md}");
    Ok(ExitCode::SUCCESS)
}
