//! The virtual scene the simulated camera photographs: an object (a mesh from `data/meshes` with
//! a BRDF from `data/merl-nbrdf`, the neural fits that stand in for MERL measurements) on the
//! turntable, the rig's light channels as far directional lights, room light as uniform ambient
//! light, and the two calibration targets (black glossy sphere, white reference).
//!
//! Frames: the lab frame is the rig profile's (turntable centre at the origin, z up, camera at
//! azimuth 0 towards +x). The object frame is the lab frame at turntable angle 0; at angle `a`
//! (degrees, counter-clockwise seen from above) `p_lab = Rz(a) p_object`. Photogrammetry
//! recovers poses in the object frame, so the camera pose written for view `a` is
//! `camera_from_object = camera_from_lab * Rz(a)` and a light's direction in the object frame is
//! `Rz(-a) l_lab`. The mesh is centred on its bounding box, turned z-up and scaled to
//! `object_size_m` (bounding-box diagonal).
//!
//! What only a person does on a real rig (room light, placing the sphere or the white reference)
//! is the shared [`StageState`], which the capture's operator sets.

use nalgebra::{Point3, Rotation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use crate::capture::plan::{LabGeometry, Stage, Target};
use crate::geometry::camera::{Intrinsics, Pose};
use crate::profile::ProfileError;

/// A value of `[scene]` out of its range; the message names the key as the profile spells it.
#[derive(Debug, thiserror::Error)]
pub enum SceneValueError {
    #[error("scene.{key} = {value}: must be positive")]
    NotPositive { key: &'static str, value: f64 },
    #[error("scene.ambient_radiance and scene.read_noise_electrons must be >= 0")]
    Negative,
    #[error("scene.pixel_samples = {0}: must be 1 to 16")]
    PixelSamples(usize),
    #[error("scene.psf_sigma_px = {0}: must be 0 to 5 pixels")]
    PsfSigma(f64),
    #[error("scene.sphere_coat_f0 = {0}: must be in [0, 1)")]
    CoatF0(f64),
    #[error("scene.mesh_up = {0:?}: must be \"y\" or \"z\"")]
    MeshUp(String),
}

/// Why the `[scene]` section of a profile cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum SceneConfigError {
    /// Not TOML, or a key `[scene]` does not have, or a value of the wrong type.
    #[error(transparent)]
    Section(#[from] ProfileError),
    /// The value error itself, located in the profile (the same error, not a cause of it).
    #[error("{origin}: {value}")]
    Value {
        origin: String,
        value: SceneValueError,
    },
}

/// The `[scene]` section of a rig profile (all optional).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SceneConfig {
    /// Mesh file (PLY/OBJ); relative paths are relative to the crate's `data/meshes`.
    pub mesh: String,
    /// The mesh's up axis: "y" (OBJ/PLY scans, the default) or "z".
    pub mesh_up: String,
    /// Material name in `data/merl-nbrdf` (a neural fit, not measured MERL data).
    pub material: String,
    /// Bounding-box diagonal of the object on the turntable, metres.
    pub object_size_m: f64,
    /// Irradiance of each light channel at level 1, W/m^2 (RGB, white light).
    pub light_irradiance: f64,
    /// Radiance of the uniform room light, W sr^-1 m^-2.
    pub ambient_radiance: f64,
    /// Radius of the black calibration sphere, metres.
    pub sphere_radius_m: f64,
    /// Normal-incidence Fresnel reflectance of the black sphere's glossy coat (0.04: plastic or
    /// glass); near its rim the sphere mirrors the lit backdrop behind it, as a real one does.
    pub sphere_coat_f0: f64,
    /// Albedo of the white reference (Lambertian).
    pub white_albedo: f64,
    /// Rays per pixel side over which the sensor integrates each pixel of the calibration
    /// targets (the sphere, the white reference); 1 = one ray through the pixel centre.
    pub pixel_samples: usize,
    /// Standard deviation of the lens's Gaussian point-spread function, pixels, for the
    /// calibration targets (0 = a perfectly sharp lens).
    pub psf_sigma_px: f64,
    /// Sensor value per unit radiance per second of exposure at gain 1.
    pub sensitivity: f64,
    /// Electrons at saturation (sets the shot noise).
    pub full_well_electrons: f64,
    /// Read noise, electrons RMS.
    pub read_noise_electrons: f64,
    /// Seed of the sensor noise; each shot's noise depends on it and on the shot's state.
    pub seed: u64,
}

impl Default for SceneConfig {
    fn default() -> Self {
        Self {
            mesh: "spot_triangulated.obj".into(),
            mesh_up: "y".into(),
            material: "blue-acrylic".into(),
            object_size_m: 0.38,
            light_irradiance: 10.0,
            ambient_radiance: 1.0,
            sphere_radius_m: 0.05,
            sphere_coat_f0: 0.04,
            white_albedo: 0.99,
            pixel_samples: 4,
            psf_sigma_px: 0.5,
            sensitivity: 120.0,
            full_well_electrons: 20_000.0,
            read_noise_electrons: 4.0,
            seed: 7,
        }
    }
}

impl SceneConfig {
    /// Reads and checks the `[scene]` section of the whole profile text (the default scene when
    /// it has none); `origin` names it in errors.
    pub fn from_profile_text(text: &str, origin: &str) -> Result<Self, SceneConfigError> {
        let scene: SceneConfig = crate::profile::parse_section(text, origin, "scene")?;
        scene.validate().map_err(|value| SceneConfigError::Value {
            origin: origin.to_owned(),
            value,
        })?;
        Ok(scene)
    }

    /// The mesh path, resolved against `data/meshes` when relative.
    pub fn mesh_path(&self) -> PathBuf {
        let p = PathBuf::from(&self.mesh);
        if p.is_absolute() {
            p
        } else {
            data_dir().join("meshes").join(p)
        }
    }

    pub fn material_path(&self) -> PathBuf {
        data_dir()
            .join("merl-nbrdf")
            .join(format!("{}.f32", self.material))
    }

    pub fn validate(&self) -> Result<(), SceneValueError> {
        let positive = [
            ("object_size_m", self.object_size_m),
            ("light_irradiance", self.light_irradiance),
            ("sphere_radius_m", self.sphere_radius_m),
            ("white_albedo", self.white_albedo),
            ("sensitivity", self.sensitivity),
            ("full_well_electrons", self.full_well_electrons),
        ];
        for (key, value) in positive {
            if !(value.is_finite() && value > 0.0) {
                return Err(SceneValueError::NotPositive { key, value });
            }
        }
        if !(self.ambient_radiance >= 0.0 && self.read_noise_electrons >= 0.0) {
            return Err(SceneValueError::Negative);
        }
        if !(1..=16).contains(&self.pixel_samples) {
            return Err(SceneValueError::PixelSamples(self.pixel_samples));
        }
        if !(0.0..=5.0).contains(&self.psf_sigma_px) {
            return Err(SceneValueError::PsfSigma(self.psf_sigma_px));
        }
        if !(0.0..1.0).contains(&self.sphere_coat_f0) {
            return Err(SceneValueError::CoatF0(self.sphere_coat_f0));
        }
        if self.mesh_up != "y" && self.mesh_up != "z" {
            return Err(SceneValueError::MeshUp(self.mesh_up.clone()));
        }
        Ok(())
    }
}

pub use crate::data::data_dir;

/// What stands on the turntable and whether the room light is on, shared between the capture's
/// operator (who sets it) and the simulated camera (which renders it).
#[derive(Clone, Debug)]
pub struct StageState(Arc<Mutex<Stage>>);

impl Default for StageState {
    fn default() -> Self {
        Self(Arc::new(Mutex::new(Stage {
            target: Target::Object,
            room_light: true,
        })))
    }
}

impl StageState {
    pub fn get(&self) -> Stage {
        *self.0.lock().unwrap_or_else(|p| p.into_inner())
    }

    pub fn set(&self, stage: Stage) {
        *self.0.lock().unwrap_or_else(|p| p.into_inner()) = stage;
    }
}

/// Rotation of the turntable by `angle_deg` about z (object frame to lab frame).
pub fn lab_from_object(angle_deg: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), angle_deg.to_radians())
}

/// The fixed camera: pinhole intrinsics and its pose in the lab frame.
#[derive(Clone, Debug, PartialEq)]
pub struct SimCameraRig {
    pub intrinsics: Intrinsics,
    pub camera_from_lab: Pose,
}

impl SimCameraRig {
    /// A camera of `width x height` at the lab geometry's distance and elevation, looking at the
    /// turntable centre, with square pixels and the principal point at the image centre.
    pub fn new(lab: &LabGeometry, width: usize, height: usize) -> Self {
        let fy = 0.5 * height as f64 / (0.5 * lab.vertical_fov_deg.to_radians()).tan();
        let intrinsics = Intrinsics::pinhole(
            width,
            height,
            fy,
            fy,
            0.5 * width as f64,
            0.5 * height as f64,
        );
        let eye = Point3::from(lab.camera_dir_lab() * lab.camera_distance_m);
        let camera_from_lab = Pose::look_at(eye, Point3::origin(), Vector3::z());
        Self {
            intrinsics,
            camera_from_lab,
        }
    }

    /// The camera pose in the object frame at turntable angle `angle_deg` (what SfM recovers).
    pub fn camera_from_object(&self, angle_deg: f64) -> Pose {
        let r = lab_from_object(angle_deg);
        Pose {
            rotation: self.camera_from_lab.rotation * r,
            translation: self.camera_from_lab.translation,
        }
    }
}

/// A light direction (lab frame) carried into the object frame at turntable angle `angle_deg`.
pub fn light_dir_object(l_lab: &Vector3<f64>, angle_deg: f64) -> Vector3<f64> {
    lab_from_object(angle_deg).inverse() * l_lab
}

/// Re-orients a y-up mesh to z-up (x stays, y becomes z, z becomes -y): a proper rotation.
pub fn y_up_to_z_up() -> Rotation3<f64> {
    Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn the_scene_section_is_optional_and_its_mistakes_are_named() {
        let s = SceneConfig::from_profile_text("[camera]\nbackend = \"sim\"\n", "p.toml").unwrap();
        assert_eq!(s, SceneConfig::default());
        let s = SceneConfig::from_profile_text("[scene]\nmaterial = \"gold-paint\"\n", "p.toml")
            .unwrap();
        assert_eq!(s.material, "gold-paint");
        let err =
            SceneConfig::from_profile_text("[scene]\nobject_size_m = -1\n", "p.toml").unwrap_err();
        assert!(matches!(
            &err,
            SceneConfigError::Value {
                value: SceneValueError::NotPositive {
                    key: "object_size_m",
                    ..
                },
                ..
            }
        ));
        assert_eq!(
            err.to_string(),
            "p.toml: scene.object_size_m = -1: must be positive"
        );
        let err = SceneConfig::from_profile_text("[scene]\nmesh_up = \"x\"\n", "p.toml")
            .unwrap_err()
            .to_string();
        assert_eq!(err, "p.toml: scene.mesh_up = \"x\": must be \"y\" or \"z\"");
    }

    fn lab() -> LabGeometry {
        LabGeometry {
            camera_distance_m: 0.6,
            camera_elevation_deg: 10.0,
            vertical_fov_deg: 30.0,
            lights: vec![(60.0, 0.0)],
        }
    }

    #[test]
    fn the_object_centre_projects_to_the_image_centre_at_every_angle() {
        let rig = SimCameraRig::new(&lab(), 64, 48);
        for a in [0.0, 37.0, 180.0, 359.0] {
            let pose = rig.camera_from_object(a);
            let p = pose.camera_from_world(&Point3::origin());
            let (x, y) = rig.intrinsics.project(&p).unwrap();
            assert!((x - 32.0).abs() < 1e-9 && (y - 24.0).abs() < 1e-9);
        }
    }

    #[test]
    fn turning_the_table_moves_the_camera_the_other_way_in_the_object_frame() {
        let rig = SimCameraRig::new(&lab(), 64, 48);
        // at 90 degrees the object's -y axis faces the camera (which sits on lab +x)
        let c = rig.camera_from_object(90.0).centre();
        let dir = c.coords.normalize();
        assert!(dir.y < -0.95, "{dir:?}");
        // the light turns with the camera: the angle between them is constant
        let l_lab = lab().light_dir_lab(0).unwrap();
        for a in [0.0, 45.0, 200.0] {
            let l = light_dir_object(&l_lab, a);
            let v = rig.camera_from_object(a).centre().coords.normalize();
            let v0 = rig.camera_from_lab.centre().coords.normalize();
            assert!((l.dot(&v) - l_lab.dot(&v0)).abs() < 1e-12);
        }
    }

    #[test]
    fn y_up_becomes_z_up() {
        let r = y_up_to_z_up();
        let up = r * Vector3::y();
        assert!((up - Vector3::z()).norm() < 1e-12);
        assert!((r.matrix().determinant() - 1.0).abs() < 1e-12);
    }
}
