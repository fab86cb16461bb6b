//! Synthetic calibration images with known truth: a perspective-rendered glossy black sphere
//! under a directional light (or ambient light), and a Lambertian white board. Rendered by
//! supersampled ray casting with the pinhole model of `geometry::camera`, independent of the
//! calibration code; seeded Gaussian noise and optional clipping.

#![allow(dead_code)]

use brdf_rig::geometry::camera::Intrinsics;
use brdf_rig::render::image::LinearImage;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;

/// Seeded Gaussian noise: `sigma = abs + rel * value`, then clipping at `saturation`.
#[derive(Clone, Copy, Debug)]
pub struct Noise {
    pub abs: f64,
    pub rel: f64,
    pub saturation: Option<f32>,
}

impl Noise {
    pub fn apply(&self, img: &mut LinearImage, seed: u64) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for v in img.data_mut() {
            let sigma = self.abs + self.rel * (*v as f64).abs();
            let mut x = *v as f64 + sigma * gauss(&mut rng);
            if let Some(s) = self.saturation {
                x = x.min(s as f64);
            }
            *v = x.max(0.0) as f32;
        }
    }
}

pub fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = rng.r#gen::<f64>().max(1e-300);
    let u2: f64 = rng.r#gen();
    (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
}

/// A random unit vector at an angle in `[min_deg, max_deg]` from `axis`.
pub fn random_dir_around(
    rng: &mut ChaCha8Rng,
    axis: &Vector3<f64>,
    min_deg: f64,
    max_deg: f64,
) -> Vector3<f64> {
    let a = axis.normalize();
    let helper = if a.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e1 = a.cross(&helper).normalize();
    let e2 = a.cross(&e1);
    let theta = rng.gen_range(min_deg..=max_deg).to_radians();
    let phi = rng.gen_range(0.0..2.0 * PI);
    (a * theta.cos() + (e1 * phi.cos() + e2 * phi.sin()) * theta.sin()).normalize()
}

/// Schlick's Fresnel reflectance of a dielectric with F0 = 0.04 (black glossy plastic).
pub fn schlick(cos: f64) -> f64 {
    0.04 + 0.96 * (1.0 - cos.clamp(0.0, 1.0)).powi(5)
}

/// Casts `ss x ss` rays per pixel and averages `shade(ray, x, y)` (rows in parallel).
fn render(
    intr: &Intrinsics,
    ss: usize,
    shade: impl Fn(&Vector3<f64>, f64, f64) -> [f64; 3] + Sync,
) -> LinearImage {
    use rayon::prelude::*;
    let mut img = LinearImage::new(intr.width, intr.height);
    let inv = 1.0 / (ss * ss) as f64;
    let w = intr.width;
    img.data_mut()
        .par_chunks_mut(3 * w)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, out) in row.chunks_exact_mut(3).enumerate() {
                let mut acc = [0.0; 3];
                for j in 0..ss {
                    for i in 0..ss {
                        let px = x as f64 + (i as f64 + 0.5) / ss as f64;
                        let py = y as f64 + (j as f64 + 0.5) / ss as f64;
                        // with lens distortion the pixel's ray goes through the camera model's
                        // undistortion (itself tested by a round trip in geometry::camera)
                        let ray = if intr.has_distortion() {
                            intr.ray(px, py)
                        } else {
                            Vector3::new((px - intr.cx) / intr.fx, (py - intr.cy) / intr.fy, 1.0)
                                .normalize()
                        };
                        let c = shade(&ray, px, py);
                        for k in 0..3 {
                            acc[k] += c[k] * inv;
                        }
                    }
                }
                for k in 0..3 {
                    out[k] = acc[k] as f32;
                }
            }
        });
    img
}

/// A glossy black sphere (weak Lambertian term plus a Blinn-Phong lobe) before a backdrop.
#[derive(Clone, Debug)]
pub struct SphereScene {
    pub intr: Intrinsics,
    /// Sphere centre in camera axes, metres.
    pub centre: Vector3<f64>,
    pub radius: f64,
    /// Unit vector towards the light, camera axes.
    pub light_dir: Vector3<f64>,
    pub irradiance: [f64; 3],
    /// Peak specular radiance per unit irradiance (at n = h).
    pub specular: f64,
    pub exponent: f64,
    pub diffuse_albedo: f64,
    /// Backdrop radiance in the light image (a lit backdrop makes the outline visible).
    pub backdrop: f64,
    /// Backdrop radiance in the ambient image.
    pub ambient: f64,
    /// A second, weaker light: direction and strength relative to the main one.
    pub second_light: Option<(Vector3<f64>, f64)>,
    /// The lobe times `n.l / (n_h.l)` (a BRDF's radiance carries the light's cosine; equal to
    /// the plain lobe at the mirror normal `n_h`); off, the lobe is radiance as it is, one cosine
    /// off what the calibration assumes.
    pub lobe_cosine: bool,
    /// Fresnel reflection of the backdrop (Schlick, F0 = 0.04) in both images: a real glossy
    /// sphere's rim fades into the backdrop at grazing angles, which shrinks its apparent outline.
    pub fresnel_rim: bool,
    /// A dark post holding the sphere from below, its half-width as a fraction of the sphere's
    /// radius in the image (drawn in the image plane, behind the sphere).
    pub post: Option<f64>,
    pub noise: Noise,
    pub supersample: usize,
}

impl SphereScene {
    /// A 320x240 camera, the sphere off the optical axis, a clipped highlight.
    pub fn new(light_dir: Vector3<f64>) -> Self {
        Self {
            intr: Intrinsics::pinhole(320, 240, 520.0, 520.0, 161.3, 118.9),
            centre: Vector3::new(0.025, -0.012, 0.42),
            radius: 0.05,
            light_dir: light_dir.normalize(),
            irradiance: [1.0, 0.95, 0.9],
            specular: 40.0,
            exponent: 1500.0,
            diffuse_albedo: 0.03,
            backdrop: 0.25,
            ambient: 0.3,
            second_light: None,
            lobe_cosine: false,
            fresnel_rim: true,
            post: None,
            noise: Noise {
                abs: 0.004,
                rel: 0.01,
                saturation: Some(1.0),
            },
            supersample: 4,
        }
    }

    /// The direction from the sphere centre to the camera.
    pub fn view_axis(&self) -> Vector3<f64> {
        -self.centre.normalize()
    }

    /// The sphere's mirror normal for its light: `n = (l + v) / |l + v|` with `v` the view
    /// direction at the point of normal `n` (fixed point; perspective makes `v` depend on `n`).
    pub fn mirror_normal(&self) -> Vector3<f64> {
        let c = self.centre;
        let mut n = (self.light_dir - c.normalize()).normalize();
        for _ in 0..100 {
            let v = -(c + n * self.radius).normalize();
            n = (self.light_dir + v).normalize();
        }
        n
    }

    /// True where the post covers pixel position `(px, py)` (behind the sphere).
    fn on_post(&self, px: f64, py: f64) -> bool {
        let Some(f) = self.post else {
            return false;
        };
        let Some((cx, cy)) = self.intr.project(&self.centre) else {
            return false;
        };
        let r_px = self.intr.fx * self.radius / self.centre.norm();
        (px - cx).abs() < f * r_px && py > cy
    }

    fn hit(&self, ray: &Vector3<f64>) -> Option<Vector3<f64>> {
        let b = ray.dot(&self.centre);
        let disc = b * b - self.centre.norm_squared() + self.radius * self.radius;
        if disc < 0.0 {
            return None;
        }
        let p = ray * (b - disc.sqrt());
        Some((p - self.centre) / self.radius)
    }

    pub fn render_light(&self, seed: u64) -> LinearImage {
        let (w, _) = (self.intr.width as f64, self.intr.height as f64);
        let mut img = render(&self.intr, self.supersample, |ray, px, py| {
            let Some(n) = self.hit(ray) else {
                if self.on_post(px, py) {
                    return [0.01; 3];
                }
                let b = self.backdrop * (1.0 + 0.3 * (px / w - 0.5));
                return [b, b * 0.97, b * 0.94];
            };
            let v = -ray;
            let lobe = |l: &Vector3<f64>| {
                let h = (l + v).normalize();
                let cosine = if self.lobe_cosine {
                    n.dot(l).max(0.0) / h.dot(l).max(1e-6)
                } else {
                    1.0
                };
                self.specular * n.dot(&h).max(0.0).powf(self.exponent) * cosine
            };
            let mut s =
                self.diffuse_albedo / PI * n.dot(&self.light_dir).max(0.0) + lobe(&self.light_dir);
            if let Some((l2, k)) = &self.second_light {
                s += k * lobe(l2);
            }
            let mut rgb = self.irradiance.map(|e| e * s);
            if self.fresnel_rim {
                // the rim mirrors the lit backdrop just behind the silhouette
                let f = schlick(n.dot(&v));
                let b = self.backdrop * (1.0 + 0.3 * (px / w - 0.5));
                for (c, tint) in rgb.iter_mut().zip([1.0, 0.97, 0.94]) {
                    *c += f * b * tint;
                }
            }
            rgb
        });
        self.noise.apply(&mut img, seed);
        img
    }

    pub fn render_ambient(&self, seed: u64) -> LinearImage {
        let h = self.intr.height as f64;
        let mut img = render(&self.intr, self.supersample, |ray, px, py| {
            match self.hit(ray) {
                Some(n) => {
                    let cos = n.dot(&-ray).max(0.0);
                    let mut s = 0.02 + 0.03 * cos;
                    if self.fresnel_rim {
                        let f = schlick(cos);
                        s = s * (1.0 - f) + f * self.ambient * (1.0 + 0.3 * (py / h - 0.5));
                    }
                    [s; 3]
                }
                None if self.on_post(px, py) => [0.03; 3],
                None => [self.ambient * (1.0 + 0.3 * (py / h - 0.5)); 3],
            }
        });
        self.noise.apply(&mut img, seed);
        img
    }
}

/// A flat Lambertian board before a dark backdrop, under a directional light.
#[derive(Clone, Debug)]
pub struct BoardScene {
    pub intr: Intrinsics,
    pub centre: Vector3<f64>,
    /// Unit normal (towards the camera side).
    pub normal: Vector3<f64>,
    pub half_size: (f64, f64),
    pub albedo: [f64; 3],
    pub irradiance: [f64; 3],
    pub light_dir: Vector3<f64>,
    pub backdrop: f64,
    /// Relative fall-off of the radiance at the image corners (lens vignetting, uneven light).
    pub vignetting: f64,
    /// Pixels set to the clip level (glints) and to zero (dust), placed at random on the board.
    pub glints: usize,
    pub dust: usize,
    pub noise: Noise,
    pub supersample: usize,
}

impl BoardScene {
    pub fn new(light_dir: Vector3<f64>) -> Self {
        Self {
            intr: Intrinsics::pinhole(240, 180, 300.0, 300.0, 120.0, 90.0),
            centre: Vector3::new(0.0, 0.0, 0.8),
            normal: Vector3::new(0.15, -0.1, -1.0).normalize(),
            half_size: (0.15, 0.11),
            albedo: [0.95, 0.93, 0.9],
            irradiance: [2.0, 1.8, 1.5],
            light_dir: light_dir.normalize(),
            backdrop: 0.02,
            vignetting: 0.0,
            glints: 0,
            dust: 0,
            noise: Noise {
                abs: 0.004,
                rel: 0.01,
                saturation: Some(1.0),
            },
            supersample: 2,
        }
    }

    /// Radiance the board sends: `a E cos(theta) / pi`.
    pub fn radiance(&self) -> [f64; 3] {
        let cos = self.normal.dot(&self.light_dir).max(0.0);
        [0, 1, 2].map(|k| self.albedo[k] * self.irradiance[k] * cos / PI)
    }

    pub fn on_board(&self, ray: &Vector3<f64>) -> bool {
        let e1 = Vector3::y().cross(&self.normal).normalize();
        let e2 = self.normal.cross(&e1);
        let denom = ray.dot(&self.normal);
        if denom.abs() < 1e-9 {
            return false;
        }
        let t = self.centre.dot(&self.normal) / denom;
        let q = ray * t - self.centre;
        t > 0.0 && q.dot(&e1).abs() <= self.half_size.0 && q.dot(&e2).abs() <= self.half_size.1
    }

    pub fn render(&self, seed: u64) -> LinearImage {
        let l = self.radiance();
        let (w, h) = (self.intr.width as f64, self.intr.height as f64);
        let rmax2 = (w * w + h * h) / 4.0;
        let mut img = render(&self.intr, self.supersample, |ray, px, py| {
            if self.on_board(ray) {
                let r2 = (px - w / 2.0).powi(2) + (py - h / 2.0).powi(2);
                let f = 1.0 - self.vignetting * r2 / rmax2;
                l.map(|v| v * f)
            } else {
                [self.backdrop; 3]
            }
        });
        self.noise.apply(&mut img, seed);
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
        let sat = self.noise.saturation.unwrap_or(1.0);
        let mut placed = 0;
        while placed < self.glints + self.dust {
            let (x, y) = (
                rng.gen_range(0..self.intr.width),
                rng.gen_range(0..self.intr.height),
            );
            let ray = Vector3::new(
                (x as f64 + 0.5 - self.intr.cx) / self.intr.fx,
                (y as f64 + 0.5 - self.intr.cy) / self.intr.fy,
                1.0,
            )
            .normalize();
            if self.on_board(&ray) {
                let v = if placed < self.glints { sat } else { 0.0 };
                img.set(x, y, [v; 3]);
                placed += 1;
            }
        }
        img
    }
}
