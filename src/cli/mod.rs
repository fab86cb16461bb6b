//! Command-line interface: clap definitions and dispatch. Thin: each subcommand lives in its
//! own file, turns raw arguments into a validated configuration, calls the library and prints.

mod merl;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

mod firmware;
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
    /// Reference firmware for the rig's Arduino Mega 2560.
    Firmware {
        #[command(subcommand)]
        command: firmware::FirmwareCommand,
    },
    /// List serial ports (to find the rig for a profile's `[serial] port`).
    Ports,
    /// Evaluate and convert BRDF files (MERL tables, neural MERL fits).
    Merl(merl::MerlArgs),
}

pub fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Firmware { command } => firmware::run(command),
        Command::Ports => ports::run(),
        Command::Merl(args) => merl::run(args),
    }
}
