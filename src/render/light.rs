//! Light sources for rendering: a far directional light (the rig's single light) and a uniform
//! white environment (room light for the ambient multi-view images).
//!
//! Conventions: `to_light` is a unit world direction pointing from the surface towards the
//! light; `irradiance` is RGB irradiance on a surface facing the light (W m^-2 per channel, or any
//! consistent unit), so a surface with normal n receives `irradiance * max(0, n . to_light)`.
//! Pure.

use nalgebra::Vector3;

/// A light at infinity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectionalLight {
    /// Unit direction towards the light, world coordinates.
    pub to_light: Vector3<f64>,
    /// RGB irradiance on a surface facing the light.
    pub irradiance: [f64; 3],
}

impl DirectionalLight {
    /// Normalises `to_light`; `None` when it is zero or not finite.
    pub fn new(to_light: Vector3<f64>, irradiance: [f64; 3]) -> Option<Self> {
        let n = to_light.norm();
        (n > 0.0 && n.is_finite()).then(|| Self {
            to_light: to_light / n,
            irradiance,
        })
    }
}

/// A uniform environment of constant RGB radiance from every direction, integrated by
/// cosine-weighted hemisphere sampling of the BRDF: `samples` directions per pixel (rounded up to
/// a square number), one jittered point per stratum of the unit square, drawn from `seed` and the
/// pixel index, so images are deterministic.
/// With `occlusion`, each sample direction is tested against the mesh (ambient occlusion), and
/// directions below the hit face's plane (possible when the interpolated normal leans away from
/// the face normal) count as blocked; without, the whole hemisphere of the normal counts. For a Lambertian BRDF the estimate is exact without
/// occlusion (`albedo * radiance`) whatever the sample count.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UniformEnvironment {
    pub radiance: [f64; 3],
    pub samples: usize,
    pub occlusion: bool,
    pub seed: u64,
}
