//! Command-line interface: clap definitions and dispatch. Thin: each subcommand lives in its
//! own file, turns raw arguments into a validated configuration, calls the library and prints.

mod cameras;
mod merl;
mod session;

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
    /// List the cameras each backend finds (sim, gphoto2, webcam, v4l2).
    Cameras(cameras::CamerasArgs),
    /// Inspect a session folder.
    Session(session::SessionArgs),
    /// List serial ports (to find the rig for a profile's `[serial] port`).
    Ports,
    /// Evaluate and convert BRDF files (MERL tables, neural MERL fits).
    Merl(merl::MerlArgs),
}

pub fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Cameras(a) => cameras::run(a),
        Command::Session(a) => session::run(a),
        Command::Ports => ports::run(),
        Command::Merl(args) => merl::run(args),
    }
}
