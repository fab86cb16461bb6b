//! `brdf-rig calibrate SESSION`: calibrate a capture session folder (light direction and
//! irradiance per channel, HDR single-light images) and write its reconstruction job.

use anyhow::{Context, Result, bail};
use brdf_rig::pipeline::session_calib::{SessionCalibOptions, calibrate_session};
use brdf_rig::pipeline::sim_session;
use clap::Args;
use std::path::PathBuf;

use super::ranges::{Closed, Open, real_in};

#[derive(Args, Debug)]
pub struct SessionArgs {
    /// Capture session folder (from `brdf-rig capture`).
    #[arg(value_name = "SESSION")]
    pub session: Option<PathBuf>,
    /// COLMAP model folder from photogrammetry (default: a simulated session's `sim/colmap`).
    #[arg(long, value_name = "DIR")]
    pub cameras: Option<PathBuf>,
    /// Mesh from photogrammetry, PLY or OBJ (default: a simulated session's `sim/mesh_sfm.ply`).
    #[arg(long, value_name = "FILE")]
    pub mesh: Option<PathBuf>,
    /// Albedo of the white reference, in (0, 1.5] (default: a simulated session's scene albedo).
    #[arg(long, value_name = "A", value_parser = real_in(Open(0.0), Closed(1.5)))]
    pub albedo: Option<f64>,
    /// Print the calibration as JSON.
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: SessionArgs) -> Result<()> {
    let Some(dir) = a.session else {
        bail!(
            "give a session folder (`brdf-rig calibrate SESSION`) or a subcommand (sphere, white)"
        );
    };
    let given = SessionCalibOptions {
        cameras: a.cameras,
        mesh: a.mesh,
        white_albedo: a.albedo,
        truth: None,
    };
    let opts = sim_session::calib_options(&dir, given)?;
    let cal = calibrate_session(&dir, &opts, |m| errln!("calibrate: {m}"))
        .with_context(|| format!("calibrating session {}", dir.display()))?;
    if a.json {
        outln!("{}", serde_json::to_string_pretty(&cal)?);
        return Ok(());
    }
    for c in &cal.channels {
        let d = c.light.dir_camera;
        outln!(
            "channel {}: light direction (camera axes) ({:.5}, {:.5}, {:.5}) +- {:.3} deg; irradiance ({:.5}, {:.5}, {:.5}) +- ({:.2e}, {:.2e}, {:.2e})",
            c.channel,
            d[0],
            d[1],
            d[2],
            c.light.uncertainty_deg,
            c.irradiance[0],
            c.irradiance[1],
            c.irradiance[2],
            c.irradiance_std_error[0],
            c.irradiance_std_error[1],
            c.irradiance_std_error[2]
        );
        if let (Some(de), Some(ie)) = (c.truth_dir_error_deg, c.truth_irradiance_error) {
            outln!(
                "  against the simulated truth: direction error {de:.3} deg, irradiance error {:.2} %",
                ie * 100.0
            );
        }
        for w in &c.warnings {
            outln!("  warning: {w}");
        }
    }
    outln!(
        "wrote {} HDR single-light images, {} and {}",
        cal.light_images,
        dir.join(brdf_rig::pipeline::calibration_file::CALIBRATION_FILE)
            .display(),
        dir.join(&cal.job).display()
    );
    Ok(())
}
