//! Opening the rig a profile describes: the board on its serial port, or, for `port = "sim"`,
//! the simulated firmware on a pseudo-terminal behind the same serial driver. The one place
//! that chooses between real and simulated rig hardware: `devices` knows nothing of the
//! simulation and `sim` nothing of profiles, so both are reached through here (the camera is
//! chosen beside the rest of a capture's start, `pipeline::capture_start`).
//!
//! Either way the turntable and light are `devices::rig`'s serial drivers: the simulated rig
//! exercises the real driver, link and codec on a pty, as a board would.

use std::path::Path;
use std::time::Duration;

use crate::devices::DeviceError;
use crate::devices::rig::{self, Rig, RigSettings};
use crate::profile::Profile;
use crate::sim::{FaultControl, FirmwareConfig, LinkFaults, SimConfig, SimHandle, SimRig};

/// An open rig and, when it is the simulated one, the handles to its firmware.
pub struct OpenRig {
    pub rig: Rig,
    /// The simulated rig's state (platter angle, lit channels), which the simulated camera
    /// looks at; `None` for a board.
    pub sim: Option<SimHandle>,
    /// Fault injection into the simulated rig's link; `None` for a board.
    pub faults: Option<FaultControl>,
}

/// The simulated firmware a profile describes (its hard limits are the profile's; its link
/// faults, warm-up and boot delay are the profile's `[sim]`).
pub fn sim_config(p: &Profile) -> SimConfig {
    let t = &p.turntable;
    SimConfig {
        firmware: FirmwareConfig {
            name: "brdf-sim".into(),
            channels: p.light.channels.len() as u8,
            min_angle: (t.min_angle_deg * 1000.0).round() as i32,
            max_angle: (t.max_angle_deg * 1000.0).round() as i32,
            max_speed: (t.max_speed_deg_s * 1000.0).round() as u32,
            max_accel: (t.max_accel_deg_s2 * 1000.0).round() as u32,
            watchdog_ms: 2000,
            warmup_ms: p.sim.warmup_ms,
            boot_counter: 0,
            power_on_angle: 12_345,
        },
        faults: LinkFaults {
            drop_rate: p.sim.drop_rate,
            corrupt_rate: p.sim.corrupt_rate,
            ..LinkFaults::default()
        },
        seed: p.sim.seed,
        boot_delay: Duration::from_millis(p.sim.boot_delay_ms.into()),
        link_path: None,
    }
}

/// Opens the rig a profile describes. With `port = "sim"` (and no `port_override`) this
/// spawns the simulated firmware on a pty first; the rest is the same code as for a board.
pub fn open(profile: &Profile, port_override: Option<&Path>) -> Result<OpenRig, DeviceError> {
    if port_override.is_none() && profile.is_simulated() {
        return open_simulated(profile, |_| {});
    }
    let port = port_override
        .map(Path::to_path_buf)
        .unwrap_or_else(|| profile.serial.port.clone().into());
    Ok(OpenRig {
        rig: rig::open(profile, &port)?,
        sim: None,
        faults: None,
    })
}

/// Spawns the simulated firmware a profile describes and opens it, with the driver's settings
/// from the profile changed by `adjust` (a test's watchdog, a silent host without heartbeat).
pub fn open_simulated(
    profile: &Profile,
    adjust: impl FnOnce(&mut RigSettings),
) -> Result<OpenRig, DeviceError> {
    let sim = SimRig::spawn(sim_config(profile)).map_err(|e| DeviceError::Other {
        device: "simulated rig".into(),
        reason: format!("cannot create a pseudo-terminal: {e}"),
    })?;
    let mut settings = RigSettings::from_profile(profile, &sim.port_path);
    adjust(&mut settings);
    let (state, faults) = (sim.state.clone(), sim.faults.clone());
    Ok(OpenRig {
        rig: rig::open_with(settings, Some(Box::new(sim)))?,
        sim: Some(state),
        faults: Some(faults),
    })
}
