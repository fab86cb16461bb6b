//! `brdf-rig turntable home|move|status`.

use std::process::ExitCode;

use anyhow::Context;
use clap::{Args, Subcommand};

use brdf_rig::devices::Turntable;

use super::rig::RigArgs;

use super::ranges::{Closed, real_in};

/// The widest angle the wire carries: millidegrees in a signed 32-bit number.
const MAX_DEG: f64 = 2_147_483.0;

#[derive(Args, Debug)]
pub struct TurntableArgs {
    #[command(flatten)]
    pub rig: RigArgs,
    #[command(subcommand)]
    pub command: TurntableCommand,
}

#[derive(Subcommand, Debug)]
pub enum TurntableCommand {
    /// Find the home switch; the angle is 0 afterwards.
    Home,
    /// Move to ANGLE degrees (homes first when the turntable is not homed).
    Move {
        /// Degrees (negative values are fine: `move -45`); the profile's travel limits apply.
        #[arg(
            allow_negative_numbers = true,
            value_parser = real_in(Closed(-MAX_DEG), Closed(MAX_DEG))
        )]
        angle: f64,
        /// ANGLE is relative to the current position.
        #[arg(long)]
        relative: bool,
    },
    /// Print angle, target, homed and moving.
    Status,
}

pub fn run(args: TurntableArgs) -> anyhow::Result<ExitCode> {
    let (_profile, mut r) = args.rig.open()?;
    let tt = &mut r.turntable;
    match args.command {
        TurntableCommand::Home => tt.home().context("homing the turntable")?,
        TurntableCommand::Move { angle, relative } => {
            let s = tt.status().context("reading the turntable status")?;
            if !s.homed {
                errln!("turntable not homed: homing first");
                tt.home().context("homing the turntable")?;
            }
            if relative {
                tt.move_by(angle)
                    .with_context(|| format!("moving the turntable by {angle} deg"))?;
            } else {
                tt.move_to(angle)
                    .with_context(|| format!("moving the turntable to {angle} deg"))?;
            }
        }
        TurntableCommand::Status => {}
    }
    let s = tt.status().context("reading the turntable status")?;
    outln!(
        "angle {:.3} deg, target {:.3} deg, {}, {}",
        s.angle_deg,
        s.target_deg,
        if s.homed { "homed" } else { "not homed" },
        if s.moving { "moving" } else { "at rest" }
    );
    Ok(ExitCode::SUCCESS)
}
