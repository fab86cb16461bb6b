//! `brdf-rig light on|off|status`.
//!
//! The firmware's watchdog switches the light off when the host goes silent, so a light
//! switched on by this command stays on only while something talks to the rig: `--hold SECS`
//! keeps this command running (heartbeating) for that long.

use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context;
use clap::{Args, Subcommand};

use brdf_rig::devices::Light;
use brdf_rig::protocol::messages::MAX_CHANNELS;

use super::ranges::{Closed, Open, int_in, real_in};

use super::rig::RigArgs;

#[derive(Args, Debug)]
pub struct LightArgs {
    #[command(flatten)]
    pub rig: RigArgs,
    #[command(subcommand)]
    pub command: LightCommand,
}

#[derive(Subcommand, Debug)]
pub enum LightCommand {
    /// Switch CHANNEL on (every other channel off unless --add) and wait until it is stable.
    On {
        #[arg(value_parser = int_in(0usize, MAX_CHANNELS - 1))]
        channel: usize,
        /// Level in (0, 1], at most the channel's `max_level` in the profile.
        #[arg(long, default_value_t = 1.0, value_parser = real_in(Open(0.0), Closed(1.0)))]
        level: f64,
        /// Keep the other channels as they are.
        #[arg(long)]
        add: bool,
        /// Stay connected this many seconds, so the watchdog keeps the light on (0 to 86400).
        #[arg(long, default_value_t = 0.0, value_parser = real_in(Closed(0.0), Closed(86_400.0)))]
        hold: f64,
    },
    /// Switch CHANNEL off, or every channel.
    Off {
        #[arg(value_parser = int_in(0usize, MAX_CHANNELS - 1))]
        channel: Option<usize>,
    },
    /// Print each channel's level and whether it is stable.
    Status,
}

pub fn run(args: LightArgs) -> anyhow::Result<ExitCode> {
    let (profile, mut r) = args.rig.open()?;
    let light = &mut r.light;
    match args.command {
        LightCommand::On {
            channel,
            level,
            add,
            hold,
        } => {
            light
                .on(channel, level, !add)
                .with_context(|| format!("switching light channel {channel} on at {level}"))?;
            if hold > 0.0 {
                print_status(light, &profile)?;
                std::thread::sleep(Duration::from_secs_f64(hold));
            }
        }
        LightCommand::Off { channel } => light.off(channel).context("switching the light off")?,
        LightCommand::Status => {}
    }
    print_status(light, &profile)?;
    Ok(ExitCode::SUCCESS)
}

fn print_status(light: &mut dyn Light, profile: &brdf_rig::profile::Profile) -> anyhow::Result<()> {
    let st = light.status().context("reading the light status")?;
    for (i, c) in st.iter().enumerate() {
        let name = profile
            .light
            .channels
            .get(i)
            .map(|c| c.name.as_str())
            .unwrap_or("?");
        outln!(
            "channel {i} {name:<8} level {:.3} {}",
            c.level,
            if c.level == 0.0 {
                "off"
            } else if c.stable {
                "stable"
            } else {
                "warming up"
            }
        );
    }
    Ok(())
}
