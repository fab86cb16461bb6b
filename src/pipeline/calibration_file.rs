//! `calibration.json`, the owner of its format: what `brdf-rig calibrate SESSION` measured per
//! light channel, written into the session folder beside the job it wrote. The calibrate step
//! writes it ([`write`]) and the report reads it ([`read`]), both through these types, so a
//! change of the format is a compile error in every reader. Version [`CALIBRATION_FORMAT_VERSION`];
//! a file without `format_version` (written before versions were recorded) is version 1.
//!
//! Paths inside the file are relative to the file's folder (the session folder).

use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

use crate::calib::clip::ClipLevel;
use crate::calib::light::LightSummary;
use crate::format::{FormatError, Versioned, version_1};

/// The file's name in the session folder.
pub const CALIBRATION_FILE: &str = "calibration.json";
/// The version written, and the only one read.
pub const CALIBRATION_FORMAT_VERSION: u32 = 1;

const FORMAT: Versioned = Versioned {
    what: "calibration file",
    version: CALIBRATION_FORMAT_VERSION,
    remedy: "re-run `brdf-rig calibrate` on the session",
};

/// One channel's calibration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ChannelCalibration {
    pub channel: usize,
    pub light: LightSummary,
    /// Irradiance per colour channel, in the session's radiance unit.
    pub irradiance: [f64; 3],
    pub irradiance_std_error: [f64; 3],
    /// Spread of the board's radiance over a 3x3 grid of cells (flat-field check).
    pub flat_field_spread: f64,
    /// Where the merged sphere and white images clip, and why (their brackets' shortest
    /// exposures).
    pub sphere_clip: ClipLevel,
    pub white_clip: ClipLevel,
    pub warnings: Vec<String>,
    /// Simulated sessions only: the angle between the measured and the true light direction,
    /// and the relative irradiance error (mean over colour channels).
    pub truth_dir_error_deg: Option<f64>,
    pub truth_irradiance_error: Option<f64>,
}

/// The session's calibration: the whole file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SessionCalibration {
    #[serde(default = "version_1")]
    pub format_version: u32,
    pub channels: Vec<ChannelCalibration>,
    pub light_images: usize,
    /// The job written, relative to the folder of this file (the session folder).
    pub job: PathBuf,
}

/// Reads `SESSION/calibration.json`.
pub fn read(session_dir: &Path) -> Result<SessionCalibration, FormatError> {
    FORMAT.read(&session_dir.join(CALIBRATION_FILE))
}

/// Writes `SESSION/calibration.json` atomically.
pub fn write(session_dir: &Path, cal: &SessionCalibration) -> Result<(), FormatError> {
    FORMAT.write(&session_dir.join(CALIBRATION_FILE), cal)
}
