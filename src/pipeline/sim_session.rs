//! What a simulated session gives the calibrate step that a real one takes from the user: the
//! photogrammetry stand-ins under `sim/` (the COLMAP model and the SfM-like mesh), the white
//! board's albedo, and the true lights to score the calibration against. The one place the
//! calibrate path looks into `sim/` (through `sim::truth`, which owns those files); a session
//! without `sim/truth.json` (a real capture) gets nothing from here.

use nalgebra::Vector3;
use std::path::Path;

use super::session_calib::{LightTruth, SessionCalibOptions};
use crate::format::FormatError;
use crate::sim::truth::{COLMAP_DIR, MESH_SFM_FILE, read_truth};

/// `given`, with what it leaves out filled from the session's simulation when it has one.
pub fn calib_options(
    session: &Path,
    given: SessionCalibOptions,
) -> Result<SessionCalibOptions, FormatError> {
    let truth = match read_truth(session) {
        Ok(t) => t,
        Err(e) if e.is_not_found() => return Ok(given),
        Err(e) => return Err(e),
    };
    let channels = truth
        .channels
        .iter()
        .map(|c| {
            let [x, y, z] = c.light_dir_camera;
            // the sensor's unit: radiance times the simulated sensitivity
            let irradiance = c.irradiance_w_m2 * truth.sensitivity;
            (c.channel, (Vector3::new(x, y, z), irradiance))
        })
        .collect();
    Ok(SessionCalibOptions {
        cameras: given.cameras.or_else(|| Some(session.join(COLMAP_DIR))),
        mesh: given.mesh.or_else(|| Some(session.join(MESH_SFM_FILE))),
        white_albedo: given.white_albedo.or(Some(truth.scene.white_albedo)),
        truth: given.truth.or(Some(LightTruth { channels })),
    })
}
