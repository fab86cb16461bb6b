//! How far a light direction measured on one sphere image may lie from the truth: the error
//! model behind [`super::SphereLight::uncertainty_rad`].
//!
//! Every figure here is an RMS angle (the root mean square of the angle to the truth, over both
//! directions across it): a Gaussian error of that RMS exceeds it in 37 % of cases and twice it
//! in 2 % (Rayleigh). Three parts, added in quadrature:
//! - **Outline**: the centre direction and the angular radius of the fitted cone, each from the
//!   edge points' scatter (`rms / sqrt(n)`, the formal part, which vanishes with many points) and
//!   a floor for what does not average out: the rim model's own error, an outline 0.03 to 0.09 px
//!   too large on the smooth Mitsuba coats and 0.21 px on a rough one, centres within 0.07 px
//!   (docs/calibration.md). Propagated to the light direction through the geometry: the
//!   highlight's ray is intersected with the sphere moved by one sigma of each.
//! - **Highlight sampling and noise**: the lobe's weighted mean normal moves with the pixel noise
//!   of its weights (propagated), and a centroid on a pixel grid is trusted to a tenth of a pixel
//!   for a lobe one pixel wide, less for a wider one (its grid error falls with its width).
//! - **Lobe shape**: the mean is taken after dividing by `n.l`, the cosine a BRDF's radiance
//!   carries. A lobe with one cosine more or less (a microfacet BRDF's `1/(n.v)` is close to
//!   `n.l` there, but shadowing, or a renderer with none, is not) leans its mean along the
//!   plane of `l` and `v` by `s^2 tan(theta)`, `s^2` the lobe's weighted spread along that plane
//!   over its pixels not held at the clip cap (a cosine does not move those) and `theta` the
//!   angle between the normal and the view. This is what remains on a sharp, well-sampled 24 MP
//!   highlight, where the other parts vanish.
//!
//! The mirroring doubles the normal's error in the light direction. Conventions: as
//! `calib::sphere`. Pure: no I/O.

use super::{OutlineSource, SphereOutline};
use crate::geometry::camera::Intrinsics;
use crate::geometry::reflect;
use nalgebra::Vector3;

/// What the highlight centroid is trusted to on the pixel grid, per axis, for a lobe a pixel
/// wide (pixels).
const SAMPLING_PX: f64 = 0.1;
/// Floors of the outline's errors that many edge points do not average out (pixels): its
/// centre and its radius (see the module header).
const OUTLINE_CENTRE_FLOOR_PX: f64 = 0.05;
const OUTLINE_RADIUS_FLOOR_PX: f64 = 0.1;
/// A circle the user draws is trusted to half a pixel in centre and radius.
const USER_CIRCLE_PX: f64 = 0.5;
/// Least scatter assumed of detected edge points (pixels), so a noiseless image still gets an
/// honest figure.
const MIN_EDGE_RMS_PX: f64 = 0.02;

/// One pixel of the highlight's lobe as the mean normal used it.
#[derive(Clone, Copy, Debug)]
pub(super) struct LobePixel {
    pub x: f64,
    pub y: f64,
    /// Sphere normal at the pixel.
    pub normal: Vector3<f64>,
    /// Its weight in the mean normal, and the standard deviation of that weight from the
    /// pixel's noise.
    pub weight: f64,
    pub weight_sigma: f64,
    /// The weight is held at the cap of the clipped pixels: neither noise nor a cosine moves it.
    pub capped: bool,
}

/// The highlight's part: the RMS angle of the mean normal `mean` of `lobe` (unit), seen along
/// `view` (from the sphere to the camera), where one pixel spans `normal_per_px` radians of
/// normal. Also the lobe's width in pixels (RMS along its narrower axis).
pub(super) fn highlight_rms_rad(
    lobe: &[LobePixel],
    mean: &Vector3<f64>,
    view: &Vector3<f64>,
    normal_per_px: f64,
) -> (f64, f64) {
    let total: f64 = lobe.iter().map(|p| p.weight).sum();
    if total.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return (f64::INFINITY, 0.0);
    }
    // Across the mean, towards the view (and away from the light): a cosine factor
    // `1 + tan(theta) t.u` on the weights that are not capped moves the mean by
    // `tan(theta) sum(w (t.u)^2) / sum(w)` over those; and the noise of the weighted mean.
    let tangent = view - mean * view.dot(mean);
    let u = if tangent.norm() > 1e-12 {
        tangent.normalize()
    } else {
        Vector3::zeros()
    };
    let mut lean2 = 0.0;
    let mut noise2 = 0.0;
    for p in lobe.iter().filter(|p| !p.capped) {
        let t = p.normal - mean * p.normal.dot(mean);
        lean2 += p.weight * t.dot(&u).powi(2);
        noise2 += (p.weight_sigma * t.norm()).powi(2);
    }
    let lean2 = lean2 / total;
    let noise2 = noise2 / (total * total);
    // the lobe's width in pixels: the smaller axis of its weighted image covariance
    let (mx, my) = lobe.iter().fold((0.0, 0.0), |(a, b), p| {
        (a + p.weight * p.x / total, b + p.weight * p.y / total)
    });
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in lobe {
        let (dx, dy) = (p.x - mx, p.y - my);
        sxx += p.weight * dx * dx / total;
        sxy += p.weight * dx * dy / total;
        syy += p.weight * dy * dy / total;
    }
    let half_trace = 0.5 * (sxx + syy);
    let det = sxx * syy - sxy * sxy;
    let narrow = (half_trace - (half_trace * half_trace - det).max(0.0).sqrt()).max(0.0);
    let width_px = narrow.sqrt();
    let sampling = SAMPLING_PX / width_px.max(1.0) * normal_per_px;
    let theta = mean.angle(view).min(85f64.to_radians());
    let shape = lean2 * theta.tan();
    // sampling per axis (two axes), noise already over both, shape along one
    let rms = (2.0 * sampling * sampling + noise2 + shape * shape).sqrt();
    (rms, width_px)
}

/// Standard uncertainties (radians) of the outline's centre direction, per axis, and of its
/// angular radius.
pub(super) fn outline_sigmas(outline: &SphereOutline, intr: &Intrinsics) -> (f64, f64) {
    let f = 0.5 * (intr.fx + intr.fy);
    match outline.source {
        OutlineSource::UserCircle => (USER_CIRCLE_PX / f, USER_CIRCLE_PX / f),
        OutlineSource::Detected => {
            let per_point = outline.rms_residual_rad.max(MIN_EDGE_RMS_PX / f);
            let n = outline.edge_points.max(1) as f64;
            let centre = per_point * (2.0 / n).sqrt();
            let radius = per_point / n.sqrt();
            (
                centre.hypot(OUTLINE_CENTRE_FLOOR_PX / f),
                radius.hypot(OUTLINE_RADIUS_FLOOR_PX / f),
            )
        }
    }
}

/// The light direction's RMS angle from the outline's uncertainty and the highlight's
/// (`highlight_rms_rad`, of the normal): the highlight's ray (through the point of normal
/// `normal`) is intersected with the sphere moved by one sigma of the centre (each axis) and
/// of the radius, and the mirrored directions compared; the highlight's part is doubled.
pub(super) fn light_rms_rad(
    outline: &SphereOutline,
    normal: &Vector3<f64>,
    highlight_rms_rad: f64,
    intr: &Intrinsics,
) -> f64 {
    let (sigma_c, sigma_a) = outline_sigmas(outline, intr);
    let light = |d: &Vector3<f64>, alpha: f64| -> Option<Vector3<f64>> {
        let o = SphereOutline {
            centre_dir: d.normalize(),
            angular_radius_rad: alpha,
            ..outline.clone()
        };
        let ray = (outline.centre_in_radii() + normal).normalize();
        let (p, n) = o.intersect(&ray)?;
        Some(reflect(&n, &(-p.normalize())).normalize())
    };
    let d = outline.centre_dir;
    let alpha = outline.angular_radius_rad;
    let Some(l0) = light(&d, alpha) else {
        return f64::INFINITY;
    };
    let helper = if d.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e1 = d.cross(&helper).normalize();
    let e2 = d.cross(&e1);
    // first order: a small step each way, scaled to one sigma (the ray may miss one way)
    let moved = |sigma: f64, at: &dyn Fn(f64) -> Option<Vector3<f64>>| -> f64 {
        let step = 1e-3 * sigma;
        let one = |s: f64| at(s).map(|l| l.angle(&l0) * sigma / step);
        match (one(step), one(-step)) {
            (Some(a), Some(b)) => 0.5 * (a + b),
            (Some(a), None) | (None, Some(a)) => a,
            (None, None) => f64::INFINITY,
        }
    };
    let outline2 = moved(sigma_c, &|s| light(&(d + e1 * s), alpha)).powi(2)
        + moved(sigma_c, &|s| light(&(d + e2 * s), alpha)).powi(2)
        + moved(sigma_a, &|s| light(&d, alpha + s)).powi(2);
    (outline2 + (2.0 * highlight_rms_rad).powi(2)).sqrt()
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    fn outline(alpha: f64, points: usize, rms_px: f64, f: f64) -> SphereOutline {
        SphereOutline {
            centre_dir: Vector3::new(0.05, -0.02, 1.0).normalize(),
            angular_radius_rad: alpha,
            centre_px: [0.0; 2],
            radius_px: alpha.tan() * f,
            edge_points: points,
            rms_residual_rad: rms_px / f,
            source: OutlineSource::Detected,
        }
    }

    /// The outline's part against a Monte Carlo of the same geometry: the light direction from
    /// spheres whose centre and radius are drawn with the stated sigmas scatters by the RMS
    /// angle computed (within the Monte Carlo's own error).
    #[test]
    fn the_outline_part_matches_a_monte_carlo_of_its_sigmas() {
        use rand::{Rng, SeedableRng};
        let f = 1000.0;
        let intr = Intrinsics::pinhole(2000, 2000, f, f, 1000.0, 1000.0);
        let o = outline(0.1, 400, 0.3, f);
        // a normal 40 deg from the view, towards +x
        let v = -o.centre_dir;
        let axis = v.cross(&Vector3::y()).normalize();
        let normal = nalgebra::Rotation3::from_axis_angle(
            &nalgebra::Unit::new_normalize(axis),
            40f64.to_radians(),
        ) * v;
        let rms = light_rms_rad(&o, &normal, 0.0, &intr);
        let (sc, sa) = outline_sigmas(&o, &intr);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut gauss = || {
            let (u1, u2): (f64, f64) = (rng.r#gen::<f64>().max(1e-300), rng.r#gen());
            (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
        };
        let ray = (o.centre_in_radii() + normal).normalize();
        let (p0, n0) = o.intersect(&ray).unwrap();
        let l0 = reflect(&n0, &(-p0.normalize()));
        let e1 = o.centre_dir.cross(&Vector3::x()).normalize();
        let e2 = o.centre_dir.cross(&e1);
        let trials = 4000;
        let mut sum2 = 0.0;
        for _ in 0..trials {
            let moved = SphereOutline {
                centre_dir: (o.centre_dir + e1 * (sc * gauss()) + e2 * (sc * gauss())).normalize(),
                angular_radius_rad: o.angular_radius_rad + sa * gauss(),
                ..o.clone()
            };
            let (p, n) = moved.intersect(&ray).unwrap();
            sum2 += reflect(&n, &(-p.normalize())).angle(&l0).powi(2);
        }
        let mc = (sum2 / trials as f64).sqrt();
        assert!(
            (mc / rms - 1.0).abs() < 0.05,
            "Monte Carlo {mc} against {rms}"
        );
        // the highlight's part is doubled
        let with = light_rms_rad(&o, &normal, 1e-3, &intr);
        assert!((with - (rms * rms + 4e-6).sqrt()).abs() < 1e-12);
        // the floors: a noiseless outline of many points still has them
        let (c, a) = outline_sigmas(&outline(0.1, 100_000, 0.0, f), &intr);
        assert!((c * f - OUTLINE_CENTRE_FLOOR_PX).abs() < 1e-3);
        assert!((a * f - OUTLINE_RADIUS_FLOOR_PX).abs() < 1e-3);
    }

    /// A symmetric lobe: the shape part is its spread squared times tan(theta); a lobe of one
    /// pixel is trusted to a tenth of a pixel per axis.
    #[test]
    fn the_highlight_part_of_a_symmetric_lobe() {
        let view = Vector3::new(0.0, 0.0, -1.0);
        // the mean normal 30 deg from the view
        let mean = Vector3::new(30f64.to_radians().sin(), 0.0, -(30f64.to_radians().cos()));
        let e1 = Vector3::y();
        let e2 = mean.cross(&e1).normalize();
        let s = 0.02;
        let lobe: Vec<LobePixel> = [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)]
            .iter()
            .enumerate()
            .map(|(k, (a, b))| LobePixel {
                x: 10.0 + 3.0 * a,
                y: 10.0 + 3.0 * b,
                normal: (mean + e1 * (s * a * 2f64.sqrt()) + e2 * (s * b * 2f64.sqrt()))
                    .normalize(),
                weight: 1.0 + 0.0 * k as f64,
                weight_sigma: 0.0,
                capped: false,
            })
            .collect();
        let (rms, width) = highlight_rms_rad(&lobe, &mean, &view, 0.0);
        // spread along the view's plane s (to first order), shape s^2 tan 30
        let shape = s * s * 30f64.to_radians().tan();
        assert!((rms / shape - 1.0).abs() < 0.01, "{rms} {shape}");
        // held at the cap, the same lobe cannot lean
        let capped: Vec<LobePixel> = lobe
            .iter()
            .map(|p| LobePixel {
                capped: true,
                normal: p.normal,
                ..*p
            })
            .collect();
        assert!(highlight_rms_rad(&capped, &mean, &view, 0.0).0 < 1e-12);
        // width: the pixels are 3 px either way on each axis: RMS 3/sqrt(2)
        assert!((width - 3.0 / 2f64.sqrt()).abs() < 1e-9, "{width}");
        // sampling only (no spread): a tenth of a pixel per axis over the width
        let point = [LobePixel {
            x: 0.0,
            y: 0.0,
            normal: mean,
            weight: 1.0,
            weight_sigma: 0.0,
            capped: false,
        }];
        let (rms, _) = highlight_rms_rad(&point, &mean, &view, 0.01);
        assert!((rms - 2f64.sqrt() * SAMPLING_PX * 0.01).abs() < 1e-12);
    }
}
