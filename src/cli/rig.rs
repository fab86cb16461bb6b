//! `brdf-rig rig check`, and the options every rig command shares (`--profile`, `--port`) with
//! the one place that turns them into an open rig.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Args, Subcommand};

use brdf_rig::devices::rig::Rig;
use brdf_rig::profile::Profile;
use brdf_rig::protocol::caps;
use brdf_rig::rig_factory;

/// How to reach the rig.
#[derive(Args, Debug, Clone)]
pub struct RigArgs {
    /// Rig profile (TOML). Default: the built-in simulated rig, which spawns a simulated firmware
    /// for this one command (state such as homed, angle or lights does not persist between
    /// invocations; run `brdf-rig-simfw` and pass its path with --port for that). With --port
    /// and no profile: the built-in rig with a real board's serial timing (200 ms per reply, 5
    /// re-sends, a 2.5 s boot window after the port opens).
    #[arg(long, global = true, env = "BRDF_RIG_PROFILE")]
    pub profile: Option<PathBuf>,
    /// Serial port path, overriding the profile's `[serial] port`.
    #[arg(long, global = true)]
    pub port: Option<PathBuf>,
}

impl RigArgs {
    pub fn profile(&self) -> anyhow::Result<Profile> {
        Ok(Profile::chosen(
            self.profile.as_deref(),
            self.port.as_deref(),
        )?)
    }

    /// Loads the profile and opens the rig (spawning the simulated firmware for `port = "sim"`).
    pub fn open(&self) -> anyhow::Result<(Profile, Rig)> {
        let profile = self.profile()?;
        let opened = rig_factory::open(&profile, self.port.as_deref()).with_context(|| {
            format!(
                "opening the rig of {} (port {})",
                profile.origin,
                self.port
                    .as_ref()
                    .map(|p| p.display().to_string())
                    .unwrap_or_else(|| profile.serial.port.clone())
            )
        })?;
        if opened.sim.is_some() {
            errln!(
                "note: simulated rig on {}, spawned for this command only (state does not persist \
                 between invocations)",
                opened.rig.port.display()
            );
        }
        Ok((profile, opened.rig))
    }
}

#[derive(Args, Debug)]
pub struct RigCommandArgs {
    #[command(flatten)]
    pub rig: RigArgs,
    #[command(subcommand)]
    pub command: RigCommand,
}

#[derive(Subcommand, Debug)]
pub enum RigCommand {
    /// Connect, shake hands and print the firmware, its limits and the rig's state.
    /// Exits non-zero when the handshake fails.
    Check,
}

pub fn run(args: RigCommandArgs) -> anyhow::Result<ExitCode> {
    match args.command {
        RigCommand::Check => check(&args.rig),
    }
}

fn check(args: &RigArgs) -> anyhow::Result<ExitCode> {
    let (profile, mut r) = args.open()?;
    let h = &r.hello;
    outln!("port:       {}", r.port.display());
    let settings = r.settings();
    let link = &settings.link;
    outln!(
        "link:       first reply {} ms after opening the port (boot window {} ms, then {} ms per \
         reply x {} attempts)",
        r.link_stats().first_reply_ms.unwrap_or(0),
        link.boot_window.as_millis(),
        link.timeout.as_millis(),
        link.retries + 1
    );
    outln!("firmware:   {}", h.name);
    outln!("protocol:   {}.{}", h.major, h.minor);
    outln!("boot:       {}", h.boot);
    let names = [
        (caps::TURNTABLE, "turntable"),
        (caps::LIGHT, "light"),
        (caps::HOME_SWITCH, "home switch"),
        (caps::SIMULTANEOUS_CHANNELS, "simultaneous channels"),
        (caps::WARMUP_SENSING, "warm-up sensing"),
    ];
    let c: Vec<&str> = names
        .iter()
        .filter(|(b, _)| h.caps & b != 0)
        .map(|(_, n)| *n)
        .collect();
    outln!("caps:       {}", c.join(", "));
    outln!(
        "firmware limits: angle [{}, {}] deg, speed {} deg/s, accel {} deg/s^2, {} light channels",
        h.min_angle as f64 / 1000.0,
        h.max_angle as f64 / 1000.0,
        h.max_speed as f64 / 1000.0,
        h.max_accel as f64 / 1000.0,
        h.channels
    );
    let t = &profile.turntable;
    outln!(
        "profile limits:  angle [{}, {}] deg, speed {} deg/s, accel {} deg/s^2, {} steps/rev ({})",
        t.min_angle_deg,
        t.max_angle_deg,
        t.max_speed_deg_s,
        t.max_accel_deg_s2,
        t.steps_per_rev,
        profile.origin
    );
    outln!("watchdog:   {} ms", h.watchdog_ms);
    use brdf_rig::devices::{Light, Turntable};
    let s = r
        .turntable
        .status()
        .context("reading the turntable status")?;
    outln!(
        "turntable:  angle {:.3} deg, {}, {}",
        s.angle_deg,
        if s.homed { "homed" } else { "not homed" },
        if s.moving { "moving" } else { "at rest" }
    );
    let lights = r.light.status().context("reading the light status")?;
    for (i, (l, ch)) in lights.iter().zip(&profile.light.channels).enumerate() {
        outln!(
            "light {i}:    {:<8} level {:.3}{} (azimuth {} deg, elevation {} deg, max level {})",
            ch.name,
            l.level,
            if l.stable { " stable" } else { "" },
            ch.azimuth_deg,
            ch.elevation_deg,
            ch.max_level
        );
    }
    Ok(ExitCode::SUCCESS)
}
