//! A planar rectangular board (the white reference target): a one-sided quad given by its
//! centre and two orthogonal half-extent axes, facing `half_u x half_v`. Rendering goes through
//! `render::raytraced`. Pure.

use super::image::LinearImage;
use super::light::DirectionalLight;
use super::raytraced::{AnalyticShape, SceneObject, render_analytic};
use crate::brdf::Brdf;
use crate::geometry::camera::{Intrinsics, Pose};
use nalgebra::{Point3, Vector3};

/// A rectangle `centre + s * half_u + t * half_v`, `|s|, |t| <= 1`; the front faces
/// `half_u x half_v`, the back is not seen (a ray from behind misses).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Board {
    pub centre: Point3<f64>,
    /// Half the width along the board's first axis.
    pub half_u: Vector3<f64>,
    /// Half the height along the second axis (orthogonal to `half_u`).
    pub half_v: Vector3<f64>,
}

impl Board {
    /// Unit normal of the front face.
    pub fn normal(&self) -> Vector3<f64> {
        self.half_u.cross(&self.half_v).normalize()
    }
}

impl AnalyticShape for Board {
    fn intersect(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<(f64, Vector3<f64>)> {
        let n = self.normal();
        let denom = dir.dot(&n);
        if denom >= 0.0 {
            return None; // parallel, or seen from behind
        }
        let t = (self.centre - origin).dot(&n) / denom;
        if t <= 0.0 {
            return None;
        }
        let d = origin + dir * t - self.centre;
        let s = d.dot(&self.half_u) / self.half_u.norm_squared();
        let r = d.dot(&self.half_v) / self.half_v.norm_squared();
        (s.abs() <= 1.0 && r.abs() <= 1.0).then_some((t, n))
    }
}

/// Renders one board with `brdf` under `light`.
pub fn render_board(
    board: &Board,
    brdf: &dyn Brdf,
    light: &DirectionalLight,
    k: &Intrinsics,
    pose: &Pose,
    background: [f32; 3],
) -> LinearImage {
    render_analytic(
        &[SceneObject {
            shape: board,
            brdf,
            coat_f0: None,
        }],
        light,
        k,
        pose,
        background,
    )
}
