//! The simulated camera's renderer: the object (mesh + neural MERL fit) under the lit channels
//! and the room light, or the calibration targets, through the shared rendering code
//! (`render::shade`, `render::sphere`, `render::board`), so the simulator and reconstruction
//! agree on what a BRDF looks like.
//!
//! The calibration targets: a black glossy sphere (a dim Lambertian base plus a narrow
//! normalised Blinn-Phong lobe, so the highlight is small and bright, as on a polished black
//! ball, under a smooth coat that mirrors the lit backdrop near the rim with Fresnel reflectance
//! `scene.sphere_coat_f0`) and a white Lambertian board of the configured albedo facing the
//! camera. Both sit at the turntable centre. The room light lights only the object (calibration
//! shots are taken with the room light off).
//!
//! The targets are imaged as a real camera images them (`render::raytraced::CameraOptics`): each
//! pixel integrates over its area (`scene.pixel_samples` rays per side) after a Gaussian lens blur
//! (`scene.psf_sigma_px`). The highlight is about a pixel wide at 160x120; sampled at pixel
//! centres only it would snap to the pixel grid, which no camera does. The object itself is still
//! one ray per pixel (`render::shade`).

use nalgebra::{Point3, Vector3};
use std::sync::Arc;

use super::camera::{RenderRequest, SceneRenderer};
use super::scene::{SceneConfig, y_up_to_z_up};
use crate::brdf::Brdf;
use crate::brdf::nbrdf::Nbrdf;
use crate::capture::plan::Target;
use crate::geometry::bvh::Bvh;
use crate::geometry::mesh::Mesh;
use crate::geometry::mesh_io::load_mesh;
use crate::render::board::Board;
use crate::render::image::LinearImage;
use crate::render::light::{DirectionalLight, UniformEnvironment};
use crate::render::raytraced::{CameraOptics, SceneObject, render_analytic_with};
use crate::render::shade::{ShadeOptions, render_mesh};
use crate::render::sphere::Sphere;

/// Why the scene could not be built.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("loading the scene mesh {path}: {source}")]
    Mesh {
        path: String,
        #[source]
        source: crate::geometry::mesh_io::MeshIoError,
    },
    #[error("loading the scene mesh {path}: {source}")]
    Place {
        path: String,
        #[source]
        source: PlaceError,
    },
    #[error("loading the material {path}: {source} (names are the files in data/merl-nbrdf)")]
    Material {
        path: String,
        #[source]
        source: crate::brdf::nbrdf::NbrdfError,
    },
}

/// Why a loaded mesh cannot be placed on the turntable.
#[derive(Debug, thiserror::Error)]
pub enum PlaceError {
    #[error("the mesh has no extent")]
    NoExtent,
    #[error("placing the mesh failed")]
    Positions,
}

/// Lambertian reflector: f_r = albedo / pi.
#[derive(Clone, Copy, Debug)]
pub struct Lambertian(pub [f64; 3]);

impl Brdf for Lambertian {
    fn eval_local(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> [f64; 3] {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return [0.0; 3];
        }
        self.0.map(|a| a / std::f64::consts::PI)
    }
}

/// A polished black surface: dim diffuse base and a normalised Blinn-Phong lobe.
#[derive(Clone, Copy, Debug)]
pub struct BlackGloss {
    pub diffuse: f64,
    pub specular: f64,
    pub exponent: f64,
}

impl Brdf for BlackGloss {
    fn eval_local(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> [f64; 3] {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return [0.0; 3];
        }
        let h = (wi + wo).normalize();
        let lobe = self.specular * (self.exponent + 8.0) / (8.0 * std::f64::consts::PI)
            * h.z.max(0.0).powf(self.exponent);
        [self.diffuse / std::f64::consts::PI + lobe; 3]
    }
}

/// The loaded scene: object mesh (placed in the object frame), its BVH and BRDF.
pub struct ObjectScene {
    mesh: Mesh,
    bvh: Bvh,
    brdf: Arc<dyn Brdf>,
    config: SceneConfig,
}

impl ObjectScene {
    /// Loads the mesh and the material the config names and places the mesh (centred, z up,
    /// scaled to `object_size_m`).
    pub fn load(config: &SceneConfig) -> Result<Self, SceneError> {
        let mesh_path = config.mesh_path();
        let (mesh, _) = load_mesh(&mesh_path).map_err(|source| SceneError::Mesh {
            path: mesh_path.display().to_string(),
            source,
        })?;
        let material_path = config.material_path();
        let brdf = Nbrdf::load(&material_path).map_err(|source| SceneError::Material {
            path: material_path.display().to_string(),
            source,
        })?;
        Self::from_parts(mesh, Arc::new(brdf), config).map_err(|source| SceneError::Place {
            path: mesh_path.display().to_string(),
            source,
        })
    }

    /// Places an already loaded mesh with any BRDF.
    pub fn from_parts(
        mut mesh: Mesh,
        brdf: Arc<dyn Brdf>,
        config: &SceneConfig,
    ) -> Result<Self, PlaceError> {
        let (lo, hi) = mesh.bounds();
        let centre = Point3::from((lo.coords + hi.coords) * 0.5);
        let diag = (hi - lo).norm();
        if diag <= 0.0 {
            return Err(PlaceError::NoExtent);
        }
        let scale = config.object_size_m / diag;
        let rot = if config.mesh_up == "z" {
            nalgebra::Rotation3::identity()
        } else {
            y_up_to_z_up()
        };
        let placed: Vec<Point3<f64>> = mesh
            .positions()
            .iter()
            .map(|p| Point3::from(rot * ((p - centre) * scale)))
            .collect();
        if !mesh.set_positions(placed) {
            return Err(PlaceError::Positions);
        }
        let bvh = Bvh::build(&mesh);
        Ok(Self {
            mesh,
            bvh,
            brdf,
            config: config.clone(),
        })
    }

    /// The placed mesh (object frame): the ground truth geometry.
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    fn black_sphere(&self) -> (Sphere, BlackGloss) {
        (
            Sphere {
                centre: Point3::origin(),
                radius: self.config.sphere_radius_m,
            },
            BlackGloss {
                diffuse: 0.01,
                specular: 0.9,
                exponent: 2000.0,
            },
        )
    }

    fn white_board(&self, req: &RenderRequest) -> Board {
        // Square, standing on the turntable centre, front normal as the request says.
        let n = req.board_normal_object.normalize();
        let side = 1.5
            * self
                .config
                .sphere_radius_m
                .max(self.config.object_size_m * 0.3);
        let u = Vector3::z().cross(&n).normalize() * side;
        let v = n.cross(&u).normalize() * side;
        Board {
            centre: Point3::origin(),
            half_u: u,
            half_v: v,
        }
    }
}

fn add(a: &mut LinearImage, b: &LinearImage) {
    for (x, y) in a.data_mut().iter_mut().zip(b.data()) {
        *x += *y;
    }
}

impl SceneRenderer for ObjectScene {
    fn render(&self, req: &RenderRequest) -> LinearImage {
        let k = &req.intrinsics;
        let pose = &req.camera_from_object;
        let mut img = LinearImage::new(k.width, k.height);
        let optics = CameraOptics {
            samples_per_side: self.config.pixel_samples,
            psf_sigma_px: self.config.psf_sigma_px,
        };
        match req.stage.target {
            Target::Object => {
                if req.ambient_radiance > 0.0 {
                    let opts = ShadeOptions {
                        light: None,
                        environment: Some(UniformEnvironment {
                            radiance: [req.ambient_radiance; 3],
                            samples: 16,
                            occlusion: true,
                            seed: self.config.seed,
                        }),
                        shadows: false,
                        // A grey backdrop, as a room behind the turntable would give.
                        background: [0.1 * req.ambient_radiance as f32; 3],
                    };
                    add(
                        &mut img,
                        &render_mesh(&self.mesh, &self.bvh, k, pose, self.brdf.as_ref(), &opts),
                    );
                }
                for l in &req.lights {
                    if let Some(light) = DirectionalLight::new(l.dir_object, [l.irradiance; 3]) {
                        let opts = ShadeOptions::single_light(light);
                        add(
                            &mut img,
                            &render_mesh(&self.mesh, &self.bvh, k, pose, self.brdf.as_ref(), &opts),
                        );
                    }
                }
            }
            Target::Sphere => {
                let (sphere, brdf) = self.black_sphere();
                for l in &req.lights {
                    if let Some(light) = DirectionalLight::new(l.dir_object, [l.irradiance; 3]) {
                        // A matte grey backdrop (albedo 0.5) behind the sphere, lit by the same
                        // light, as a lab sets one up: the black sphere's outline then stands
                        // out all round, not only on its lit side.
                        let backdrop = [(0.5 * l.irradiance / std::f64::consts::PI) as f32; 3];
                        let obj = SceneObject {
                            shape: &sphere,
                            brdf: &brdf,
                            coat_f0: Some(self.config.sphere_coat_f0),
                        };
                        add(
                            &mut img,
                            &render_analytic_with(&[obj], &light, k, pose, backdrop, &optics),
                        );
                    }
                }
            }
            Target::White => {
                let board = self.white_board(req);
                let brdf = Lambertian([self.config.white_albedo; 3]);
                for l in &req.lights {
                    if let Some(light) = DirectionalLight::new(l.dir_object, [l.irradiance; 3]) {
                        let obj = SceneObject {
                            shape: &board,
                            brdf: &brdf,
                            coat_f0: None,
                        };
                        add(
                            &mut img,
                            &render_analytic_with(&[obj], &light, k, pose, [0.0; 3], &optics),
                        );
                    }
                }
            }
        }
        img
    }

    fn describe(&self) -> String {
        format!(
            "{} with {} (neural MERL fit), {} triangles",
            self.config.mesh,
            self.config.material,
            self.mesh.faces().len()
        )
    }
}

impl super::camera::RigView for crate::sim::SimHandle {
    fn angle_deg(&self) -> f64 {
        self.snapshot().angle_deg
    }
    fn levels(&self) -> Vec<f64> {
        self.snapshot().levels
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;
    use crate::capture::plan::{LabGeometry, Stage};
    use crate::sim::camera::LitLight;
    use crate::sim::scene::{SimCameraRig, light_dir_object};

    fn setup(
        target: Target,
        angle: f64,
        channel: usize,
    ) -> (ObjectScene, RenderRequest, LabGeometry) {
        let lab = LabGeometry {
            camera_distance_m: 0.6,
            camera_elevation_deg: 0.0,
            vertical_fov_deg: 30.0,
            lights: vec![(20.0, 0.0), (60.0, 0.0), (110.0, 0.0)],
        };
        let cfg = SceneConfig::default();
        let scene = ObjectScene::load(&cfg).unwrap();
        let rig = SimCameraRig::new(&lab, 64, 48);
        let l_lab = lab.light_dir_lab(channel).unwrap();
        let req = RenderRequest {
            intrinsics: rig.intrinsics,
            camera_from_object: rig.camera_from_object(angle),
            stage: Stage {
                target,
                room_light: false,
            },
            ambient_radiance: 0.0,
            lights: vec![LitLight {
                dir_object: light_dir_object(&l_lab, angle),
                irradiance: 2.0,
            }],
            board_normal_object: lab.camera_dir_lab(),
        };
        (scene, req, lab)
    }

    #[test]
    fn white_board_turned_to_the_bisector_has_the_lambertian_radiance() {
        // channel 2 at azimuth 110: the runner turns the board by 55 degrees
        let (scene, req, _) = setup(Target::White, 55.0, 2);
        let img = scene.render(&req);
        let c = img.get(32, 24);
        let want = 0.99 * 2.0 * (55.0f64).to_radians().cos() / std::f64::consts::PI;
        for v in c {
            assert!((f64::from(v) - want).abs() < 1e-4, "{v} vs {want}");
        }
    }

    #[test]
    fn black_sphere_shows_a_highlight_where_the_mirror_direction_says() {
        let (scene, req, lab) = setup(Target::Sphere, 0.0, 1);
        let img = scene.render(&req);
        // the grey backdrop is uniform: look on the sphere only (pixels that differ from it)
        let backdrop = img.luminance(0, 0);
        let (mut best, mut at) = (0.0, (0, 0));
        for y in 0..img.height() {
            for x in 0..img.width() {
                let v = img.luminance(x, y);
                if v != backdrop && v > best {
                    best = img.luminance(x, y);
                    at = (x, y);
                }
            }
        }
        // normal at the highlight bisects camera and light (60 deg apart in the horizontal
        // plane): 30 deg towards the light (+y in the lab), which is left in the image
        let rig = SimCameraRig::new(&lab, 64, 48);
        let n = nalgebra::Vector3::new(30f64.to_radians().cos(), 30f64.to_radians().sin(), 0.0);
        let p = nalgebra::Point3::from(n * scene.config.sphere_radius_m);
        let (px, py) = rig
            .intrinsics
            .project(&rig.camera_from_object(0.0).camera_from_world(&p))
            .unwrap();
        assert!(
            (at.0 as f64 + 0.5 - px).abs() <= 1.5 && (at.1 as f64 + 0.5 - py).abs() <= 1.5,
            "{at:?} vs ({px}, {py})"
        );
        assert!(best > 10.0 * img.luminance(32, 24).max(1e-6) || best > 1.0);
    }

    #[test]
    fn object_is_lit_from_the_light_side_and_dark_without_light() {
        let (scene, mut req, _) = setup(Target::Object, 0.0, 1);
        let lit = scene.render(&req);
        let covered = lit.data().iter().filter(|&&v| v > 0.0).count();
        assert!(covered > 100, "{covered}");
        req.lights.clear();
        let dark = scene.render(&req);
        assert!(dark.data().iter().all(|&v| v == 0.0));
        assert!(scene.describe().contains("neural MERL fit"));
    }
}
