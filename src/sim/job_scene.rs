//! Simulated reconstruction scenes: a mesh rendered with a known BRDF from a ring of cameras,
//! each with its own single directional light, written as a job folder (SfM-like mesh, COLMAP
//! text model, linear EXR images, `job.toml`). Used by the tests, the benchmark and the
//! accuracy study; an I/O edge (writes files). Unlike `sim::truth` (what a simulated turntable
//! session knows), this is a camera ring around the object, written as a job for `reconstruct`.
//!
//! Geometry: cameras on a ring around the mesh's bounding-box centre, world up = +y, at
//! `elevation_deg` above the ring plane, alternately above and below; the mesh fills about 80 %
//! of the shorter image side. Light: in camera axes, at angle `alpha` from the direction back to
//! the camera (`theta_d` about `alpha / 2` at the object), `alpha` spread evenly over
//! `light_angle_deg` across the views, rotated about the optical axis so it comes from above,
//! alternately left and right. A turntable rig with one fixed light has a single `alpha`; this
//! scene spreads it on purpose (METHOD.md section 1: the basis needs several `theta_d`).
//!
//! Materials: one BRDF for the whole object ([`write_scene`]), or one per face
//! ([`write_scene_materials`], labels from `geometry::labels`), with the truth per face written
//! beside the scene (`sim::truth_labels`).

use crate::brdf::Brdf;
use crate::geometry::bvh::Bvh;
use crate::geometry::camera::{Intrinsics, Pose};
use crate::geometry::colmap::{CameraModel, ColmapCamera, ColmapImage, ColmapModel, write_text};
use crate::geometry::labels::FaceLabels;
use crate::geometry::mesh::Mesh;
use crate::geometry::mesh_io::{PlyEncoding, write_ply};
use crate::imageio::{self, ExrPrecision};
use crate::reconstruct::job::{JOB_FILE, Job, LightImageSpec};
use crate::render::light::DirectionalLight;
use crate::render::shade::{ShadeOptions, check_materials, render_mesh_materials};
use crate::sim::truth_labels::write_truth_labels;
pub use crate::sim::truth_labels::{
    TRUTH_LABELS_FILE, TruthLabels, TruthLabelsError, read_truth_labels,
};
use nalgebra::{Point3, Vector3};
use std::path::Path;

/// How to lay out a simulated scene.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneSpec {
    pub views: usize,
    pub width: usize,
    pub height: usize,
    pub elevation_deg: f64,
    /// Range of the light-view angle alpha over the views, degrees.
    pub light_angle_deg: (f64, f64),
    pub irradiance: [f64; 3],
    /// The light turns with the camera: the same direction in camera axes in every view (one
    /// light fixed beside the camera of a turntable rig: a single theta_d). Otherwise it comes
    /// alternately from the upper left and the upper right.
    pub fixed_light: bool,
    /// Without `fixed_light`: the light also comes from below (upper left, upper right, lower
    /// left, lower right in turn) instead of from above only. A study of how well the light
    /// images pin the normals (docs/normal-refinement.md, "Session 41").
    pub light_from_below: bool,
}

impl SceneSpec {
    /// One light fixed beside the camera at `alpha_deg` from the optical axis (the paper's rig).
    pub fn one_light(alpha_deg: f64) -> Self {
        Self {
            light_angle_deg: (alpha_deg, alpha_deg),
            fixed_light: true,
            ..Self::default()
        }
    }
}

impl Default for SceneSpec {
    fn default() -> Self {
        Self {
            views: 11,
            width: 128,
            height: 96,
            elevation_deg: 25.0,
            light_angle_deg: (10.0, 150.0),
            irradiance: [3.0, 3.0, 3.0],
            fixed_light: false,
            light_from_below: false,
        }
    }
}

/// Camera and light of view `i` (light in camera axes).
pub fn view_geometry(mesh: &Mesh, spec: &SceneSpec, i: usize) -> (Intrinsics, Pose, Vector3<f64>) {
    let (lo, hi) = mesh.bounds();
    let centre = Point3::from((lo.coords + hi.coords) / 2.0);
    let radius = mesh.diagonal() / 2.0;
    let dist = 3.0 * radius;
    let az = 2.0 * std::f64::consts::PI * i as f64 / spec.views.max(1) as f64;
    let el = spec.elevation_deg.to_radians() * if i.is_multiple_of(2) { 1.0 } else { -0.4 };
    let eye = centre + dist * Vector3::new(el.cos() * az.sin(), el.sin(), el.cos() * az.cos());
    let pose = Pose::look_at(eye, centre, Vector3::y());
    let short = spec.width.min(spec.height) as f64;
    let f = 0.4 * short * dist / radius;
    let k = Intrinsics::pinhole(
        spec.width,
        spec.height,
        f,
        f,
        spec.width as f64 / 2.0,
        spec.height as f64 / 2.0,
    );
    let t = if spec.views > 1 {
        i as f64 / (spec.views - 1) as f64
    } else {
        0.5
    };
    let (a0, a1) = spec.light_angle_deg;
    let alpha = (a0 + t * (a1 - a0)).to_radians();
    // Around the optical axis: from above (-y), tilted left or right.
    let side = if i.is_multiple_of(2) || spec.fixed_light {
        40.0
    } else {
        -40.0
    };
    // from below every other pair of views, when asked
    let above = spec.fixed_light || !spec.light_from_below || (i / 2).is_multiple_of(2);
    let phi = if above { -90.0f64 + side } else { 90.0 - side }.to_radians();
    let l_cam = Vector3::new(
        alpha.sin() * phi.cos(),
        alpha.sin() * phi.sin(),
        -alpha.cos(),
    );
    (k, pose, l_cam)
}

/// Renders `truth_mesh` with `brdf` and writes the job folder; the job names `job_mesh` (the
/// SfM-like mesh the reconstruction sees). Returns the job, as written to `dir/job.toml`. The
/// one-material case of [`write_scene_materials`].
pub fn write_scene(
    dir: &Path,
    truth_mesh: &Mesh,
    job_mesh: &Mesh,
    brdf: &dyn Brdf,
    spec: &SceneSpec,
) -> std::io::Result<Job> {
    let labels = FaceLabels::uniform(truth_mesh.faces().len());
    write_scene_materials(dir, truth_mesh, job_mesh, &[brdf], &labels, &[], spec)
}

/// [`write_scene`] for an object of several materials: face `f` of `truth_mesh` is rendered
/// with `brdfs[labels.labels[f]]`. With more than one material (`labels.count > 1`) the truth is
/// written beside the scene, `dir/truth_labels.json` (`sim::truth_labels`: the labels and
/// `names`, empty or one name per material); with one, the folder is exactly
/// [`write_scene`]'s.
///
/// The labels are per face of `truth_mesh`. `geometry::sfm_like` moves vertices and keeps the
/// faces, so for a `job_mesh` made by it (or `truth_mesh` itself) they are also the labels of
/// the job's `mesh.ply`; a job mesh of another face count is refused when there is more than one
/// material, since the truth would not describe it. Every check runs before anything is written.
pub fn write_scene_materials(
    dir: &Path,
    truth_mesh: &Mesh,
    job_mesh: &Mesh,
    brdfs: &[&dyn Brdf],
    labels: &FaceLabels,
    names: &[String],
    spec: &SceneSpec,
) -> std::io::Result<Job> {
    let invalid = |e: &dyn std::fmt::Display| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!("simulated scene {}: {e}", dir.display()),
        )
    };
    check_materials(truth_mesh, brdfs, labels).map_err(|e| invalid(&e))?;
    let several = labels.count > 1;
    if several && job_mesh.faces().len() != truth_mesh.faces().len() {
        return Err(invalid(&format_args!(
            "the job mesh has {} faces and the truth mesh {}: the truth labels would not \
             describe the job mesh (make it with geometry::sfm_like, which keeps the faces)",
            job_mesh.faces().len(),
            truth_mesh.faces().len()
        )));
    }
    if !names.is_empty() && names.len() != labels.count as usize {
        return Err(invalid(&format_args!(
            "{} material names for {} materials",
            names.len(),
            labels.count
        )));
    }
    let io = |e: &dyn std::fmt::Display| std::io::Error::other(e.to_string());
    std::fs::create_dir_all(dir.join("light"))?;
    let bvh = Bvh::build(truth_mesh);
    let mut model = ColmapModel::default();
    let mut light_images = Vec::with_capacity(spec.views);
    for i in 0..spec.views {
        let (k, pose, l_cam) = view_geometry(truth_mesh, spec, i);
        let light = DirectionalLight::new(pose.dir_to_world(&l_cam), spec.irradiance)
            .ok_or_else(|| io(&"degenerate light direction"))?;
        let img = render_mesh_materials(
            truth_mesh,
            &bvh,
            &k,
            &pose,
            brdfs,
            labels,
            &ShadeOptions::single_light(light),
        );
        let name = format!("view_{i:02}.exr");
        let file = dir.join("light").join(&name);
        imageio::write_exr(&file, &img, ExrPrecision::F32).map_err(|e| io(&e))?;
        let id = i as u32 + 1;
        model.cameras.insert(
            id,
            ColmapCamera {
                id,
                model: CameraModel::Pinhole,
                intrinsics: k,
            },
        );
        model.images.push(ColmapImage {
            id,
            camera_id: id,
            name: name.clone(),
            pose,
        });
        light_images.push(LightImageSpec {
            file,
            camera: name,
            light_dir_camera: l_cam,
            irradiance: spec.irradiance,
            mask: None,
            labels: None,
            saturation: None,
        });
    }
    std::fs::create_dir_all(dir.join("sparse"))?;
    write_text(&dir.join("sparse"), &model).map_err(|e| io(&e))?;
    write_ply(
        &dir.join("mesh.ply"),
        job_mesh,
        PlyEncoding::BinaryLittleEndian,
    )
    .map_err(|e| io(&e))?;
    let job = Job {
        source: dir.join(JOB_FILE),
        mesh: dir.join("mesh.ply"),
        cameras: dir.join("sparse"),
        light_images,
        warnings: Vec::new(),
    };
    if several {
        write_truth_labels(&dir.join(TRUTH_LABELS_FILE), labels, names).map_err(|e| io(&e))?;
    }
    let text = job.to_toml(dir).map_err(std::io::Error::other)?;
    crate::atomic::write_atomic(&job.source, text.as_bytes())?;
    Ok(job)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::Mesh;

    fn cube() -> Mesh {
        let p = |x: f64, y: f64, z: f64| Point3::new(x, y, z);
        let positions = vec![
            p(0.0, 0.0, 0.0),
            p(1.0, 0.0, 0.0),
            p(1.0, 1.0, 0.0),
            p(0.0, 1.0, 0.0),
            p(0.0, 0.0, 1.0),
            p(1.0, 0.0, 1.0),
            p(1.0, 1.0, 1.0),
            p(0.0, 1.0, 1.0),
        ];
        let faces = vec![[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7]];
        Mesh::new(positions, faces, "two squares")
            .expect("a mesh")
            .0
    }

    /// Camera y points down in the image, so a light from above has a negative y in camera
    /// axes: from above in every view by default, from below in every other pair of views with
    /// `light_from_below`, and never from below with one light fixed to the camera.
    #[test]
    fn the_light_comes_from_below_only_when_asked() {
        let mesh = cube();
        let y = |spec: &SceneSpec| -> Vec<f64> {
            (0..8).map(|i| view_geometry(&mesh, spec, i).2.y).collect()
        };
        let above = y(&SceneSpec::default());
        assert!(above.iter().all(|v| *v < 0.0), "{above:?}");
        let spread = y(&SceneSpec {
            light_from_below: true,
            ..SceneSpec::default()
        });
        let signs: Vec<bool> = spread.iter().map(|v| *v < 0.0).collect();
        assert_eq!(
            signs,
            [true, true, false, false, true, true, false, false],
            "{spread:?}"
        );
        let fixed = y(&SceneSpec {
            light_from_below: true,
            ..SceneSpec::one_light(30.0)
        });
        assert!(fixed.iter().all(|v| *v < 0.0), "{fixed:?}");
    }
}
