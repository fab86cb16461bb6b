//! The sphere probe: a BRDF judged as images see it. An orthographic sphere is rendered with
//! the BRDF under a fixed set of novel directional lights and under the standard environment
//! (`render::environment`), and two renders are compared as images (relative L2 of the linear
//! values, and PSNR after a fixed tone map). docs/error-metrics.md, "Rendered errors".
//!
//! Frame: the view frame, x right, y up, z towards the viewer; the view direction is +z for
//! every pixel (orthographic). Pixel `(x, y)` of a `size x size` image (row 0 at the top) sees
//! the unit sphere at `(2 (x + 0.5) / size - 1, 1 - 2 (y + 0.5) / size)`; only pixels whose
//! centre lies inside the disc are rendered, and they are what the errors sum over.
//!
//! The BRDF is seen only through its values at MERL bins (`BinValues`), like every error in
//! `brdf::metrics`, so a table, a network, a basis reconstruction and an analytic fit are
//! compared on equal terms. The environment integral at a pixel is a fixed quadrature over the
//! half vector: `theta_h` at the centre of each of the 90 MERL `theta_h` bins (square-root
//! spacing, so the specular peak is resolved exactly as finely as the table resolves it),
//! `phi_h` on `phi_h_steps` even steps; `wi` is `wo` mirrored about `h`, with the Jacobian
//! `d omega_i = 4 (wo . h) d omega_h`. Everything that does not depend on the BRDF (the bin and
//! the weight `L_env(wi) cos theta_i d omega_i` of every sample) is computed once, so a render is
//! a gather over the bins. Pure.

use super::environment::Environment;
use super::frame::ShadingFrame;
use super::image::LinearImage;
use super::light::DirectionalLight;
use crate::brdf::BinValues;
use crate::brdf::coords::{THETA_H_BINS, merl_index};
use nalgebra::Vector3;
use rayon::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// Resolution of the probe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeSettings {
    /// Image side, pixels.
    pub size: usize,
    /// Steps of the half vector's azimuth in the environment quadrature.
    pub phi_h_steps: usize,
}

impl Default for ProbeSettings {
    fn default() -> Self {
        Self {
            size: 40,
            phi_h_steps: 24,
        }
    }
}

/// The novel directional lights of every rendered score (view frame, unit irradiance): near
/// the view, from the upper left, low from the right, behind the sphere (rim light: large
/// `theta_d`), from below left.
pub fn standard_lights() -> Vec<DirectionalLight> {
    [
        (0.3, 0.4, 1.0),
        (-1.0, 0.5, 0.8),
        (1.0, -0.2, 0.3),
        (0.2, 1.0, -0.4),
        (-0.4, -0.8, 0.6),
    ]
    .iter()
    .filter_map(|&(x, y, z)| DirectionalLight::new(Vector3::new(x, y, z), [1.0; 3]))
    .collect()
}

/// A probe: the geometry and quadrature of every render, precomputed.
pub struct SphereProbe {
    settings: ProbeSettings,
    /// Pixel `(x, y)` of each rendered (disc) pixel.
    pixels: Vec<(u32, u32)>,
    /// Distinct MERL bins any render reads, sorted.
    bins: Vec<usize>,
    /// Per light, per pixel: the slot of its bin in `bins` and `E cos theta_i`, if lit.
    lights: Vec<Vec<Option<LitPixel>>>,
    /// Environment samples of pixel `p`: `env[env_start[p]..env_start[p + 1]]`.
    env_start: Vec<usize>,
    env: Vec<(u32, [f32; 3])>,
}

/// The renders of one BRDF, per disc pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeRenders {
    pub lights: Vec<Vec<[f64; 3]>>,
    pub environment: Vec<[f64; 3]>,
}

/// How two BRDFs differ as rendered images.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RenderedErrors {
    /// Relative L2 error of the linear environment render (the headline number).
    pub environment: f64,
    /// Relative L2 error over the directional-light renders, all lights together.
    pub lights: f64,
    /// PSNR of the environment render after the fixed tone map, dB.
    pub environment_psnr_db: f64,
    /// Mean PSNR of the directional-light renders after the fixed tone map, dB.
    pub lights_psnr_db: f64,
}

impl SphereProbe {
    /// Builds the probe for the standard lights and environment.
    pub fn standard(settings: ProbeSettings) -> Self {
        Self::new(settings, &standard_lights(), &Environment::standard())
    }

    /// [`Self::standard`] made on the calling thread alone: what a process-wide `OnceLock`
    /// must use. A rayon worker that runs parallel work inside the initialiser may, while it
    /// waits for that work, take another task that asks for the same lock, and then waits for
    /// itself (a deadlock seen in the tests).
    pub fn standard_serial(settings: ProbeSettings) -> Self {
        Self::build(
            settings,
            &standard_lights(),
            &Environment::standard(),
            false,
        )
    }

    pub fn new(settings: ProbeSettings, lights: &[DirectionalLight], env: &Environment) -> Self {
        Self::build(settings, lights, env, true)
    }

    fn build(
        settings: ProbeSettings,
        lights: &[DirectionalLight],
        env: &Environment,
        parallel: bool,
    ) -> Self {
        let size = settings.size.max(2);
        let pixels: Vec<(u32, u32)> = (0..size * size)
            .filter_map(|i| {
                let (x, y) = (i % size, i / size);
                let (px, py) = pixel_position(size, x, y);
                (px * px + py * py < 1.0).then_some((x as u32, y as u32))
            })
            .collect();
        let v = Vector3::z();
        // Per pixel: light samples and environment samples, with bins as MERL indices.
        type PixelSamples = (Vec<Option<(usize, [f64; 3])>>, Vec<(usize, [f64; 3])>);
        let samples = |&(x, y): &(u32, u32)| -> PixelSamples {
            let (px, py) = pixel_position(size, x as usize, y as usize);
            let n = Vector3::new(px, py, (1.0 - px * px - py * py).max(0.0).sqrt());
            let frame = ShadingFrame::new(n);
            let wo = frame.to_local(&v);
            let lit = lights
                .iter()
                .map(|l| {
                    let wi = frame.to_local(&l.to_light);
                    (wi.z > 0.0 && wo.z > 0.0)
                        .then(|| (merl_index(&wi, &wo), l.irradiance.map(|e| e * wi.z)))
                })
                .collect();
            (
                lit,
                environment_samples(&frame, &wo, env, settings.phi_h_steps),
            )
        };
        let per_pixel: Vec<PixelSamples> = if parallel {
            pixels.par_iter().map(samples).collect()
        } else {
            pixels.iter().map(samples).collect()
        };
        let mut bins: Vec<usize> = per_pixel
            .iter()
            .flat_map(|(lit, envs)| {
                lit.iter()
                    .flatten()
                    .map(|s| s.0)
                    .chain(envs.iter().map(|s| s.0))
            })
            .collect();
        bins.sort_unstable();
        bins.dedup();
        let slot = |b: usize| bins.binary_search(&b).unwrap_or(0) as u32;
        let to_f32 = |w: [f64; 3]| w.map(|x| x as f32);
        let mut light_samples = vec![Vec::with_capacity(pixels.len()); lights.len()];
        let mut env_start = Vec::with_capacity(pixels.len() + 1);
        let mut env_samples = Vec::new();
        for (lit, envs) in &per_pixel {
            for (li, s) in lit.iter().enumerate() {
                light_samples[li].push(s.map(|(b, w)| (slot(b), to_f32(w))));
            }
            env_start.push(env_samples.len());
            env_samples.extend(envs.iter().map(|&(b, w)| (slot(b), to_f32(w))));
        }
        env_start.push(env_samples.len());
        Self {
            settings: ProbeSettings { size, ..settings },
            pixels,
            bins,
            lights: light_samples,
            env_start,
            env: env_samples,
        }
    }

    /// The MERL bins a render reads (a caller may tabulate a BRDF at just these).
    pub fn bins(&self) -> &[usize] {
        &self.bins
    }

    /// Number of rendered (disc) pixels.
    pub fn pixel_count(&self) -> usize {
        self.pixels.len()
    }

    /// Renders a BRDF known at MERL bins. Non-finite values render as zero.
    pub fn render(&self, brdf: &dyn BinValues) -> ProbeRenders {
        let values: Vec<[f64; 3]> = brdf
            .values_at(&self.bins)
            .into_iter()
            .map(|v| v.map(|x| if x.is_finite() { x } else { 0.0 }))
            .collect();
        self.render_values(&values)
    }

    /// Renders from values at [`Self::bins`] (same order).
    pub fn render_values(&self, values: &[[f64; 3]]) -> ProbeRenders {
        let get = |slot: u32| values.get(slot as usize).copied().unwrap_or([0.0; 3]);
        let lights = self
            .lights
            .iter()
            .map(|per_pixel| {
                per_pixel
                    .iter()
                    .map(|s| match s {
                        Some((slot, w)) => {
                            let f = get(*slot);
                            [0, 1, 2].map(|c| f[c] * f64::from(w[c]))
                        }
                        None => [0.0; 3],
                    })
                    .collect()
            })
            .collect();
        let environment = (0..self.pixels.len())
            .into_par_iter()
            .map(|p| {
                let mut acc = [0.0; 3];
                for (slot, w) in &self.env[self.env_start[p]..self.env_start[p + 1]] {
                    let f = get(*slot);
                    for c in 0..3 {
                        acc[c] += f[c] * f64::from(w[c]);
                    }
                }
                acc
            })
            .collect();
        ProbeRenders {
            lights,
            environment,
        }
    }

    /// A render as a `size x size` image (black outside the disc), for reports.
    pub fn image(&self, values: &[[f64; 3]]) -> LinearImage {
        let size = self.settings.size;
        let mut img = LinearImage::new(size, size);
        for (&(x, y), v) in self.pixels.iter().zip(values) {
            img.set(x as usize, y as usize, v.map(|c| c as f32));
        }
        img
    }
}

/// A lit pixel under a light: the slot of its bin in `bins`, and `E cos theta_i`.
type LitPixel = (u32, [f32; 3]);

/// The pixel's position on the unit disc (y up).
fn pixel_position(size: usize, x: usize, y: usize) -> (f64, f64) {
    let s = size as f64;
    (
        2.0 * (x as f64 + 0.5) / s - 1.0,
        1.0 - 2.0 * (y as f64 + 0.5) / s,
    )
}

/// The half-vector quadrature about a direction `w` above the surface: `theta_h` at the 90 MERL
/// bin centres (`theta_h = u^2 pi / 2`, so `d theta_h = u pi du`, `du = 1 / 90`), `phi_h` in
/// `phi_steps` steps; for each half vector `h`, the mirror of `w` about `h` and its solid angle
/// `d omega = 4 (w . h) sin theta_h d theta_h d phi_h`. Mirrors below the horizon are left out.
pub fn mirror_quadrature(w: &Vector3<f64>, phi_steps: usize) -> Vec<(Vector3<f64>, f64)> {
    let phi_steps = phi_steps.max(1);
    let d_phi = TAU / phi_steps as f64;
    let mut out = Vec::with_capacity(THETA_H_BINS * phi_steps);
    for i in 0..THETA_H_BINS {
        let u = (i as f64 + 0.5) / THETA_H_BINS as f64;
        let theta_h = u * u * FRAC_PI_2;
        let d_theta = u * PI / THETA_H_BINS as f64;
        let (st, ct) = theta_h.sin_cos();
        for j in 0..phi_steps {
            let phi = (j as f64 + 0.5) * d_phi;
            let h = Vector3::new(st * phi.cos(), st * phi.sin(), ct);
            let w_h = w.dot(&h);
            if w_h <= 0.0 {
                continue;
            }
            let m = 2.0 * w_h * h - w;
            if m.z <= 0.0 {
                continue;
            }
            out.push((m, 4.0 * w_h * st * d_theta * d_phi));
        }
    }
    out
}

/// The environment quadrature of one pixel (see the module header): `(bin, L cos_i d omega_i)`.
fn environment_samples(
    frame: &ShadingFrame,
    wo: &Vector3<f64>,
    env: &Environment,
    phi_steps: usize,
) -> Vec<(usize, [f64; 3])> {
    if wo.z <= 0.0 {
        return Vec::new();
    }
    mirror_quadrature(wo, phi_steps)
        .into_iter()
        .map(|(wi, d_omega_i)| {
            let l = env.radiance(&frame.to_world(&wi));
            (merl_index(&wi, wo), l.map(|x| x * wi.z * d_omega_i))
        })
        .collect()
}

/// Relative L2 error of `rec` against `truth` over every pixel and channel.
fn relative_l2<'a>(
    truth: impl Iterator<Item = &'a [f64; 3]>,
    rec: impl Iterator<Item = &'a [f64; 3]>,
) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (t, r) in truth.zip(rec) {
        for c in 0..3 {
            num += (t[c] - r[c]).powi(2);
            den += t[c] * t[c];
        }
    }
    if den > 0.0 {
        (num / den).sqrt()
    } else {
        f64::NAN
    }
}

/// PSNR after the fixed tone map: exposure so the truth's 99th-percentile channel value maps
/// to 1, clamp to [0, 1], gamma 1/2.2; peak 1.
fn psnr_db(truth: &[[f64; 3]], rec: &[[f64; 3]]) -> f64 {
    let mut vals: Vec<f64> = truth.iter().flatten().copied().collect();
    if vals.is_empty() {
        return f64::NAN;
    }
    vals.sort_by(f64::total_cmp);
    let p99 = vals[((vals.len() - 1) as f64 * 0.99).round() as usize];
    if p99 <= 0.0 {
        return f64::NAN;
    }
    let tone = |x: f64| (x / p99).clamp(0.0, 1.0).powf(1.0 / 2.2);
    let mut se = 0.0;
    let mut n = 0usize;
    for (t, r) in truth.iter().zip(rec) {
        for c in 0..3 {
            se += (tone(t[c]) - tone(r[c])).powi(2);
            n += 1;
        }
    }
    let mse = se / n as f64;
    if mse <= 0.0 {
        return f64::INFINITY;
    }
    -10.0 * mse.log10()
}

/// Compares two renders made by the same probe.
pub fn compare(truth: &ProbeRenders, rec: &ProbeRenders) -> RenderedErrors {
    let environment = relative_l2(truth.environment.iter(), rec.environment.iter());
    let lights = relative_l2(truth.lights.iter().flatten(), rec.lights.iter().flatten());
    let psnrs: Vec<f64> = truth
        .lights
        .iter()
        .zip(&rec.lights)
        .map(|(t, r)| psnr_db(t, r))
        .filter(|p| !p.is_nan())
        .collect();
    RenderedErrors {
        environment,
        lights,
        environment_psnr_db: psnr_db(&truth.environment, &rec.environment),
        lights_psnr_db: if psnrs.is_empty() {
            f64::NAN
        } else {
            psnrs.iter().sum::<f64>() / psnrs.len() as f64
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::coords::MerlBin;

    /// A constant BRDF at every bin.
    struct Constant([f64; 3]);
    impl BinValues for Constant {
        fn values_at(&self, bins: &[usize]) -> Vec<[f64; 3]> {
            vec![self.0; bins.len()]
        }
    }

    /// A peak in the first 20 theta_h bins (theta_h < 4.4 degrees).
    struct Peak;
    impl BinValues for Peak {
        fn values_at(&self, bins: &[usize]) -> Vec<[f64; 3]> {
            bins.iter()
                .map(|&b| {
                    let m = MerlBin::from_index(b).expect("bin");
                    if m.theta_h < 20 { [100.0; 3] } else { [0.1; 3] }
                })
                .collect()
        }
    }

    #[test]
    fn a_lambertian_sphere_in_a_uniform_environment_shows_its_albedo() {
        let env = Environment {
            horizon: [1.0; 3],
            zenith: [1.0; 3],
            ground: [1.0; 3],
            windows: vec![],
        };
        let light = DirectionalLight::new(Vector3::new(0.0, 0.0, 1.0), [2.0; 3]).unwrap();
        let probe = SphereProbe::new(
            ProbeSettings {
                size: 24,
                phi_h_steps: 24,
            },
            &[light],
            &env,
        );
        let albedo = 0.6;
        let r = probe.render(&Constant([albedo / PI; 3]));
        // Uniform radiance 1 over the hemisphere: radiance albedo, at every pixel, whatever the
        // normal (the quadrature covers every incident direction once).
        for v in &r.environment {
            assert!((v[0] - albedo).abs() < 0.01 * albedo, "{v:?}");
        }
        // Light along the view: radiance albedo E cos / pi, cos = n.z.
        let (x, y) = probe.pixels[probe.pixel_count() / 2];
        let (px, py) = pixel_position(24, x as usize, y as usize);
        let nz = (1.0 - px * px - py * py).sqrt();
        let v = r.lights[0][probe.pixel_count() / 2];
        // (weights are stored as f32)
        let want = albedo * 2.0 * nz / PI;
        assert!((v[0] - want).abs() < 1e-6 * want, "{v:?} {want}");
    }

    #[test]
    fn errors_are_zero_for_the_same_brdf_and_scale_with_a_uniform_error() {
        let probe = SphereProbe::standard(ProbeSettings {
            size: 16,
            phi_h_steps: 12,
        });
        let t = probe.render(&Peak);
        let same = compare(&t, &probe.render(&Peak));
        assert_eq!(same.environment, 0.0);
        assert_eq!(same.lights, 0.0);
        assert!(same.environment_psnr_db.is_infinite());
        // f scaled by 1.2 everywhere: every relative error is exactly 0.2.
        struct Scaled;
        impl BinValues for Scaled {
            fn values_at(&self, bins: &[usize]) -> Vec<[f64; 3]> {
                Peak.values_at(bins)
                    .into_iter()
                    .map(|v| v.map(|x| 1.2 * x))
                    .collect()
            }
        }
        let e = compare(&t, &probe.render(&Scaled));
        assert!((e.environment - 0.2).abs() < 1e-9, "{e:?}");
        assert!((e.lights - 0.2).abs() < 1e-9, "{e:?}");
        assert!(e.environment_psnr_db.is_finite() && e.environment_psnr_db > 10.0);
        // A zero BRDF scores 1.
        let z = compare(&t, &probe.render(&Constant([0.0; 3])));
        assert!((z.environment - 1.0).abs() < 1e-12);
        // The peak is seen: flattening it changes both renders.
        let flat = compare(&t, &probe.render(&Constant([0.1; 3])));
        assert!(flat.environment > 0.05 && flat.lights > 0.05, "{flat:?}");
    }

    #[test]
    fn the_image_places_the_disc_in_the_frame() {
        let probe = SphereProbe::standard(ProbeSettings {
            size: 8,
            phi_h_steps: 4,
        });
        let r = probe.render(&Constant([0.3; 3]));
        let img = probe.image(&r.environment);
        assert_eq!((img.width(), img.height()), (8, 8));
        assert_eq!(img.get(0, 0), [0.0; 3]);
        assert!(img.get(4, 4)[0] > 0.0);
    }
}
