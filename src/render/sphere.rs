//! An analytic sphere (ray-sphere intersection, no mesh): BRDF previews and the glossy black
//! calibration sphere. Rendering goes through `render::raytraced`. Pure.

use super::image::LinearImage;
use super::light::DirectionalLight;
use super::raytraced::{AnalyticShape, SceneObject, render_analytic};
use crate::brdf::Brdf;
use crate::geometry::camera::{Intrinsics, Pose};
use nalgebra::{Point3, Vector3};

/// A sphere in world coordinates; its normals point outwards.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    pub centre: Point3<f64>,
    pub radius: f64,
}

impl AnalyticShape for Sphere {
    /// The nearest hit in front of the origin (from outside: the near side; from inside: the far
    /// side, with the outward normal).
    fn intersect(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<(f64, Vector3<f64>)> {
        let oc = origin - self.centre;
        let a = dir.norm_squared();
        let half_b = oc.dot(dir);
        let c = oc.norm_squared() - self.radius * self.radius;
        let disc = half_b * half_b - a * c;
        if disc < 0.0 || a == 0.0 {
            return None;
        }
        let sq = disc.sqrt();
        // numerically stable roots (no cancellation between half_b and sq)
        let q = -(half_b + sq.copysign(half_b));
        let (t0, t1) = if q != 0.0 {
            let (r0, r1) = (q / a, c / q);
            (r0.min(r1), r0.max(r1))
        } else {
            (0.0, 0.0)
        };
        let t = if t0 > 0.0 {
            t0
        } else if t1 > 0.0 {
            t1
        } else {
            return None;
        };
        let n = (origin + dir * t - self.centre) / self.radius;
        Some((t, n))
    }
}

/// Renders one sphere with `brdf` under `light`.
pub fn render_sphere(
    sphere: &Sphere,
    brdf: &dyn Brdf,
    light: &DirectionalLight,
    k: &Intrinsics,
    pose: &Pose,
    background: [f32; 3],
) -> LinearImage {
    render_analytic(
        &[SceneObject {
            shape: sphere,
            brdf,
            coat_f0: None,
        }],
        light,
        k,
        pose,
        background,
    )
}
