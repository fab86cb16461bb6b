//! A procedural HDR environment for scoring BRDFs as images see them: a sky that brightens
//! towards the horizon, a dark ground, and three bright soft windows. It stands in for the
//! room or sky a recovered BRDF will be rendered under (docs/error-metrics.md, "Rendered
//! errors"); it is fixed and documented so that every figure made with it is comparable.
//!
//! Frame: the probe's view frame, x right, y up, z towards the viewer (`render::probe`).
//! Radiance is RGB, in the same unit as the irradiance of the probe's directional lights (a
//! window of peak radiance L and angular radius sigma gives an irradiance of about
//! `2 pi sigma^2 L` on a surface facing it).
//!
//! The windows are Gaussian lobes in angle (so the environment is smooth and every quadrature
//! sees them), placed so that their mirror images fall on a sphere seen from +z at different
//! places: upper left in front (warm), the right side a little behind (cool, reflected near the
//! limb), and high behind the sphere (the brightest and narrowest, reflected at grazing angles
//! at the top of the limb, where Fresnel matters). Pure.

use nalgebra::Vector3;

/// One soft window: a Gaussian lobe of radiance around a direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Window {
    /// Unit direction of the window's centre, probe frame.
    pub direction: Vector3<f64>,
    /// Peak radiance, RGB.
    pub radiance: [f64; 3],
    /// Angular standard deviation, radians.
    pub sigma: f64,
}

/// Sky, ground and windows (see the module header).
#[derive(Clone, Debug, PartialEq)]
pub struct Environment {
    /// Sky radiance at the horizon and at the zenith (+y), RGB.
    pub horizon: [f64; 3],
    pub zenith: [f64; 3],
    /// Radiance below the horizon.
    pub ground: [f64; 3],
    pub windows: Vec<Window>,
}

impl Environment {
    /// The fixed environment every rendered score uses.
    pub fn standard() -> Self {
        let dir = |x: f64, y: f64, z: f64| Vector3::new(x, y, z).normalize();
        Self {
            horizon: [0.9, 0.85, 0.8],
            zenith: [0.3, 0.42, 0.75],
            ground: [0.12, 0.1, 0.08],
            windows: vec![
                Window {
                    direction: dir(-0.5, 0.55, 0.65),
                    radiance: [24.0, 21.0, 17.0],
                    sigma: 12f64.to_radians(),
                },
                Window {
                    direction: dir(0.9, 0.15, -0.35),
                    radiance: [11.0, 13.0, 16.0],
                    sigma: 15f64.to_radians(),
                },
                Window {
                    direction: dir(0.1, 0.75, -0.65),
                    radiance: [60.0, 60.0, 60.0],
                    sigma: 7f64.to_radians(),
                },
            ],
        }
    }

    /// Radiance arriving from unit direction `w` (probe frame).
    pub fn radiance(&self, w: &Vector3<f64>) -> [f64; 3] {
        // Sky and ground blend over +-3 degrees of elevation, so the field is continuous.
        let t = smoothstep(-0.05, 0.05, w.y);
        let up = w.y.max(0.0).sqrt();
        let mut out = [0.0; 3];
        for (c, o) in out.iter_mut().enumerate() {
            let sky = self.horizon[c] * (1.0 - up) + self.zenith[c] * up;
            *o = self.ground[c] * (1.0 - t) + sky * t;
        }
        for win in &self.windows {
            let cos = win.direction.dot(w).clamp(-1.0, 1.0);
            let angle = cos.acos();
            let g = (-0.5 * (angle / win.sigma).powi(2)).exp();
            if g > 1e-12 {
                for (o, r) in out.iter_mut().zip(&win.radiance) {
                    *o += r * g;
                }
            }
        }
        out
    }
}

fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_are_bright_peaks_and_the_field_is_continuous_at_the_horizon() {
        let env = Environment::standard();
        for w in &env.windows {
            let at = env.radiance(&w.direction);
            // The peak adds the window's radiance to the sky under it.
            assert!(
                at[0] >= w.radiance[0] && at[0] < w.radiance[0] + 1.0,
                "{at:?}"
            );
        }
        let below = env.radiance(&Vector3::new(1.0, -1e-6, 0.0).normalize());
        let above = env.radiance(&Vector3::new(1.0, 1e-6, 0.0).normalize());
        for c in 0..3 {
            assert!((below[c] - above[c]).abs() < 1e-3, "{below:?} {above:?}");
        }
        let ground = env.radiance(&-Vector3::y());
        for c in 0..3 {
            assert!((ground[c] - env.ground[c]).abs() < 1e-6, "{ground:?}");
        }
        // Nothing is negative anywhere on a coarse sphere of directions.
        for i in 0..50 {
            for j in 0..50 {
                let th = std::f64::consts::PI * (i as f64 + 0.5) / 50.0;
                let ph = std::f64::consts::TAU * j as f64 / 50.0;
                let w = Vector3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin());
                assert!(env.radiance(&w).iter().all(|v| *v > 0.0));
            }
        }
    }
}
