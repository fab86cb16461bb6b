//! The sphere as the camera sees it: the cone of rays tangent to it, fitted to edge rays or
//! given as a circle.
//!
//! Conventions: as `calib::sphere` (camera axes, unit rays, radians). Pure: no I/O.

use super::SphereError;
use crate::geometry::camera::Intrinsics;
use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use std::f64::consts::PI;

/// Where an outline came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutlineSource {
    Detected,
    UserCircle,
}

/// The sphere seen from the camera: the cone of rays tangent to it.
#[derive(Clone, Debug, PartialEq)]
pub struct SphereOutline {
    /// Unit direction from the camera centre to the sphere centre.
    pub centre_dir: Vector3<f64>,
    /// Half-angle of the tangent cone: `sin(alpha) = radius / distance`.
    pub angular_radius_rad: f64,
    /// Projection of the sphere centre (not the centre of the outline ellipse).
    pub centre_px: [f64; 2],
    /// Mean outline radius in pixels (for tolerances and messages).
    pub radius_px: f64,
    /// Edge points kept by the fit.
    pub edge_points: usize,
    /// RMS angular distance of the edge rays from the fitted cone.
    pub rms_residual_rad: f64,
    pub source: OutlineSource,
}

impl SphereOutline {
    /// The sphere centre in camera axes, in units of the sphere radius.
    pub fn centre_in_radii(&self) -> Vector3<f64> {
        self.centre_dir / self.angular_radius_rad.sin()
    }

    /// The first intersection of a camera ray (unit) with the sphere: `(point, normal)` with the
    /// point in units of the sphere radius; `None` when the ray misses.
    pub fn intersect(&self, ray: &Vector3<f64>) -> Option<(Vector3<f64>, Vector3<f64>)> {
        let c = self.centre_in_radii();
        let b = ray.dot(&c);
        let disc = b * b - (c.norm_squared() - 1.0);
        if disc < 0.0 {
            return None;
        }
        let p = ray * (b - disc.sqrt());
        Some((p, (p - c).normalize()))
    }

    /// True when the ray through pixel `(px, py)` hits the sphere.
    pub fn contains_pixel(&self, intr: &Intrinsics, px: f64, py: f64) -> bool {
        intr.ray(px, py).dot(&self.centre_dir) > self.angular_radius_rad.cos()
    }

    /// Fits the cone to edge rays (unit, camera axes) with outlier rejection.
    pub fn from_edge_rays(rays: &[Vector3<f64>], intr: &Intrinsics) -> Option<Self> {
        let mut kept: Vec<Vector3<f64>> = rays.to_vec();
        let mut fit = fit_cone(&kept)?;
        for _ in 0..3 {
            let res: Vec<f64> = kept.iter().map(|r| r.dot(&fit.0) - fit.1).collect();
            let mut sorted = res.clone();
            let med = crate::stats::median(&mut sorted)?;
            let sigma = crate::calib::robust::mad_sigma(&res, med)?;
            let tol = (4.0 * sigma).max(1e-12);
            let next: Vec<Vector3<f64>> = kept
                .iter()
                .zip(&res)
                .filter(|(_, e)| (*e - med).abs() <= tol)
                .map(|(r, _)| *r)
                .collect();
            if next.len() == kept.len() || next.len() < 6 {
                break;
            }
            kept = next;
            fit = fit_cone(&kept)?;
        }
        let (d, cos_a) = fit;
        if !(cos_a > 0.0 && cos_a < 1.0) {
            return None;
        }
        let alpha = cos_a.acos();
        let rms = (kept
            .iter()
            .map(|r| (r.dot(&d).clamp(-1.0, 1.0).acos() - alpha).powi(2))
            .sum::<f64>()
            / kept.len() as f64)
            .sqrt();
        let (cpx, cpy) = intr.project(&d)?;
        Some(Self {
            centre_dir: d,
            angular_radius_rad: alpha,
            centre_px: [cpx, cpy],
            radius_px: alpha.tan() * 0.5 * (intr.fx + intr.fy),
            edge_points: kept.len(),
            rms_residual_rad: rms,
            source: OutlineSource::Detected,
        })
    }

    /// An outline the user gives as a circle in the image (centre and radius in pixels). Under
    /// perspective the true outline is slightly elliptical; the cone through the circle is the
    /// best a circle can say.
    pub fn from_circle(
        cx: f64,
        cy: f64,
        radius_px: f64,
        intr: &Intrinsics,
    ) -> Result<Self, SphereError> {
        if !(cx.is_finite() && cy.is_finite() && radius_px.is_finite() && radius_px > 1.0) {
            return Err(SphereError::InvalidCircle {
                reason: format!(
                    "centre ({cx}, {cy}) radius {radius_px}: need finite values and a radius above 1 px"
                ),
            });
        }
        let (w, h) = (intr.width as f64, intr.height as f64);
        if cx - radius_px < 0.0 || cy - radius_px < 0.0 || cx + radius_px > w || cy + radius_px > h
        {
            return Err(SphereError::SphereCut {
                cx,
                cy,
                radius_px,
                width: intr.width,
                height: intr.height,
            });
        }
        let rays: Vec<Vector3<f64>> = (0..180)
            .map(|i| {
                let a = i as f64 * 2.0 * PI / 180.0;
                intr.ray(cx + radius_px * a.cos(), cy + radius_px * a.sin())
            })
            .collect();
        let mut o =
            Self::from_edge_rays(&rays, intr).ok_or_else(|| SphereError::InvalidCircle {
                reason: "the circle does not back-project to a cone in front of the camera".into(),
            })?;
        o.source = OutlineSource::UserCircle;
        Ok(o)
    }
}

/// Total-least-squares plane through the ray tips: `(d, cos_alpha)` with `d` pointing forward.
fn fit_cone(rays: &[Vector3<f64>]) -> Option<(Vector3<f64>, f64)> {
    if rays.len() < 5 {
        return None;
    }
    let n = rays.len() as f64;
    let mean = rays.iter().fold(Vector3::zeros(), |a, r| a + r) / n;
    let mut cov = Matrix3::zeros();
    for r in rays {
        let d = r - mean;
        cov += d * d.transpose();
    }
    let eig = SymmetricEigen::new(cov);
    let (imin, _) = eig
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))?;
    let mut d: Vector3<f64> = eig.eigenvectors.column(imin).into_owned();
    if d.dot(&mean) < 0.0 {
        d = -d;
    }
    let d = d.normalize();
    Some((d, d.dot(&mean)))
}

/// The tangent ray of the outline cone at azimuth `a` around its axis.
pub(super) fn tangent_ray(o: &SphereOutline, a: f64) -> Vector3<f64> {
    let d = o.centre_dir;
    let helper = if d.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e1 = d.cross(&helper).normalize();
    let e2 = d.cross(&e1);
    let (s, c) = o.angular_radius_rad.sin_cos();
    (d * c + (e1 * a.cos() + e2 * a.sin()) * s).normalize()
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    /// Exact tangent rays of a known sphere: the cone fit must return its centre and size.
    #[test]
    fn cone_fit_recovers_sphere_from_exact_tangent_rays() {
        let intr = Intrinsics::pinhole(320, 240, 300.0, 300.0, 160.0, 120.0);
        let centre = Vector3::<f64>::new(0.3, -0.2, 2.0);
        let radius: f64 = 0.25;
        let d = centre.normalize();
        let alpha = (radius / centre.norm()).asin();
        let truth = SphereOutline {
            centre_dir: d,
            angular_radius_rad: alpha,
            centre_px: [0.0; 2],
            radius_px: 0.0,
            edge_points: 0,
            rms_residual_rad: 0.0,
            source: OutlineSource::Detected,
        };
        let rays: Vec<_> = (0..50)
            .map(|i| tangent_ray(&truth, i as f64 * 0.13))
            .collect();
        // every ray is tangent: it meets the sphere at exactly one point
        for r in &rays {
            let b = r.dot(&centre);
            assert!((b * b - centre.norm_squared() + radius * radius).abs() < 1e-12);
        }
        let fit = SphereOutline::from_edge_rays(&rays, &intr).unwrap();
        assert!((fit.centre_dir - d).norm() < 1e-12);
        assert!((fit.angular_radius_rad - alpha).abs() < 1e-12);
        let (px, py) = intr.project(&centre).unwrap();
        assert!((fit.centre_px[0] - px).abs() < 1e-9 && (fit.centre_px[1] - py).abs() < 1e-9);
        // the normal at the centre pixel faces the camera
        let (_, n) = fit.intersect(&d).unwrap();
        assert!((n + d).norm() < 1e-12);
    }

    #[test]
    fn user_circle_outside_the_frame_is_cut() {
        let intr = Intrinsics::pinhole(100, 100, 100.0, 100.0, 50.0, 50.0);
        assert!(matches!(
            SphereOutline::from_circle(10.0, 50.0, 20.0, &intr),
            Err(SphereError::SphereCut { .. })
        ));
        assert!(matches!(
            SphereOutline::from_circle(50.0, 50.0, f64::NAN, &intr),
            Err(SphereError::InvalidCircle { .. })
        ));
        let o = SphereOutline::from_circle(50.0, 50.0, 20.0, &intr).unwrap();
        assert!((o.centre_px[0] - 50.0).abs() < 1e-6 && (o.radius_px - 20.0).abs() < 0.5);
    }
}
