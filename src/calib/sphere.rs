//! The light probe: a glossy black sphere photographed under the single light. Its outline gives
//! the sphere's position, its specular highlight the mirror normal, and the light direction is
//! the view direction mirrored about that normal, `l = 2 (n.v) n - v` (METHOD.md section 1.3).
//!
//! Conventions: camera axes x right, y down, z forward (COLMAP); every direction is a unit vector
//! in camera axes; `v` points from the sphere towards the camera, `l` from the sphere towards the
//! light. Pixel centres at half-integers. Angles in radians.
//!
//! Approach, perspective-exact: under perspective a sphere projects to an ellipse, not a circle,
//! so instead of fitting a conic in the image, every sub-pixel edge point is back-projected to a
//! ray with the intrinsics (distortion included). The rays tangent to a sphere form a circular
//! cone around the direction `d` of the sphere's centre with half-angle `alpha`, so
//! `d . r_i = cos(alpha)` for every edge ray: the ray tips lie on a plane, fitted by total least
//! squares (smallest eigenvector of their covariance). With the sphere radius as unit the centre
//! is `C = d / sin(alpha)`; the scale of the scene never matters for directions. The normal at a
//! pixel is found by intersecting its ray with that sphere. The highlight is located in *normal
//! space* (weighted mean of the sphere normals of its pixels), where the iso-brightness contours
//! of an isotropic lobe are circles around the mirror normal, so foreshortening near the rim and
//! a clipped (saturated) core do not bias it.
//!
//! Edge points: a threshold (Otsu) finds the sphere as the largest round region darker (or
//! brighter) than its surround, a circle fit to its border pixels seeds radial intensity
//! profiles, and each profile's crossing of the level half way between the local inside and
//! outside levels is the sub-pixel edge (exact for an anti-aliased straight step edge). A glossy
//! dielectric sphere's rim fades into the backdrop it mirrors at grazing angles (Fresnel), which
//! shrinks that edge by ~0.9 % of the radius for `f0 = 0.04`, about 0.5 degree of light
//! direction; it is corrected in closed form ([`SphereOutline::corrected_for_fresnel_rim`]).
//! Depends on `geometry::camera` and `render::image` only; pure, no I/O.

use super::regions::{self, Plane, saturation_level};
use crate::geometry::camera::Intrinsics;
use crate::render::image::LinearImage;
use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use std::f64::consts::PI;
use thiserror::Error;

#[derive(Debug, Error, Clone, PartialEq)]
pub enum SphereError {
    #[error("no sphere found: {reason}")]
    NoSphere { reason: String },
    #[error(
        "the sphere is cut by the frame edge (outline centre ({cx:.1}, {cy:.1}) px, radius \
         {radius_px:.1} px, image {width}x{height}): frame the whole sphere"
    )]
    SphereCut {
        cx: f64,
        cy: f64,
        radius_px: f64,
        width: usize,
        height: usize,
    },
    #[error("no highlight on the sphere: {reason}")]
    NoHighlight { reason: String },
    #[error(
        "the brightest region (centroid ({x:.1}, {y:.1}) px) lies outside the sphere (outline \
         centre ({cx:.1}, {cy:.1}) px, radius {radius_px:.1} px): mask or remove the other \
         bright object, or check that the outline image matches the light image"
    )]
    HighlightOutsideSphere {
        x: f64,
        y: f64,
        cx: f64,
        cy: f64,
        radius_px: f64,
    },
    #[error("{what} is {got_w}x{got_h} pixels but the intrinsics are for {want_w}x{want_h}")]
    SizeMismatch {
        what: String,
        got_w: usize,
        got_h: usize,
        want_w: usize,
        want_h: usize,
    },
    #[error("invalid outline circle: {reason}")]
    InvalidCircle { reason: String },
}

/// Tuning of the sphere detection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereOptions {
    /// Value at or above which a channel is clipped. `None`: detected as the image maximum when
    /// at least 4 pixels share it (a clipped highlight), otherwise no clipping assumed.
    pub saturation: Option<f32>,
    /// Smallest sphere radius, in pixels, worth considering.
    pub min_radius_px: f64,
    /// Normal-incidence Fresnel reflectance of the sphere's surface, to correct the detected
    /// outline for the bright (or dark) rim a glossy dielectric shows: see
    /// [`SphereOutline::corrected_for_fresnel_rim`]. 0.04 for black glossy plastic or glass;
    /// `None` for a matte outline image or a metal (chrome) sphere.
    pub rim_fresnel_f0: Option<f64>,
}

impl Default for SphereOptions {
    fn default() -> Self {
        Self {
            saturation: None,
            min_radius_px: 8.0,
            rim_fresnel_f0: Some(0.04),
        }
    }
}

/// `n.v` on the sphere where Schlick's Fresnel reflectance is one half, for `f0 < 0.5`.
pub fn half_fresnel_cos(f0: f64) -> Option<f64> {
    (f0.is_finite() && (0.0..0.5).contains(&f0)).then(|| 1.0 - ((0.5 - f0) / (1.0 - f0)).powf(0.2))
}

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
            let med = super::robust::median(&mut sorted)?;
            let sigma = super::robust::mad_sigma(&res, med)?;
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

    /// The outline of the sphere itself from the apparent outline of a glossy dielectric one.
    ///
    /// Near the silhouette a glossy sphere mirrors what lies just behind it, with a Fresnel
    /// reflectance rising to 1 at grazing angles, so its rim fades into the backdrop and the
    /// half-level edge sits where the reflectance is 1/2: radiance `(1 - F) I + F B` equals
    /// `(I + B) / 2` exactly when `F = 1/2`, whatever the sphere's own level `I` and the backdrop's
    /// `B`. With Schlick's `F = f0 + (1 - f0)(1 - n.v)^5` that is `n.v = c*`, and a ray at angle
    /// `beta` from the centre direction meets the sphere where `sin(theta) = sin(beta) / sin(alpha)`;
    /// so the true `sin(alpha) = sin(alpha_apparent) / sqrt(1 - c*^2)` (0.94 % larger for
    /// `f0 = 0.04`, independent of the sphere's size in pixels). No change for `f0 >= 0.5` (a
    /// metal's rim does not cross the half level).
    pub fn corrected_for_fresnel_rim(&self, f0: f64, intr: &Intrinsics) -> Self {
        let Some(c) = half_fresnel_cos(f0) else {
            return self.clone();
        };
        let sin_a = (self.angular_radius_rad.sin() / (1.0 - c * c).sqrt()).min(0.999_999);
        let alpha = sin_a.asin();
        Self {
            angular_radius_rad: alpha,
            radius_px: alpha.tan() * 0.5 * (intr.fx + intr.fy),
            ..self.clone()
        }
    }

    /// First-order standard uncertainty (radians) of a sphere normal read off this outline: a
    /// centre-direction error `dc` shifts the sphere by `dc / alpha` of its own radius. A user
    /// circle is trusted to half a pixel.
    pub fn normal_uncertainty_rad(&self, intr: &Intrinsics) -> f64 {
        let f = 0.5 * (intr.fx + intr.fy);
        let per_point = match self.source {
            OutlineSource::Detected => self.rms_residual_rad.max(0.02 / f),
            OutlineSource::UserCircle => 0.5 / f,
        };
        let n = match self.source {
            OutlineSource::Detected => self.edge_points.max(1) as f64,
            OutlineSource::UserCircle => 1.0,
        };
        let sigma_centre = per_point * (2.0 / n).sqrt();
        let sigma_radius = per_point / n.sqrt();
        (sigma_centre.powi(2) + sigma_radius.powi(2)).sqrt() / self.angular_radius_rad
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

fn check_size(img: &LinearImage, intr: &Intrinsics, what: &str) -> Result<(), SphereError> {
    if img.width() != intr.width || img.height() != intr.height {
        return Err(SphereError::SizeMismatch {
            what: what.into(),
            got_w: img.width(),
            got_h: img.height(),
            want_w: intr.width,
            want_h: intr.height,
        });
    }
    Ok(())
}

/// A round region found by thresholding: the seed of the sub-pixel outline.
struct Candidate {
    cx: f64,
    cy: f64,
    r: f64,
    area: usize,
    touches_border: bool,
}

/// Finds the sphere outline in an image where the sphere stands out from its surround (ambient
/// light with a lighter backdrop, or the single-light image when its backdrop is lit).
pub fn detect_outline(
    img: &LinearImage,
    intr: &Intrinsics,
    opts: &SphereOptions,
) -> Result<SphereOutline, SphereError> {
    check_size(img, intr, "the outline image")?;
    let (w, h) = (img.width(), img.height());
    if w < 8 || h < 8 {
        return Err(SphereError::NoSphere {
            reason: format!("the image is only {w}x{h} pixels"),
        });
    }
    let sat = saturation_level(img, opts.saturation);
    let lum = Plane::luminance(img);
    let smooth = lum.box3();
    let lo = regions::quantile(&smooth.data, 0.0).unwrap_or(0.0);
    let hi = regions::quantile(&smooth.data, 0.99).unwrap_or(0.0);
    let no_contrast = || SphereError::NoSphere {
        reason: "the image has no contrast to separate a sphere from its surround".into(),
    };
    if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
        return Err(no_contrast());
    }
    let thr = regions::otsu_threshold(&smooth.data, lo, hi).ok_or_else(no_contrast)?;
    let min_area = PI * opts.min_radius_px * opts.min_radius_px;
    let mut best: Option<Candidate> = None;
    for dark in [true, false] {
        let mask: Vec<bool> = smooth.data.iter().map(|&v| (v < thr) == dark).collect();
        for comp in regions::components(&mask, w, h) {
            if (comp.pixels.len() as f64) < min_area {
                continue;
            }
            // cut off a stand or post narrower than about 0.6 of the region's radius
            let filled = regions::filled_mask(&comp, w, h);
            let k = ((comp.pixels.len() as f64 / PI).sqrt() * 0.3).round() as usize;
            let opened = regions::open_mask(&filled, w, h, k.max(1));
            for part in regions::components(&opened, w, h) {
                if (part.pixels.len() as f64) < min_area {
                    continue;
                }
                let part_filled = regions::filled_mask(&part, w, h);
                if let Some(c) = round_candidate(&part_filled, &lum, w, h, part.touches_border, sat)
                    && (c.area as f64) >= min_area
                    && best.as_ref().is_none_or(|b| c.area > b.area)
                {
                    best = Some(c);
                }
            }
        }
    }
    let c = best.ok_or_else(|| SphereError::NoSphere {
        reason: format!(
            "no round region of radius at least {} px stands out from its surround",
            opts.min_radius_px
        ),
    })?;
    let cut = SphereError::SphereCut {
        cx: c.cx,
        cy: c.cy,
        radius_px: c.r,
        width: w,
        height: h,
    };
    if c.touches_border
        || c.cx - c.r < 1.0
        || c.cy - c.r < 1.0
        || c.cx + c.r > w as f64 - 1.0
        || c.cy + c.r > h as f64 - 1.0
    {
        return Err(cut);
    }
    let points = subpixel_edges(&lum, &c, sat);
    if points.len() < 16 {
        return Err(SphereError::NoSphere {
            reason: format!(
                "only {} sharp edge points around the round region at ({:.1}, {:.1}) px",
                points.len(),
                c.cx,
                c.cy
            ),
        });
    }
    let rays: Vec<Vector3<f64>> = points.iter().map(|&(x, y)| intr.ray(x, y)).collect();
    let mut outline =
        SphereOutline::from_edge_rays(&rays, intr).ok_or_else(|| SphereError::NoSphere {
            reason: "the edge points do not fit a sphere's outline".into(),
        })?;
    if let Some(f0) = opts.rim_fresnel_f0 {
        outline = outline.corrected_for_fresnel_rim(f0, intr);
    }
    // the fitted outline itself must lie inside the frame
    for i in 0..72 {
        let a = i as f64 * 2.0 * PI / 72.0;
        let ray = tangent_ray(&outline, a);
        let inside = intr
            .project(&ray)
            .is_some_and(|(x, y)| x > 0.5 && y > 0.5 && x < w as f64 - 0.5 && y < h as f64 - 0.5);
        if !inside {
            return Err(cut);
        }
    }
    Ok(outline)
}

/// The tangent ray of the outline cone at azimuth `a` around its axis.
fn tangent_ray(o: &SphereOutline, a: f64) -> Vector3<f64> {
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

/// Circle fit to the border of a filled region; `None` unless the region is round.
fn round_candidate(
    filled: &[bool],
    lum: &Plane,
    w: usize,
    h: usize,
    touches_border: bool,
    sat: Option<f32>,
) -> Option<Candidate> {
    let area = filled.iter().filter(|&&m| m).count();
    let mut border = Vec::new();
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let i = y * w + x;
            if filled[i] && (!filled[i - 1] || !filled[i + 1] || !filled[i - w] || !filled[i + w]) {
                border.push((x as f64 + 0.5, y as f64 + 0.5));
            }
        }
    }
    if border.len() < 12 {
        return None;
    }
    let (cx, cy, r) = regions::fit_circle(&border)?;
    let rms = (border
        .iter()
        .map(|(x, y)| ((x - cx).hypot(y - cy) - r).powi(2))
        .sum::<f64>()
        / border.len() as f64)
        .sqrt();
    if rms > 0.08 * r + 0.5 {
        return None;
    }
    // a straight boundary fits a huge circle; a sphere (even one cut by the frame) has its
    // centre in the frame and fits in it
    if !(cx > 0.0 && cy > 0.0 && cx < w as f64 && cy < h as f64 && 2.0 * r < w.max(h) as f64) {
        return None;
    }
    // the region must fill its circle (within the frame) and stay inside it
    let (mut in_circle, mut members_in, mut members_out) = (0usize, 0usize, 0usize);
    let mut interior = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let d = (x as f64 + 0.5 - cx).hypot(y as f64 + 0.5 - cy);
            let m = filled[y * w + x];
            if d < r - 1.0 {
                in_circle += 1;
                if m {
                    members_in += 1;
                    interior.push(lum.at(x, y));
                }
            } else if d > r + 1.5 && m {
                members_out += 1;
            }
        }
    }
    if in_circle == 0
        || (members_in as f64) < 0.95 * in_circle as f64
        || (members_out as f64) > 0.05 * area as f64
    {
        return None;
    }
    // a clipped blob (the highlight itself) is not the sphere
    if let (Some(s), Some(m)) = (sat, regions::quantile(&interior, 0.5))
        && m >= 0.9 * s
    {
        return None;
    }
    Some(Candidate {
        cx,
        cy,
        r,
        area,
        touches_border,
    })
}

/// Sub-pixel edge points along radial profiles around a candidate circle.
fn subpixel_edges(lum: &Plane, c: &Candidate, sat: Option<f32>) -> Vec<(f64, f64)> {
    const HALF: f64 = 6.0;
    const STEP: f64 = 0.1;
    let n_angles = ((2.0 * PI * c.r).round() as usize).clamp(64, 1440);
    let ns = (2.0 * HALF / STEP).round() as usize + 1;
    // per profile: samples, inside level, outside level
    let mut profiles: Vec<(f64, f64, Vec<f64>, f64, f64)> = Vec::with_capacity(n_angles);
    'angle: for k in 0..n_angles {
        let a = k as f64 * 2.0 * PI / n_angles as f64;
        let (ux, uy) = (a.cos(), a.sin());
        let mut samples = Vec::with_capacity(ns);
        for j in 0..ns {
            let s = c.r - HALF + j as f64 * STEP;
            let Some(v) = regions::bilinear(lum, c.cx + s * ux, c.cy + s * uy) else {
                continue 'angle;
            };
            if sat.is_some_and(|s| v >= 0.98 * s as f64) {
                continue 'angle;
            }
            samples.push(v);
        }
        let inner: Vec<f64> = samples[..=(3.0 / STEP) as usize].to_vec();
        let outer: Vec<f64> = samples[ns - 1 - (3.0 / STEP) as usize..].to_vec();
        let (Some(li), Some(lo)) = (
            super::robust::median(&mut inner.clone()),
            super::robust::median(&mut outer.clone()),
        ) else {
            continue;
        };
        profiles.push((ux, uy, samples, li, lo));
    }
    let mut contrasts: Vec<f64> = profiles.iter().map(|p| p.4 - p.3).collect();
    let Some(global) = super::robust::median(&mut contrasts) else {
        return Vec::new();
    };
    let mut points = Vec::new();
    for (ux, uy, samples, li, lo) in profiles {
        let contrast = lo - li;
        if contrast * global <= 0.0 || contrast.abs() < 0.3 * global.abs() {
            continue;
        }
        // something much brighter than both sides (a highlight at the rim) spoils the profile
        let top = li.max(lo) + contrast.abs();
        if samples.iter().any(|&v| v > top) {
            continue;
        }
        let mid = 0.5 * (li + lo);
        let mut best: Option<f64> = None;
        for j in 0..samples.len() - 1 {
            let (a, b) = (samples[j] - mid, samples[j + 1] - mid);
            if a == 0.0 || a * b < 0.0 {
                let t = if a == 0.0 { 0.0 } else { a / (a - b) };
                let s = c.r - HALF + (j as f64 + t) * STEP;
                if best.is_none_or(|bs| (s - c.r).abs() < (bs - c.r).abs()) {
                    best = Some(s);
                }
            }
        }
        if let Some(s) = best {
            points.push((c.cx + s * ux, c.cy + s * uy));
        }
    }
    points
}

/// The specular highlight on the sphere.
#[derive(Clone, Debug, PartialEq)]
pub struct Highlight {
    /// Weighted image centroid of the highlight region (for reports).
    pub centroid_px: [f64; 2],
    /// Sphere normal at the highlight (weighted mean in normal space).
    pub normal: Vector3<f64>,
    /// Pixels in the highlight region, and how many of them are clipped.
    pub pixels: usize,
    pub saturated_pixels: usize,
    /// Brightest luminance in the region (the clip level when clipped).
    pub peak: f32,
}

/// Finds the highlight: among the connected regions above half way from the sphere's typical
/// level to its brightest pixel, centred on the sphere, the one with the largest summed excess
/// (so a small second highlight or a hot pixel loses to the real one). Clipped pixels count at
/// the clip level. Brighter things elsewhere in the frame (a lamp, a lit wall) are ignored; when
/// nothing on the sphere stands out but a compact bright spot lies off it, the outline and the
/// light image disagree: [`SphereError::HighlightOutsideSphere`].
pub fn find_highlight(
    img: &LinearImage,
    outline: &SphereOutline,
    intr: &Intrinsics,
    opts: &SphereOptions,
) -> Result<Highlight, SphereError> {
    check_size(img, intr, "the light image")?;
    let (w, h) = (img.width(), img.height());
    let sat = saturation_level(img, opts.saturation);
    let lum = Plane::luminance(img);
    let maxc = Plane::max_channel(img);
    let cap = sat.unwrap_or(f32::INFINITY);
    let eff: Vec<f32> = lum.data.iter().map(|&v| v.min(cap)).collect();
    // the sphere's own pixels, two pixels in from the rim (rim pixels mix with the backdrop)
    let f = 0.5 * (intr.fx + intr.fy);
    let cos_inner = (outline.angular_radius_rad - 2.0 / f).max(0.0).cos();
    let mut inside = Vec::new();
    let mut peak_inside = f32::MIN;
    for y in 0..h {
        for x in 0..w {
            let ray = intr.ray(x as f64 + 0.5, y as f64 + 0.5);
            if ray.dot(&outline.centre_dir) > cos_inner {
                let v = eff[y * w + x];
                inside.push(v as f64);
                peak_inside = peak_inside.max(v);
            }
        }
    }
    let mut sorted = inside.clone();
    let level = super::robust::median(&mut sorted).ok_or_else(|| SphereError::NoHighlight {
        reason: "the sphere covers no pixel".into(),
    })?;
    let sigma = super::robust::mad_sigma(&inside, level).unwrap_or(0.0);
    let floor = level + (10.0 * sigma).max(0.05 * level.abs()).max(1e-9);
    if (peak_inside as f64) <= floor {
        // nothing on the sphere; a compact bright spot elsewhere means the highlight is off the
        // outline (an outline image or circle that does not match the light image)
        let peak = eff.iter().copied().fold(f32::MIN, f32::max) as f64;
        if peak > floor {
            let thr = level + 0.5 * (peak - level);
            if let Some((c, (x, y), _)) = bright_regions(&eff, w, h, thr)
                .into_iter()
                .max_by(|a, b| a.2.total_cmp(&b.2))
                && !c.touches_border
                && c.pixels.len() < inside.len()
            {
                return Err(SphereError::HighlightOutsideSphere {
                    x,
                    y,
                    cx: outline.centre_px[0],
                    cy: outline.centre_px[1],
                    radius_px: outline.radius_px,
                });
            }
        }
        return Err(SphereError::NoHighlight {
            reason: format!(
                "the brightest pixel on the sphere ({peak_inside:.4}) barely exceeds its typical \
                 level ({level:.4}, noise {sigma:.4}); is the light on?"
            ),
        });
    }
    let thr = level + 0.5 * (peak_inside as f64 - level);
    // on the sphere: centred on it, and mostly on it (a ring of backdrop around the sphere, joined
    // through a bright Fresnel rim, is centred on it too)
    let on_sphere = |c: &regions::Component, x: f64, y: f64| {
        let pixel_on = |i: &&usize| {
            outline.contains_pixel(intr, (**i % w) as f64 + 0.5, (**i / w) as f64 + 0.5)
        };
        outline.contains_pixel(intr, x, y)
            && 2 * c.pixels.iter().filter(pixel_on).count() >= c.pixels.len()
    };
    let (best, _) = bright_regions(&eff, w, h, thr)
        .into_iter()
        .filter(|(c, (x, y), _)| on_sphere(c, *x, *y))
        .max_by(|a, b| a.2.total_cmp(&b.2))
        .map(|(c, xy, _)| (c, xy))
        .ok_or_else(|| SphereError::NoHighlight {
            reason: "no bright region is centred on the sphere".into(),
        })?;
    let (mut sx, mut sy, mut sw) = (0.0, 0.0, 0.0);
    let mut n_sum = Vector3::zeros();
    let mut saturated = 0;
    let mut peak_region = f32::MIN;
    for &i in &best.pixels {
        let (x, y) = ((i % w) as f64 + 0.5, (i / w) as f64 + 0.5);
        let wgt = (eff[i] as f64 - thr).max(1e-12);
        sx += wgt * x;
        sy += wgt * y;
        sw += wgt;
        if sat.is_some_and(|s| maxc.data[i] >= s) {
            saturated += 1;
        }
        peak_region = peak_region.max(eff[i]);
        let ray = intr.ray(x, y);
        if let Some((_, n)) = outline.intersect(&ray) {
            // a pixel covers normal-space area proportional to 1 / (n.v)
            let cos = n.dot(&-ray).max(0.05);
            n_sum += n * (wgt / cos);
        }
    }
    let (x, y) = (sx / sw, sy / sw);
    if n_sum.norm() == 0.0 {
        return Err(SphereError::NoHighlight {
            reason: format!("the bright region at ({x:.1}, {y:.1}) px misses the sphere"),
        });
    }
    Ok(Highlight {
        centroid_px: [x, y],
        normal: n_sum.normalize(),
        pixels: best.pixels.len(),
        saturated_pixels: saturated,
        peak: peak_region,
    })
}

/// Connected regions of `eff >= thr`: component, weighted centroid (pixel coordinates) and
/// summed excess over `thr`.
fn bright_regions(
    eff: &[f32],
    w: usize,
    h: usize,
    thr: f64,
) -> Vec<(regions::Component, (f64, f64), f64)> {
    let mask: Vec<bool> = eff.iter().map(|&v| v as f64 >= thr).collect();
    regions::components(&mask, w, h)
        .into_iter()
        .map(|c| {
            let (mut sx, mut sy, mut s) = (0.0, 0.0, 0.0);
            for &i in &c.pixels {
                let e = (eff[i] as f64 - thr).max(1e-12);
                sx += e * ((i % w) as f64 + 0.5);
                sy += e * ((i / w) as f64 + 0.5);
                s += e;
            }
            (c, (sx / s, sy / s), s)
        })
        .collect()
}

/// Mirror `v` about `n`: `2 (n.v) n - v`.
pub fn reflect(n: &Vector3<f64>, v: &Vector3<f64>) -> Vector3<f64> {
    n * (2.0 * n.dot(v)) - v
}

/// The light direction measured from one sphere image.
#[derive(Clone, Debug, PartialEq)]
pub struct SphereLight {
    /// Unit vector from the sphere towards the light, camera axes.
    pub dir_camera: Vector3<f64>,
    /// Sphere normal at the highlight, and the direction from that point to the camera.
    pub normal: Vector3<f64>,
    pub view: Vector3<f64>,
    pub outline: SphereOutline,
    pub highlight: Highlight,
    /// First-order standard uncertainty of `dir_camera` (radians): twice the normal's, since
    /// mirroring doubles a normal error.
    pub uncertainty_rad: f64,
}

/// Light direction from a light image and the sphere's outline.
pub fn light_from_sphere(
    light_image: &LinearImage,
    outline: &SphereOutline,
    intr: &Intrinsics,
    opts: &SphereOptions,
) -> Result<SphereLight, SphereError> {
    let highlight = find_highlight(light_image, outline, intr, opts)?;
    let n = highlight.normal;
    let p = outline.centre_in_radii() + n;
    let v = -p.normalize();
    let l = reflect(&n, &v).normalize();
    // the highlight centroid is trusted to a tenth of a pixel
    let sigma_h = 0.1 / outline.radius_px.max(1.0);
    let sigma_n = (outline.normal_uncertainty_rad(intr).powi(2) + sigma_h.powi(2)).sqrt();
    Ok(SphereLight {
        dir_camera: l,
        normal: n,
        view: v,
        outline: outline.clone(),
        highlight,
        uncertainty_rad: 2.0 * sigma_n,
    })
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
    fn fresnel_half_point_and_rim_correction() {
        let c = half_fresnel_cos(0.04).unwrap();
        let f = 0.04 + 0.96 * (1.0 - c).powi(5);
        assert!((f - 0.5).abs() < 1e-12);
        assert!(half_fresnel_cos(0.6).is_none());
        // the ray at the apparent edge meets the true sphere where n.v = c
        let intr = Intrinsics::pinhole(320, 240, 300.0, 300.0, 160.0, 120.0);
        let apparent = SphereOutline {
            centre_dir: Vector3::z(),
            angular_radius_rad: 0.2,
            centre_px: [160.0, 120.0],
            radius_px: 60.0,
            edge_points: 100,
            rms_residual_rad: 0.0,
            source: OutlineSource::Detected,
        };
        let truth = apparent.corrected_for_fresnel_rim(0.04, &intr);
        assert!(truth.angular_radius_rad > apparent.angular_radius_rad);
        let ray = tangent_ray(&apparent, 0.7);
        let (_, n) = truth.intersect(&ray).unwrap();
        assert!((n.dot(&-ray) - c).abs() < 1e-9, "{} vs {c}", n.dot(&-ray));
    }

    #[test]
    fn reflection_is_the_mirror_direction() {
        let n = Vector3::new(0.0, 0.0, -1.0);
        let v = Vector3::new(0.6, 0.0, -0.8);
        let l = reflect(&n, &v);
        assert!((l - Vector3::new(-0.6, 0.0, -0.8)).norm() < 1e-12);
        // half vector of l and v is n
        assert!(((l + v).normalize() - n).norm() < 1e-12);
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
