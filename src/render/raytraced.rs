//! Ray-traced analytic scenes (spheres, planar boards) with no mesh: BRDF previews and the
//! calibration targets (a glossy black sphere for the light direction, a white Lambertian board
//! for the irradiance), exact to the pixel so calibration can be tested against known truth.
//!
//! Radiance along a camera ray: nearest hit among the shapes, `f_r(l, v) E max(0, n . l)` with
//! shadow rays between the shapes, plus, for an object with a smooth coat
//! ([`SceneObject::coat_f0`]), the surroundings mirrored with Schlick's Fresnel reflectance: the
//! backdrop (`background`) in directions pointing away from the camera (behind the scene, where a
//! missed camera ray looks too), a dark room towards the camera's side.
//!
//! Pixels: [`render_analytic`] takes one ray per pixel centre through `Intrinsics::ray`
//! (distortion exact), no anti-aliasing: a pixel shows one shape or the background, which tests
//! of exact per-pixel values rely on. [`render_analytic_with`] images as a real camera does
//! ([`CameraOptics`]): each pixel integrates radiance over its area (an `n x n` grid of rays) after
//! an optical point-spread function (Gaussian), so a feature smaller than a pixel, like the
//! calibration sphere's highlight, spreads over its neighbours in proportion to where it lies
//! instead of snapping to the pixel grid. Directions follow `render::light`; the BRDF frame is
//! `ShadingFrame`. Pure.

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
    /// A smooth dielectric coat with this normal-incidence Fresnel reflectance (0.04 for glossy
    /// plastic or glass) mirrors the surroundings on top of `brdf`; `None`: the BRDF alone.
    pub coat_f0: Option<f64>,
}

/// How the camera turns the radiance field into pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraOptics {
    /// Rays per pixel side: a pixel averages an `n x n` grid of rays over its area (a sensor
    /// integrates; 1 = one ray through the pixel centre).
    pub samples_per_side: usize,
    /// Standard deviation of the lens's Gaussian point-spread function, in pixels (0 = none).
    pub psf_sigma_px: f64,
}

impl CameraOptics {
    /// One ray per pixel centre, no blur: an ideal point-sampling pinhole.
    pub const POINT: Self = Self {
        samples_per_side: 1,
        psf_sigma_px: 0.0,
    };
}

/// Output rows rendered together: their fine rows plus the blur's margin are kept in memory.
const BAND_ROWS: usize = 16;

/// Renders the objects under `light` from camera `k`, `pose`, one ray per pixel centre;
/// uncovered pixels get `background`.
pub fn render_analytic(
    objects: &[SceneObject<'_>],
    light: &DirectionalLight,
    k: &Intrinsics,
    pose: &Pose,
    background: [f32; 3],
) -> LinearImage {
    render_analytic_with(objects, light, k, pose, background, &CameraOptics::POINT)
}

/// Renders as [`render_analytic`] through a camera with pixel-area integration and a
/// point-spread function (see the module header). The image is rendered on a grid `n` times
/// finer, blurred there by the PSF (edges extended), and averaged over each pixel's `n x n`
/// block; bands of rows run in parallel.
pub fn render_analytic_with(
    objects: &[SceneObject<'_>],
    light: &DirectionalLight,
    k: &Intrinsics,
    pose: &Pose,
    background: [f32; 3],
    optics: &CameraOptics,
) -> LinearImage {
    let (w, h) = (k.width, k.height);
    let mut img = LinearImage::new(w, h);
    if w == 0 || h == 0 {
        return img;
    }
    let n = optics.samples_per_side.max(1);
    let kernel = gaussian_kernel(optics.psf_sigma_px * n as f64);
    let r = kernel.len() / 2;
    let scene = Surroundings::new(objects, light, pose, background);
    let (fw, fh) = (w * n, h * n);
    // fine sample (fx, fy) -> radiance, for fine coordinates clamped into the image
    let sample = |fx: usize, fy: usize| -> [f32; 3] {
        let px = (fx as f64 + 0.5) / n as f64;
        let py = (fy as f64 + 0.5) / n as f64;
        scene.radiance(&(scene.world_from_cam * k.ray(px, py)))
    };
    let norm = 1.0 / (n * n) as f32;
    img.data_mut()
        .par_chunks_mut(w * 3 * BAND_ROWS)
        .enumerate()
        .for_each(|(band, out)| {
            let y0 = band * BAND_ROWS;
            let rows = out.len() / (w * 3);
            // fine rows [fy0 - r, fy1 + r), clamped at the image edge
            let (fy0, fy1) = (y0 * n, (y0 + rows) * n);
            let lo = fy0.saturating_sub(r);
            let hi = (fy1 + r).min(fh);
            let clamp_y = |fy: isize| fy.clamp(0, fh as isize - 1) as usize;
            let mut fine: Vec<[f32; 3]> = Vec::with_capacity((hi - lo) * fw);
            for fy in lo..hi {
                for fx in 0..fw {
                    fine.push(sample(fx, fy));
                }
            }
            let at = |fx: isize, fy: isize| -> [f32; 3] {
                let fy = clamp_y(fy);
                let fx = fx.clamp(0, fw as isize - 1) as usize;
                fine[(fy - lo) * fw + fx]
            };
            // horizontal pass over the kept rows, vertical pass only where an output row needs it
            let mut horiz: Vec<[f32; 3]> = vec![[0.0; 3]; (hi - lo) * fw];
            for fy in lo..hi {
                for fx in 0..fw {
                    let mut acc = [0.0f32; 3];
                    for (j, &wk) in kernel.iter().enumerate() {
                        let v = at(fx as isize + j as isize - r as isize, fy as isize);
                        for c in 0..3 {
                            acc[c] += wk * v[c];
                        }
                    }
                    horiz[(fy - lo) * fw + fx] = acc;
                }
            }
            let hat = |fx: usize, fy: isize| horiz[(clamp_y(fy) - lo) * fw + fx];
            for (row, y) in out.chunks_mut(w * 3).zip(y0..) {
                for x in 0..w {
                    let mut acc = [0.0f32; 3];
                    for sy in 0..n {
                        let fy = (y * n + sy) as isize;
                        for sx in 0..n {
                            let fx = x * n + sx;
                            for (j, &wk) in kernel.iter().enumerate() {
                                let v = hat(fx, fy + j as isize - r as isize);
                                for c in 0..3 {
                                    acc[c] += wk * v[c];
                                }
                            }
                        }
                    }
                    for c in 0..3 {
                        row[3 * x + c] = acc[c] * norm;
                    }
                }
            }
        });
    img
}

/// A normalised Gaussian sampled at integer offsets out to three sigma (`[1.0]` for no blur).
fn gaussian_kernel(sigma: f64) -> Vec<f32> {
    if !(sigma.is_finite() && sigma > 0.0) {
        return vec![1.0];
    }
    let r = (3.0 * sigma).ceil() as i64;
    let raw: Vec<f64> = (-r..=r)
        .map(|i| (-0.5 * (i as f64 / sigma).powi(2)).exp())
        .collect();
    let sum: f64 = raw.iter().sum();
    raw.iter().map(|v| (v / sum) as f32).collect()
}

/// What one camera ray sees: the objects, the light, and what a coat mirrors.
struct Surroundings<'s, 'a> {
    objects: &'s [SceneObject<'a>],
    light: &'s DirectionalLight,
    origin: Point3<f64>,
    world_from_cam: nalgebra::UnitQuaternion<f64>,
    /// The camera's optical axis in the world: mirrored rays along it meet the backdrop.
    forward: Vector3<f64>,
    background: [f32; 3],
}

impl<'s, 'a> Surroundings<'s, 'a> {
    fn new(
        objects: &'s [SceneObject<'a>],
        light: &'s DirectionalLight,
        pose: &Pose,
        background: [f32; 3],
    ) -> Self {
        let world_from_cam = pose.rotation.inverse();
        Self {
            objects,
            light,
            origin: pose.centre(),
            world_from_cam,
            forward: world_from_cam * Vector3::z(),
            background,
        }
    }

    fn radiance(&self, dir: &Vector3<f64>) -> [f32; 3] {
        let Some((t, n, obj)) = nearest(self.objects, &self.origin, dir) else {
            return self.background;
        };
        let mut rgb = shade_hit(self.objects, self.light, &self.origin, dir, t, &n, obj);
        if let Some(f0) = obj.coat_f0 {
            let cos_o = n.dot(&-dir);
            if cos_o > 0.0 {
                let f = f0 + (1.0 - f0) * (1.0 - cos_o).powi(5);
                let mirrored = dir + n * (2.0 * cos_o);
                let p = self.origin + dir * t + n * (1e-9 * t.max(1.0));
                let sees_backdrop = mirrored.dot(&self.forward) > 0.0
                    && nearest(self.objects, &p, &mirrored).is_none();
                let env = if sees_backdrop {
                    self.background
                } else {
                    [0.0; 3]
                };
                // the coat passes (1 - F) of what lies beneath it
                for c in 0..3 {
                    rgb[c] = ((1.0 - f) * f64::from(rgb[c]) + f * f64::from(env[c])) as f32;
                }
            }
        }
        rgb
    }
}

/// Radiance along one camera ray from the light alone, no coat (`None` when it hits nothing).
pub fn shade_ray(
    objects: &[SceneObject<'_>],
    light: &DirectionalLight,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
) -> Option<[f32; 3]> {
    let (t, n, obj) = nearest(objects, origin, dir)?;
    Some(shade_hit(objects, light, origin, dir, t, &n, obj))
}

fn shade_hit(
    objects: &[SceneObject<'_>],
    light: &DirectionalLight,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    t: f64,
    n: &Vector3<f64>,
    obj: &SceneObject<'_>,
) -> [f32; 3] {
    let p = origin + dir * t;
    let frame = ShadingFrame::new(*n);
    let wo = frame.to_local(&-dir);
    let wi = frame.to_local(&light.to_light);
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return [0.0; 3];
    }
    // shadow ray, offset relative to the distance travelled (scenes have no fixed scale)
    let shadow_origin = p + n * (1e-9 * t.max(1.0));
    if nearest(objects, &shadow_origin, &light.to_light).is_some() {
        return [0.0; 3];
    }
    let fr = obj.brdf.eval_local(&wi, &wo);
    std::array::from_fn(|c| (fr[c] * light.irradiance[c] * wi.z) as f32)
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
