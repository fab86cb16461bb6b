//! Command-line interface: clap definitions and dispatch. Thin: each subcommand lives in its
//! own file, turns raw arguments into a validated configuration, calls the library and prints.

// first: its macros (`outln!`, `out!`, `errln!`, `errout!`) are for every module below
#[macro_use]
pub(crate) mod output;

pub mod calibrate;
mod calibrate_session;
mod demo;
mod merl;
mod ranges;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

mod bench;
mod bench_accuracy;
mod bench_capture;
mod bench_confidence;
mod bench_external;
mod bench_knobs;
mod bench_materials;
mod bench_notes;
mod bench_reconstruct;
mod bench_render;
mod bench_sweeps;
mod cameras;
mod capture;
mod firmware;
mod light;
mod ports;
mod reconstruct;
mod report;
mod rig;
mod serve;
mod session;
mod turntable;

#[derive(Parser, Debug)]
#[command(
    name = "brdf-rig",
    version,
    about = "Drive a turntable BRDF rig and recover an object's BRDF"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// The whole story on the simulated rig: capture, calibrate, reconstruct, report.
    Demo(demo::DemoArgs),
    /// Reference firmware for the rig's Arduino Mega 2560.
    Firmware {
        #[command(subcommand)]
        command: firmware::FirmwareCommand,
    },
    /// Run a capture session (new with --out, or continue one with --resume).
    Capture(capture::CaptureArgs),
    /// List the cameras each backend finds (sim, gphoto2, webcam, v4l2).
    Cameras(cameras::CamerasArgs),
    /// Inspect a session folder: `session verify DIR` re-checks every checksum.
    Session(session::SessionArgs),
    /// List serial ports (to find the rig for a profile's `[serial] port`).
    Ports,
    /// Evaluate and convert BRDF files (MERL tables, neural MERL fits).
    Merl(merl::MerlArgs),
    /// Recover a BRDF from a reconstruction job (mesh, COLMAP poses, single-light images).
    Reconstruct(reconstruct::Args),
    /// Write a self-contained HTML report of a session or reconstruction folder.
    Report(report::ReportArgs),
    /// Talk to the rig: `rig check` connects, shakes hands and prints what it found.
    Rig(rig::RigCommandArgs),
    /// Home, move or query the turntable.
    Turntable(turntable::TurntableArgs),
    /// Switch light channels on and off, or query them.
    Light(light::LightArgs),
    /// Measurements behind the tables in docs/benchmarks-*.md.
    Bench(bench::BenchArgs),
    /// Calibrate the light: direction from a glossy sphere, irradiance from a white board.
    Calibrate(calibrate::CalibrateArgs),
    /// The lab page: run guided and unattended captures from a browser (live preview, next
    /// step, progress, the session's checksums). Listens on 127.0.0.1:8080 by default.
    Serve(serve::ServeArgs),
}

pub fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Demo(a) => demo::run(a),
        Command::Firmware { command } => firmware::run(command),
        Command::Capture(a) => capture::run(a),
        Command::Cameras(a) => cameras::run(a),
        Command::Session(a) => session::run(a),
        Command::Ports => ports::run(),
        Command::Merl(args) => merl::run(args),
        Command::Reconstruct(args) => reconstruct::run(args),
        Command::Report(args) => report::run(args),
        Command::Rig(a) => rig::run(a),
        Command::Turntable(a) => turntable::run(a),
        Command::Light(a) => light::run(a),
        Command::Bench(a) => bench::run(a),
        Command::Calibrate(args) => calibrate::run(args).map(|()| ExitCode::SUCCESS),
        Command::Serve(args) => serve::run(args),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;
    use clap::CommandFactory;

    /// Every command parses with its defaults: each range-checked default is in its range, and
    /// each value parser yields the type its field has (a mismatch would panic here, not at a
    /// user's command line).
    #[test]
    fn every_command_parses_its_defaults() {
        Cli::command().debug_assert();
        for args in [
            "capture --out o",
            "capture --resume o",
            "reconstruct j.toml --out o",
            "reconstruct j.toml --out o --components 3",
            "calibrate s",
            "calibrate sphere --image a.exr --intrinsics 1,1,1,1",
            "calibrate white --image a.exr --albedo 1 --light-dir 0,0,1",
            "light on 0",
            "light off",
            "light off 2",
            "turntable move -5",
            "report d",
            "merl eval f 1 2 3 4",
            "bench rig",
            "bench accuracy",
            "bench speed",
            "bench stability",
            "bench render",
            "bench capture",
            "bench capture --page --reps 2",
            "bench reconstruct",
            "serve",
            "serve --bind 0.0.0.0:0 --token-file t --preview-size 320x240",
        ] {
            let argv = std::iter::once("brdf-rig").chain(args.split(' '));
            if let Err(e) = Cli::try_parse_from(argv) {
                panic!("{args}: {e}");
            }
        }
    }

    /// The study knobs take their documented words, and a wrong one is refused with the
    /// value and the words it could have been.
    #[test]
    fn basis_fit_and_unobserved_take_their_words_and_name_a_wrong_one() {
        for args in [
            "reconstruct j.toml --out o --basis-fit samples --unobserved transfer-basis",
            "reconstruct j.toml --out o --min-gain 0",
            "reconstruct j.toml --out o --peak-energy 0",
            "bench materials --peak-energy 2.5",
            "reconstruct j.toml --out o --lambert-ggx-f0 free",
            "bench external --scenes s --lambert-ggx-f0 physical",
            "bench accuracy --basis-fit rows --unobserved transfer --min-gain 0.05",
            "bench external --scenes s --unobserved model --min-gain 0",
            "bench reconstruct --basis-fit samples",
        ] {
            let argv = std::iter::once("brdf-rig").chain(args.split(' '));
            if let Err(e) = Cli::try_parse_from(argv) {
                panic!("{args}: {e}");
            }
        }
        for (args, words) in [
            (
                "reconstruct j.toml --out o --basis-fit all",
                "rows or samples",
            ),
            (
                "reconstruct j.toml --out o --unobserved prior",
                "model, transfer or transfer-basis",
            ),
            ("bench external --scenes s --min-gain 2", "in [0, 1]"),
            ("reconstruct j.toml --out o --min-gain 1.5", "in [0, 1]"),
            ("reconstruct j.toml --out o --peak-energy 11", "in [0, 10]"),
            ("bench accuracy --peak-energy=-1", "in [0, 10]"),
            (
                "reconstruct j.toml --out o --lambert-ggx-f0 dielectric",
                "physical or free",
            ),
        ] {
            let argv = std::iter::once("brdf-rig").chain(args.split(' '));
            let e = Cli::try_parse_from(argv).err().unwrap().to_string();
            assert!(e.contains(words), "{args}: {e}");
        }
    }
}
