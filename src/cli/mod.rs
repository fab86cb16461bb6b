//! Command-line interface: clap definitions and dispatch. Thin: each subcommand lives in its
//! own file, turns raw arguments into a validated configuration, calls the library and prints.

pub mod calibrate;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

mod ports;

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
    /// List serial ports (to find the rig for a profile's `[serial] port`).
    Ports,
    /// Calibrate the light: direction from a glossy sphere, irradiance from a white board.
    Calibrate(calibrate::CalibrateArgs),
}

pub fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Ports => ports::run(),
        Command::Calibrate(args) => calibrate::run(args).map(|()| ExitCode::SUCCESS),
    }
}
