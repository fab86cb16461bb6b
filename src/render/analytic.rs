//! Ray-traced analytic scenes (spheres, planar boards) with no mesh: BRDF previews and the
//! calibration targets (a glossy black sphere for the light direction, a white Lambertian board
//! for the irradiance), exact to the pixel so calibration can be tested against known truth.
//!
//! One ray per pixel centre through `Intrinsics::ray` (distortion exact), nearest hit among the
//! shapes, radiance `f_r(l, v) E max(0, n . l)` with shadow rays between the shapes; no
//! anti-aliasing (a pixel shows one shape or the background). Directions follow
//! `render::light`; the BRDF frame is `ShadingFrame`. Pure.

use super::frame::ShadingFrame;
use super::image::LinearImage;
use super::light::DirectionalLight;
use crate::brdf::Brdf;
use crate::geometry::camera::{Intrinsics, Pose};
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

/// A shape a ray can hit: returns the distance along the unit ray and the unit outward normal.
pub trait AnalyticShape: Send + Sync {
    fn intersect(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<(f64, Vector3<f64>)>;
}

/// One object of a scene: a shape and its material.
pub struct SceneObject<'a> {
    pub shape: &'a dyn AnalyticShape,
    pub brdf: &'a dyn Brdf,
}

/// Renders the objects under `light` from camera `k`, `pose`; uncovered pixels get `background`.
pub fn render_analytic(
    objects: &[SceneObject<'_>],
    light: &DirectionalLight,
    k: &Intrinsics,
    pose: &Pose,
    background: [f32; 3],
) -> LinearImage {
    let (w, h) = (k.width, k.height);
    let mut img = LinearImage::new(w, h);
    if w == 0 {
        return img;
    }
    let centre = pose.centre();
    let world_from_cam = pose.rotation.inverse();
    img.data_mut()
        .par_chunks_mut(w * 3)
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..w {
                let dir = world_from_cam * k.ray(x as f64 + 0.5, y as f64 + 0.5);
                let px = &mut row[3 * x..3 * x + 3];
                match shade_ray(objects, light, &centre, &dir) {
                    Some(rgb) => px.copy_from_slice(&rgb),
                    None => px.copy_from_slice(&background),
                }
            }
        });
    img
}

/// Radiance along one camera ray (`None` when it hits nothing).
pub fn shade_ray(
    objects: &[SceneObject<'_>],
    light: &DirectionalLight,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
) -> Option<[f32; 3]> {
    let (t, n, obj) = nearest(objects, origin, dir)?;
    let p = origin + dir * t;
    let frame = ShadingFrame::new(n);
    let wo = frame.to_local(&-dir);
    let wi = frame.to_local(&light.to_light);
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return Some([0.0; 3]);
    }
    // shadow ray, offset relative to the distance travelled (scenes have no fixed scale)
    let shadow_origin = p + n * (1e-9 * t.max(1.0));
    if nearest(objects, &shadow_origin, &light.to_light).is_some() {
        return Some([0.0; 3]);
    }
    let fr = obj.brdf.eval_local(&wi, &wo);
    Some(std::array::from_fn(|c| {
        (fr[c] * light.irradiance[c] * wi.z) as f32
    }))
}

fn nearest<'a, 'b>(
    objects: &'b [SceneObject<'a>],
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
) -> Option<(f64, Vector3<f64>, &'b SceneObject<'a>)> {
    objects
        .iter()
        .filter_map(|o| o.shape.intersect(origin, dir).map(|(t, n)| (t, n, o)))
        .min_by(|a, b| a.0.total_cmp(&b.0))
}
