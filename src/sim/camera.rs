//! The simulated camera: renders the virtual scene (`scene`) as the rig stands now, seen through
//! a pinhole camera, and turns radiance into a sensor image (exposure, gain, seeded shot and read
//! noise, saturation). It reads the platter angle and the lit channels from the simulated
//! firmware's shared state ([`RigView`]), so a capture that forgot to move the turntable or to
//! switch a light on gets the wrong picture, as it would on a real rig.
//!
//! Sensor model (values in [0, 1], 1 = saturation): `e = L t s W` electrons for radiance `L`,
//! exposure `t`, sensitivity `s` (value per radiance-second) and full well `W`;
//! `e' = e + sqrt(e) N(0,1) + r N(0,1)` (shot noise as a Gaussian, read noise `r`);
//! value = `clamp(g e' / W, 0, 1)` at gain `g`. So radiance = value / (t g s) below saturation.
//! The noise of a shot is seeded by the scene seed and the shot's state (angle, lights, stage,
//! exposure, gain): the same shot taken again (a resumed capture) gives the same image.

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_distr_free::standard_normal;
use std::sync::Arc;

use super::scene::{SceneConfig, SimCameraRig, StageState, light_dir_object};
use crate::capture::plan::{LabGeometry, Stage};
use crate::devices::{Camera, DeviceError, ShotMetadata, ShotSettings};
use crate::geometry::camera::{Intrinsics, Pose};
use crate::render::image::LinearImage;

/// What the camera can see of the simulated rig (the firmware's shared state).
pub trait RigView: Send {
    /// Physical platter angle, degrees.
    fn angle_deg(&self) -> f64;
    /// Level of each light channel in [0, 1].
    fn levels(&self) -> Vec<f64>;
}

/// One lit channel, in the object frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LitLight {
    /// Unit vector towards the light.
    pub dir_object: Vector3<f64>,
    /// W/m^2 (white).
    pub irradiance: f64,
}

/// Everything a renderer needs for one radiance image.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderRequest {
    pub intrinsics: Intrinsics,
    pub camera_from_object: Pose,
    pub stage: Stage,
    /// Uniform room-light radiance (0 when the room light is off).
    pub ambient_radiance: f64,
    pub lights: Vec<LitLight>,
    /// Front normal of the white reference in the object frame: it stands on the turntable
    /// facing the camera at angle 0 and turns with the table.
    pub board_normal_object: Vector3<f64>,
}

/// Renders radiance (W sr^-1 m^-2, RGB) for a request.
pub trait SceneRenderer: Send + Sync {
    fn render(&self, req: &RenderRequest) -> LinearImage;
    /// A short description for the shot metadata.
    fn describe(&self) -> String;
}

/// Sensor constants (see the module header).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sensor {
    pub sensitivity: f64,
    pub full_well: f64,
    pub read_noise: f64,
    pub seed: u64,
}

impl Sensor {
    pub fn from_config(cfg: &SceneConfig) -> Self {
        Self {
            sensitivity: cfg.sensitivity,
            full_well: cfg.full_well_electrons,
            read_noise: cfg.read_noise_electrons,
            seed: cfg.seed,
        }
    }

    /// Exposes a radiance image. `shot_key` seeds the noise.
    pub fn expose(
        &self,
        radiance: &LinearImage,
        settings: ShotSettings,
        shot_key: u64,
    ) -> LinearImage {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(self.seed ^ shot_key.rotate_left(17));
        let scale = settings.exposure_secs * self.sensitivity * self.full_well;
        let out: Vec<f32> = radiance
            .data()
            .iter()
            .map(|&l| {
                let e = (f64::from(l) * scale).max(0.0);
                let noisy = e
                    + e.sqrt() * standard_normal(&mut rng)
                    + self.read_noise * standard_normal(&mut rng);
                (settings.gain * noisy / self.full_well).clamp(0.0, 1.0) as f32
            })
            .collect();
        // Same size as the input by construction.
        LinearImage::from_rgb(radiance.width(), radiance.height(), out)
            .unwrap_or_else(|| LinearImage::new(radiance.width(), radiance.height()))
    }
}

/// FNV-1a over the bytes of the shot state: a stable seed across runs and platforms.
fn shot_key(parts: &[u64]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for p in parts {
        for b in p.to_le_bytes() {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    h
}

/// The simulated camera.
pub struct SimCamera {
    rig: Box<dyn RigView>,
    stage: StageState,
    camera: SimCameraRig,
    lab: LabGeometry,
    scene: SceneConfig,
    sensor: Sensor,
    renderer: Arc<dyn SceneRenderer>,
    /// The last radiance image and the state it was rendered for (an exposure bracket renders
    /// once).
    cache: Option<(RenderRequest, LinearImage)>,
    renders: usize,
}

impl SimCamera {
    pub fn new(
        rig: Box<dyn RigView>,
        stage: StageState,
        lab: LabGeometry,
        scene: SceneConfig,
        width: usize,
        height: usize,
        renderer: Arc<dyn SceneRenderer>,
    ) -> Self {
        Self {
            rig,
            stage,
            camera: SimCameraRig::new(&lab, width, height),
            sensor: Sensor::from_config(&scene),
            lab,
            scene,
            renderer,
            cache: None,
            renders: 0,
        }
    }

    pub fn camera_rig(&self) -> &SimCameraRig {
        &self.camera
    }

    /// How many radiance images were rendered (the rest came from the cache).
    pub fn renders(&self) -> usize {
        self.renders
    }

    /// The render request for the rig's current state.
    pub fn request_now(&self) -> RenderRequest {
        let angle = self.rig.angle_deg();
        let stage = self.stage.get();
        let lights = self
            .rig
            .levels()
            .iter()
            .enumerate()
            .filter(|(_, l)| **l > 0.0)
            .filter_map(|(ch, &level)| {
                self.lab.light_dir_lab(ch).map(|l_lab| LitLight {
                    dir_object: light_dir_object(&l_lab, angle),
                    irradiance: level * self.scene.light_irradiance,
                })
            })
            .collect();
        RenderRequest {
            intrinsics: self.camera.intrinsics,
            camera_from_object: self.camera.camera_from_object(angle),
            stage,
            ambient_radiance: if stage.room_light {
                self.scene.ambient_radiance
            } else {
                0.0
            },
            lights,
            board_normal_object: self.lab.camera_dir_lab(),
        }
    }
}

impl Camera for SimCamera {
    fn capture(
        &mut self,
        settings: ShotSettings,
    ) -> Result<(LinearImage, ShotMetadata), DeviceError> {
        if !(settings.exposure_secs.is_finite()
            && settings.exposure_secs > 0.0
            && settings.gain > 0.0)
        {
            return Err(DeviceError::Limit {
                device: "simulated camera".into(),
                what: "exposure/gain".into(),
                reason: format!(
                    "exposure {} s and gain {} must be positive",
                    settings.exposure_secs, settings.gain
                ),
            });
        }
        let req = self.request_now();
        let radiance = match &self.cache {
            Some((r, img)) if *r == req => img.clone(),
            _ => {
                let img = self.renderer.render(&req);
                self.renders += 1;
                self.cache = Some((req.clone(), img.clone()));
                img
            }
        };
        let angle_mdeg = (self.rig.angle_deg() * 1000.0).round() as i64 as u64;
        let mut parts = vec![
            angle_mdeg,
            settings.exposure_secs.to_bits(),
            settings.gain.to_bits(),
            req.stage.room_light as u64,
            req.stage.target as u64,
        ];
        parts.extend(self.rig.levels().iter().map(|l| l.to_bits()));
        let image = self.sensor.expose(&radiance, settings, shot_key(&parts));
        Ok((
            image,
            ShotMetadata {
                exposure_secs: settings.exposure_secs,
                gain: settings.gain,
                saturation: 1.0,
                device: format!("simulated camera ({})", self.renderer.describe()),
            },
        ))
    }
}

/// Standard normal deviates without another dependency (Box-Muller on `rand`'s uniform).
mod rand_distr_free {
    use rand::Rng;

    pub fn standard_normal<R: Rng>(rng: &mut R) -> f64 {
        let u1: f64 = rng.r#gen::<f64>().max(1e-300);
        let u2: f64 = rng.r#gen::<f64>();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;
    use crate::capture::plan::Target;
    use std::sync::Mutex;

    #[test]
    fn sensor_is_linear_in_exposure_noisy_as_poisson_and_saturates() {
        let sensor = Sensor {
            sensitivity: 100.0,
            full_well: 10_000.0,
            read_noise: 0.0,
            seed: 3,
        };
        let n = 20_000;
        let radiance = LinearImage::from_rgb(n, 1, vec![0.25; n * 3]).unwrap();
        let s = |t| ShotSettings {
            exposure_secs: t,
            gain: 1.0,
        };
        let a = sensor.expose(&radiance, s(0.01), 1); // mean 0.25 -> 2500 e
        let mean = a.data().iter().map(|&v| f64::from(v)).sum::<f64>() / (3 * n) as f64;
        let var = a
            .data()
            .iter()
            .map(|&v| (f64::from(v) - mean).powi(2))
            .sum::<f64>()
            / (3 * n) as f64;
        assert!((mean - 0.25).abs() < 1e-3, "{mean}");
        // Poisson: variance in electrons = mean electrons -> in value units mean / W
        let want = 0.25 / 10_000.0;
        assert!((var / want - 1.0).abs() < 0.05, "{var} vs {want}");
        let b = sensor.expose(&radiance, s(0.02), 1);
        let mean_b = b.data().iter().map(|&v| f64::from(v)).sum::<f64>() / (3 * n) as f64;
        assert!((mean_b / mean - 2.0).abs() < 0.01);
        let c = sensor.expose(&radiance, s(1.0), 1);
        assert!(c.data().iter().all(|&v| v == 1.0));
        // seeded: same key, same image; another key, another noise
        assert_eq!(sensor.expose(&radiance, s(0.01), 1), a);
        assert_ne!(sensor.expose(&radiance, s(0.01), 2), a);
    }

    struct FixedRig(Arc<Mutex<(f64, Vec<f64>)>>);
    impl RigView for FixedRig {
        fn angle_deg(&self) -> f64 {
            self.0.lock().unwrap().0
        }
        fn levels(&self) -> Vec<f64> {
            self.0.lock().unwrap().1.clone()
        }
    }

    /// Paints the request into the image so the test sees what the camera asked for.
    struct Probe;
    impl SceneRenderer for Probe {
        fn render(&self, req: &RenderRequest) -> LinearImage {
            let mut img = LinearImage::new(req.intrinsics.width, req.intrinsics.height);
            let l = req.lights.first().map(|l| l.dir_object).unwrap_or_default();
            img.set(0, 0, [l.x as f32, l.y as f32, req.ambient_radiance as f32]);
            img.set(
                1,
                0,
                [req.stage.target as u8 as f32, req.lights.len() as f32, 0.0],
            );
            img
        }
        fn describe(&self) -> String {
            "probe".into()
        }
    }

    #[test]
    fn the_camera_sees_the_rigs_angle_lights_and_stage_and_renders_a_bracket_once() {
        let state = Arc::new(Mutex::new((0.0, vec![0.0, 0.0])));
        let lab = LabGeometry {
            camera_distance_m: 0.6,
            camera_elevation_deg: 0.0,
            vertical_fov_deg: 30.0,
            lights: vec![(90.0, 0.0), (0.0, 90.0)],
        };
        let stage = StageState::default();
        let scene = SceneConfig {
            read_noise_electrons: 0.0,
            full_well_electrons: 1e12, // no visible shot noise
            sensitivity: 1.0,
            ..SceneConfig::default()
        };
        let mut cam = SimCamera::new(
            Box::new(FixedRig(state.clone())),
            stage.clone(),
            lab,
            scene,
            4,
            3,
            Arc::new(Probe),
        );
        let s = ShotSettings {
            exposure_secs: 1.0,
            gain: 1.0,
        };
        let (img, _) = cam.capture(s).unwrap();
        assert!((img.get(0, 0)[2] - 1.0).abs() < 1e-3, "room light on");
        *state.lock().unwrap() = (90.0, vec![1.0, 0.0]);
        stage.set(Stage {
            target: Target::Object,
            room_light: false,
        });
        let (img, _) = cam.capture(s).unwrap();
        // light 0 at lab +y; after turning the table by 90 degrees it is at object +x
        // (values are clamped to [0, 1] by the sensor, so check the sign pattern)
        let p = img.get(0, 0);
        assert!(p[0] > 0.99 && p[1] < 1e-3 && p[2] < 1e-3, "{p:?}");
        let renders = cam.renders();
        cam.capture(ShotSettings {
            exposure_secs: 0.5,
            gain: 1.0,
        })
        .unwrap();
        assert_eq!(cam.renders(), renders, "a bracket renders once");
        stage.set(Stage {
            target: Target::White,
            room_light: false,
        });
        let (img, _) = cam.capture(s).unwrap();
        assert_eq!(img.get(1, 0)[0], 1.0, "white target seen"); // Target::White as u8 = 2, clamped
        assert!(
            cam.capture(ShotSettings {
                exposure_secs: -1.0,
                gain: 1.0
            })
            .is_err()
        );
    }
}
