//! One observation: a usable pixel of a single-light image with what the rest of the
//! reconstruction needs (directions, reflectance, MERL bin, curvature), and where it was seen.
//! Conventions as `reconstruct::observe`, which makes them from images. Pure.

use crate::brdf::coords::{HalfDiff, merl_index};
use crate::render::frame::ShadingFrame;
use nalgebra::{Point3, Vector3};

/// Where a pixel was seen: the light image, the pixel, the surface point, its unit normal
/// (world frame, facing the camera) and the surface's mean curvature there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Seen {
    /// Index of the light image in the job.
    pub image: usize,
    pub x: u32,
    pub y: u32,
    pub position: Point3<f64>,
    pub normal: Vector3<f64>,
    /// Mean curvature H = (k1 + k2) / 2, in 1 / (mesh unit).
    pub mean_curvature: f64,
    /// The mesh face the pixel sees ([`NO_FACE`] when not from a mesh).
    pub face: u32,
}

/// The face of a pixel that was not seen on a mesh (tests and probes).
pub const NO_FACE: u32 = u32::MAX;

impl Seen {
    /// A pixel at the origin of a flat surface with normal `normal` (for tests and probes that
    /// only need the directions).
    pub fn pixel(image: usize, x: u32, y: u32, normal: Vector3<f64>) -> Self {
        Self {
            image,
            x,
            y,
            position: Point3::origin(),
            normal,
            mean_curvature: 0.0,
            face: NO_FACE,
        }
    }
}

/// One usable pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Observation {
    /// Index of the light image in the job.
    pub image: usize,
    pub x: u32,
    pub y: u32,
    pub position: Point3<f64>,
    pub normal: Vector3<f64>,
    pub light: Vector3<f64>,
    pub view: Vector3<f64>,
    pub mean_curvature: f64,
    /// The mesh face the pixel sees ([`NO_FACE`] when not from a mesh).
    pub face: u32,
    /// Pixel value I (linear), RGB.
    pub radiance: [f64; 3],
    pub irradiance: [f64; 3],
    /// r = I / (E cos theta_i), RGB.
    pub reflectance: [f64; 3],
    pub cos_theta_i: f64,
    pub cos_theta_o: f64,
    /// n . h, the quantity ordered by the monotonicity assumption.
    pub n_dot_h: f64,
    pub angles: HalfDiff,
    /// Flat MERL index of (theta_h, theta_d, phi_d).
    pub bin: usize,
}

/// `(wi, wo)` in the local shading frame of `n` (normal = +z; `render::frame`, shared with
/// the renderer so observation and rendering agree).
pub fn to_local(
    n: &Vector3<f64>,
    l: &Vector3<f64>,
    v: &Vector3<f64>,
) -> (Vector3<f64>, Vector3<f64>) {
    let frame = ShadingFrame::new(*n);
    (frame.to_local(l), frame.to_local(v))
}

impl Observation {
    /// Builds an observation of the pixel `seen` lit from `light` and seen from `view` (unit,
    /// world, away from the surface), with pixel value `radiance` under `irradiance`; `None`
    /// when the geometry is below either horizon.
    pub fn new(
        seen: Seen,
        light: Vector3<f64>,
        view: Vector3<f64>,
        radiance: [f64; 3],
        irradiance: [f64; 3],
    ) -> Option<Self> {
        let Seen {
            image,
            x,
            y,
            position,
            normal,
            mean_curvature,
            face,
        } = seen;
        let cos_theta_i = normal.dot(&light);
        let cos_theta_o = normal.dot(&view);
        if !(cos_theta_i > 0.0 && cos_theta_o > 0.0) {
            return None;
        }
        let h = (light + view).try_normalize(1e-12)?;
        let (wi, wo) = to_local(&normal, &light, &view);
        let reflectance = [0, 1, 2].map(|c| radiance[c] / (irradiance[c] * cos_theta_i));
        Some(Self {
            image,
            x,
            y,
            position,
            normal,
            light,
            view,
            mean_curvature,
            face,
            radiance,
            irradiance,
            reflectance,
            cos_theta_i,
            cos_theta_o,
            n_dot_h: normal.dot(&h),
            angles: HalfDiff::from_directions(&wi, &wo),
            bin: merl_index(&wi, &wo),
        })
    }

    /// The half vector h = (l + v) / |l + v|.
    pub fn half(&self) -> Vector3<f64> {
        (self.light + self.view).normalize()
    }

    /// Mean reflectance over the channels (the "luminance" compared by the monotonicity check).
    pub fn luminance(&self) -> f64 {
        self.reflectance.iter().sum::<f64>() / 3.0
    }

    /// The same pixel with another normal (assumption 3 sets n = h); `None` below a horizon.
    pub fn with_normal(&self, normal: Vector3<f64>) -> Option<Self> {
        Self::new(
            Seen {
                normal,
                ..self.seen()
            },
            self.light,
            self.view,
            self.radiance,
            self.irradiance,
        )
    }

    /// Where this observation was seen.
    pub fn seen(&self) -> Seen {
        Seen {
            image: self.image,
            x: self.x,
            y: self.y,
            position: self.position,
            normal: self.normal,
            mean_curvature: self.mean_curvature,
            face: self.face,
        }
    }
}

#[cfg(test)]
impl Observation {
    /// A test pixel of image 0 at (0, 0): normal, light and view +z, unit irradiance and
    /// cosines, `radiance` (and the same reflectance), at the given theta_h and theta_d
    /// (radians; phi_h 0, phi_d 1) and their MERL bin.
    pub fn at_angles(theta_h: f64, theta_d: f64, radiance: [f64; 3]) -> Self {
        let angles = HalfDiff {
            theta_h,
            phi_h: 0.0,
            theta_d,
            phi_d: 1.0,
        };
        Self {
            image: 0,
            x: 0,
            y: 0,
            position: Point3::origin(),
            normal: Vector3::z(),
            light: Vector3::z(),
            view: Vector3::z(),
            mean_curvature: 0.0,
            face: NO_FACE,
            radiance,
            irradiance: [1.0; 3],
            reflectance: radiance,
            cos_theta_i: 1.0,
            cos_theta_o: 1.0,
            n_dot_h: 1.0,
            angles,
            bin: angles.merl_bin().index(),
        }
    }

    /// Test pixels of `truth` over a cap of normals (within about 22 degrees of +z), seen from
    /// `v` and lit from each of `lights` (light `j` is image `j`), their reflectance and
    /// radiance (unit irradiance) `truth`'s.
    pub fn lobe_pixels(
        truth: &dyn crate::brdf::Brdf,
        v: Vector3<f64>,
        lights: &[Vector3<f64>],
    ) -> Vec<Self> {
        let mut out = Vec::new();
        for (j, l) in lights.iter().enumerate() {
            for i in 0..400 {
                let t = i as f64 * 2.399;
                let r = 0.4 * ((i as f64 + 0.5) / 400.0).sqrt();
                let n = Vector3::new(r * t.cos(), r * t.sin(), 1.0).normalize();
                let Some(mut o) =
                    Self::new(Seen::pixel(j, i as u32, 0, n), *l, v, [1.0; 3], [1.0; 3])
                else {
                    continue;
                };
                let (wi, wo) = to_local(&n, l, &v);
                o.reflectance = truth.eval_local(&wi, &wo);
                o.radiance = o.reflectance.map(|x| x * o.cos_theta_i);
                out.push(o);
            }
        }
        out
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn reflectance_and_angles_of_a_known_configuration() {
        // Normal +z, light 60 deg from it in the xz plane, viewer straight above.
        let n = Vector3::z();
        let l = Vector3::new(60f64.to_radians().sin(), 0.0, 60f64.to_radians().cos());
        let v = Vector3::z();
        let o = Observation::new(Seen::pixel(0, 1, 2, n), l, v, [0.5, 1.0, 1.5], [2.0; 3]).unwrap();
        // r = I / (E cos 60) = I
        for c in 0..3 {
            assert!((o.reflectance[c] - [0.5, 1.0, 1.5][c]).abs() < 1e-12);
        }
        assert!((o.angles.theta_h - 30f64.to_radians()).abs() < 1e-12);
        assert!((o.angles.theta_d - 30f64.to_radians()).abs() < 1e-12);
        assert!((o.n_dot_h - 30f64.to_radians().cos()).abs() < 1e-12);
        // The result does not depend on the world orientation (isotropy + local frame).
        let rot = nalgebra::Rotation3::from_euler_angles(0.3, -1.1, 2.0);
        let o2 = Observation::new(
            Seen::pixel(0, 1, 2, rot * n),
            rot * l,
            rot * v,
            [0.5, 1.0, 1.5],
            [2.0; 3],
        )
        .unwrap();
        assert_eq!(o.bin, o2.bin);
        assert!((o.angles.theta_d - o2.angles.theta_d).abs() < 1e-9);
        // Below the horizon: none.
        assert!(Observation::new(Seen::pixel(0, 0, 0, n), -l, v, [1.0; 3], [1.0; 3]).is_none());
        // n = h puts the pixel in theta_h bin 0.
        let oh = o.with_normal(o.half()).unwrap();
        assert!(oh.angles.theta_h < 1e-7);
        assert!((oh.n_dot_h - 1.0).abs() < 1e-12);
    }
}
