//! The rig profile's `[camera]` section, which capture owns (the rig driver ignores it): which
//! camera backend to use and where the camera stands. Optional: without it the profile means the
//! simulated camera at the default placement. (The simulated camera's `[scene]` belongs to
//! `sim::scene`; capture imports nothing from `sim`.)
//!
//! ```toml
//! [camera]
//! backend = "sim"          # sim | gphoto2 | webcam | v4l2
//! distance_m = 0.6         # camera to turntable centre
//! elevation_deg = 0.0      # above the plane through the object's centre
//! vertical_fov_deg = 30.0
//! # gphoto2 only
//! gphoto2_program = "gphoto2"
//! gphoto2_port = "usb:001,004"
//! shutter_key = "shutterspeed"
//! iso_key = "iso"
//! extra_config = ["imageformat=RAW"]
//! # webcam only: the nokhwa index; v4l2 only: the device node
//! webcam_index = 0
//! v4l2_device = "/dev/video0"
//! ```

use serde::Deserialize;

use super::plan::LabGeometry;
use crate::profile::ProfileError;

/// Why `[camera]` cannot be used. Each names the profile (`origin`) and the key.
#[derive(Debug, thiserror::Error)]
pub enum CameraConfigError {
    /// Not TOML, or a key `[camera]` does not have, or a value of the wrong type.
    #[error(transparent)]
    Section(#[from] ProfileError),
    #[error("{origin}: camera.backend = {backend:?}: must be one of sim, gphoto2, webcam, v4l2")]
    Backend { origin: String, backend: String },
    /// A number outside its range; `rule` is the range as the message gives it.
    #[error("{origin}: camera.{key} must be {rule}")]
    Range {
        origin: String,
        key: &'static str,
        rule: &'static str,
    },
    #[error("{origin}: camera.extra_config[{index}] = {entry:?}: must be key=value")]
    ExtraConfig {
        origin: String,
        index: usize,
        entry: String,
    },
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraSection {
    pub backend: String,
    pub distance_m: f64,
    pub elevation_deg: f64,
    pub vertical_fov_deg: f64,
    pub gphoto2_program: String,
    pub gphoto2_port: Option<String>,
    pub shutter_key: String,
    pub iso_key: String,
    pub extra_config: Vec<String>,
    pub webcam_index: u32,
    pub v4l2_device: String,
}

impl Default for CameraSection {
    fn default() -> Self {
        Self {
            backend: "sim".into(),
            distance_m: 0.6,
            // The simulated profile's light channels are in the camera's horizontal plane, so
            // theta_d = azimuth / 2 exactly (see rig-profiles/simulated.toml).
            elevation_deg: 0.0,
            vertical_fov_deg: 30.0,
            gphoto2_program: "gphoto2".into(),
            gphoto2_port: None,
            shutter_key: "shutterspeed".into(),
            iso_key: "iso".into(),
            extra_config: Vec::new(),
            webcam_index: 0,
            v4l2_device: "/dev/video0".into(),
        }
    }
}

/// Reads `[camera]` from the whole profile text; `origin` names it in errors.
pub fn parse_camera_section(text: &str, origin: &str) -> Result<CameraSection, CameraConfigError> {
    let c: CameraSection = crate::profile::parse_section(text, origin, "camera")?;
    if !["sim", "gphoto2", "webcam", "v4l2"].contains(&c.backend.as_str()) {
        return Err(CameraConfigError::Backend {
            origin: origin.to_owned(),
            backend: c.backend,
        });
    }
    let range = |key, rule| {
        Err(CameraConfigError::Range {
            origin: origin.to_owned(),
            key,
            rule,
        })
    };
    if !(c.distance_m > 0.0 && c.distance_m.is_finite()) {
        return range("distance_m", "positive");
    }
    if !(c.vertical_fov_deg > 1.0 && c.vertical_fov_deg < 170.0) {
        return range("vertical_fov_deg", "in (1, 170)");
    }
    if !(-89.0..=89.0).contains(&c.elevation_deg) {
        return range("elevation_deg", "in [-89, 89]");
    }
    if let Some((index, entry)) = c
        .extra_config
        .iter()
        .enumerate()
        .find(|(_, kv)| !kv.contains('='))
    {
        return Err(CameraConfigError::ExtraConfig {
            origin: origin.to_owned(),
            index,
            entry: entry.clone(),
        });
    }
    Ok(c)
}

impl CameraSection {
    /// The lab geometry: this camera placement and the profile's light channel directions
    /// `(azimuth_deg, elevation_deg)`.
    pub fn lab(&self, lights: Vec<(f64, f64)>) -> LabGeometry {
        LabGeometry {
            camera_distance_m: self.distance_m,
            camera_elevation_deg: self.elevation_deg,
            vertical_fov_deg: self.vertical_fov_deg,
            lights,
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn the_section_is_optional_and_other_sections_are_ignored() {
        let c = parse_camera_section("[serial]\nport = \"sim\"\nweird = 1\n", "p.toml").unwrap();
        assert_eq!(c, CameraSection::default());
        let c = parse_camera_section(
            "[camera]\nbackend = \"gphoto2\"\nextra_config = [\"imageformat=RAW\"]\n[scene]\nmaterial = \"gold-paint\"\n",
            "p.toml",
        )
        .unwrap();
        assert_eq!(c.backend, "gphoto2");
    }

    #[test]
    fn mistakes_are_named() {
        let err = parse_camera_section("[camera]\nbackend = \"polaroid\"\n", "p.toml")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("p.toml") && err.contains("camera.backend"),
            "{err}"
        );
        let err = parse_camera_section("[camera]\nexposure = 3\n", "p.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("exposure"), "{err}");
    }

    #[test]
    fn a_bad_value_names_its_key_and_entry() {
        let err = parse_camera_section("[camera]\ndistance_m = -1.0\n", "p.toml").unwrap_err();
        assert_eq!(
            err.to_string(),
            "p.toml: camera.distance_m must be positive"
        );
        let err = parse_camera_section("[camera]\nextra_config = [\"a=b\", \"iso\"]\n", "p.toml")
            .unwrap_err();
        assert!(matches!(
            err,
            CameraConfigError::ExtraConfig { index: 1, .. }
        ));
        assert_eq!(
            err.to_string(),
            "p.toml: camera.extra_config[1] = \"iso\": must be key=value"
        );
    }
}
