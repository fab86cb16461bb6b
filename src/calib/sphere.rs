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
//! profiles, and each profile's *area edge* is the sub-pixel edge: where a sharp step between the
//! local inside and outside levels would hold the same light as the profile. For a blurred step
//! it is the half-level crossing; unlike the crossing it does not move when the lens and the
//! pixel area blur an edge that is not a symmetric step. A glossy dielectric sphere's rim fades
//! into the backdrop it mirrors at grazing angles (Fresnel), which moves that edge inwards by
//! 0.4 to 1 pixel (2.4 % of the radius at 19 px, 1.4 % at 75 px, for `f0 = 0.04`: degrees
//! of light direction near the rim); it is corrected in closed form
//! ([`SphereOutline::corrected_for_fresnel_rim`]).
//!
//! Highlight position: the half-peak region chooses the highlight; its lobe is then followed down
//! to a few percent of the peak above the sphere's own radiance (estimated per ring around the
//! centre, so the brightening rim does not count), every pixel weighted by that excess. Its
//! tails carry the sub-pixel position a half-peak cut would throw away.
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

/// How far (pixels) inside the true outline the area edge of a glossy dielectric sphere's rim
/// lies, for a sphere of `radius_px` and Fresnel reflectance `f0 < 0.5` at normal incidence (see
/// [`SphereOutline::corrected_for_fresnel_rim`]): the integral over the edge window of
/// `(F(d) - F_in) / (1 - F_in)`, with `d` the depth inside the outline, `n.v = sqrt(1 - (1 -
/// d/R)^2)` there (the sphere seen from afar), and `F_in` the reflectance at the middle of the
/// inside window (its median, `F` falling with depth), the windows centred on the detected edge.
pub fn rim_edge_offset_px(radius_px: f64, f0: f64) -> Option<f64> {
    if !(f0.is_finite() && (0.0..0.5).contains(&f0) && radius_px > 1.0) {
        return None;
    }
    let fresnel = |d: f64| {
        let t = 1.0 - (d / radius_px).min(1.0);
        let cos = (1.0 - t * t).max(0.0).sqrt();
        f0 + (1.0 - f0) * (1.0 - cos).powi(5)
    };
    // The windows are centred on the detected edge, `delta` inside the true one: the outside
    // stretch (EDGE_WINDOW - delta) is all backdrop, so the area edge condition reads
    // delta = integral over depths [0, delta + EDGE_WINDOW] of (F - F_in) / (1 - F_in).
    const STEPS: usize = 3000;
    let mut delta = 0.0;
    for _ in 0..30 {
        let f_in = fresnel(delta + 1.5 * EDGE_WINDOW);
        let span = delta + EDGE_WINDOW;
        let h = span / STEPS as f64;
        let next: f64 = (0..STEPS)
            .map(|i| (fresnel((i as f64 + 0.5) * h) - f_in) / (1.0 - f_in) * h)
            .sum();
        if (next - delta).abs() < 1e-9 {
            return Some(next);
        }
        delta = next;
    }
    Some(delta)
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
    /// Near the silhouette a glossy sphere mirrors what lies just behind it, with Schlick's
    /// Fresnel reflectance `F = f0 + (1 - f0)(1 - n.v)^5` rising to 1 at grazing angles, so its
    /// rim fades into the backdrop. Across the rim the radiance is `I + F (B - I)` for the
    /// sphere's own level `I` and the backdrop's `B`; normalised between the profile's inside
    /// level (the same expression at the inside window, `F_in`) and `B` it is
    /// `(F - F_in) / (1 - F_in)` whatever `I` and `B` are. The detected edge (the area edge, see
    /// `subpixel_edges`) therefore lies [`rim_edge_offset_px`] inside the true one, a function of
    /// the radius in pixels and `f0` only; that many pixels are added back to the radius. No
    /// change for `f0 >= 0.5` (a metal, whose rim is not a fade to the backdrop).
    pub fn corrected_for_fresnel_rim(&self, f0: f64, intr: &Intrinsics) -> Self {
        let Some(delta) = rim_edge_offset_px(self.radius_px, f0) else {
            return self.clone();
        };
        let scale = (self.radius_px + delta) / self.radius_px;
        let alpha = (self.angular_radius_rad.tan() * scale).atan();
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
            // close notches a highlight at the rim bites into the region, then cut off a stand
            // or post narrower than about 0.6 of the region's radius
            let filled = regions::filled_mask(&comp, w, h);
            let k = ((comp.pixels.len() as f64 / PI).sqrt() * 0.3).round() as usize;
            let closed = regions::close_mask(&filled, w, h, k.max(1));
            let opened = regions::open_mask(&closed, w, h, k.max(1));
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

/// Half-width (pixels) of the stretch of a radial profile over which the edge's light is summed;
/// the inside and outside levels come from the next 3 pixels on either side.
const EDGE_WINDOW: f64 = 3.0;

/// Sub-pixel edge points along radial profiles around a candidate circle. Each profile is read
/// twice: around the seed circle, then with its level windows re-centred on the edge found, so
/// the windows sit at the same depths whatever the seed's error (the rim correction assumes so).
fn subpixel_edges(lum: &Plane, c: &Candidate, sat: Option<f32>) -> Vec<(f64, f64)> {
    let n_angles = ((2.0 * PI * c.r).round() as usize).clamp(64, 1440);
    // per profile: direction, samples, inside level, outside level
    let mut profiles = Vec::with_capacity(n_angles);
    for k in 0..n_angles {
        let a = k as f64 * 2.0 * PI / n_angles as f64;
        let (ux, uy) = (a.cos(), a.sin());
        if let Some(p) = read_profile(lum, c.cx, c.cy, ux, uy, c.r, sat) {
            profiles.push((ux, uy, p));
        }
    }
    let mut contrasts: Vec<f64> = profiles.iter().map(|p| p.2.outside - p.2.inside).collect();
    let Some(global) = super::robust::median(&mut contrasts) else {
        return Vec::new();
    };
    let usable = |p: &Profile| {
        let contrast = p.outside - p.inside;
        // something much brighter than both sides (a highlight at the rim) spoils the profile
        let top = p.inside.max(p.outside) + contrast.abs();
        contrast * global > 0.0
            && contrast.abs() >= 0.3 * global.abs()
            && !p.samples.iter().any(|&v| v > top)
    };
    let mut points = Vec::new();
    for (ux, uy, first) in profiles {
        if !usable(&first) {
            continue;
        }
        let r1 = c.r + first.area_offset();
        let Some(second) = read_profile(lum, c.cx, c.cy, ux, uy, r1, sat) else {
            continue;
        };
        let offset = second.area_offset();
        if usable(&second) && offset.abs() < 1.0 {
            points.push((c.cx + (r1 + offset) * ux, c.cy + (r1 + offset) * uy));
        }
    }
    points
}

/// Samples of a radial profile every `PROFILE_STEP` px over `radius +- PROFILE_HALF`, with the
/// inside and outside levels (medians of the outer 3 px at either end).
struct Profile {
    samples: Vec<f64>,
    inside: f64,
    outside: f64,
}

const PROFILE_HALF: f64 = 6.0;
const PROFILE_STEP: f64 = 0.1;

fn read_profile(
    lum: &Plane,
    cx: f64,
    cy: f64,
    ux: f64,
    uy: f64,
    radius: f64,
    sat: Option<f32>,
) -> Option<Profile> {
    let ns = (2.0 * PROFILE_HALF / PROFILE_STEP).round() as usize + 1;
    let mut samples = Vec::with_capacity(ns);
    for j in 0..ns {
        let s = radius - PROFILE_HALF + j as f64 * PROFILE_STEP;
        let v = regions::bilinear(lum, cx + s * ux, cy + s * uy)?;
        if sat.is_some_and(|s| v >= 0.98 * s as f64) {
            return None;
        }
        samples.push(v);
    }
    let k = ((PROFILE_HALF - EDGE_WINDOW) / PROFILE_STEP).round() as usize;
    let inside = super::robust::median(&mut samples[..=k].to_vec())?;
    let outside = super::robust::median(&mut samples[ns - 1 - k..].to_vec())?;
    Some(Profile {
        samples,
        inside,
        outside,
    })
}

impl Profile {
    /// The area edge relative to the profile's middle (positive: outwards): where a sharp step
    /// between the two levels would hold the same light as the profile over the edge window. A
    /// lens blur or the pixel's area moves light across the edge but keeps its total, so this
    /// edge does not move with them, unlike a level crossing on a profile that is not a
    /// symmetric step (the Fresnel rim of a glossy sphere).
    fn area_offset(&self) -> f64 {
        let contrast = self.outside - self.inside;
        let first = ((PROFILE_HALF - EDGE_WINDOW) / PROFILE_STEP).round() as usize;
        let last = ((PROFILE_HALF + EDGE_WINDOW) / PROFILE_STEP).round() as usize;
        let u = |j: usize| (self.samples[j] - self.inside) / contrast;
        let area: f64 = (first..last)
            .map(|j| 0.5 * (u(j) + u(j + 1)) * PROFILE_STEP)
            .sum();
        // u = 0 inside, 1 outside: a step at offset e leaves area EDGE_WINDOW - e
        EDGE_WINDOW - area
    }
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
    // The half-peak region picks *which* highlight; its position comes from the whole lobe:
    // the region grown down to a few percent of its peak over the sphere's own radiance, each
    // pixel weighted by its excess. The tails carry the sub-pixel position, and any weight that
    // is a function of the brightness alone (clipping included) keeps the mean on the mirror
    // normal of an isotropic lobe.
    let background = radial_background(&eff, outline, intr, w, h);
    let excess = |i: usize| background[i].map(|b| f64::from(eff[i]) - b);
    let peak_excess = best
        .pixels
        .iter()
        .filter_map(|&i| excess(i))
        .fold(0.0f64, f64::max);
    let excess_all: Vec<f64> = (0..w * h).filter_map(excess).collect();
    let noise = super::robust::mad_sigma(&excess_all, 0.0).unwrap_or(0.0);
    let low = (LOBE_FRACTION * peak_excess).max(5.0 * noise);
    let lobe = regions::grow_region(&best.pixels, w, h, |i| excess(i).is_some_and(|e| e >= low));
    // per lobe pixel: position, sphere normal, normal-space area (1 / n.v), excess, clipped
    type LobePixel = (f64, f64, Vector3<f64>, f64, f64, bool);
    let mut px: Vec<LobePixel> = Vec::with_capacity(lobe.len());
    let mut peak_region = f32::MIN;
    for &i in &lobe {
        let (x, y) = ((i % w) as f64 + 0.5, (i / w) as f64 + 0.5);
        peak_region = peak_region.max(eff[i]);
        let ray = intr.ray(x, y);
        let e = excess(i).unwrap_or(0.0).max(1e-12);
        let clipped = sat.is_some_and(|s| maxc.data[i] >= s);
        match outline.intersect(&ray) {
            Some((_, n)) => px.push((x, y, n, 1.0 / n.dot(&-ray).max(0.05), e, clipped)),
            None => px.push((x, y, Vector3::zeros(), 0.0, e, clipped)),
        }
    }
    let saturated = px.iter().filter(|p| p.5).count();
    let sw: f64 = px.iter().map(|p| p.4).sum();
    let (x, y) = (
        px.iter().map(|p| p.4 * p.0).sum::<f64>() / sw,
        px.iter().map(|p| p.4 * p.1).sum::<f64>() / sw,
    );
    let mean_normal = |weight: &dyn Fn(&LobePixel) -> f64| {
        px.iter()
            .fold(Vector3::zeros(), |acc, p| acc + p.2 * (weight(p) * p.3))
    };
    let n_sum = mean_normal(&|p| p.4);
    if n_sum.norm() == 0.0 {
        return Err(SphereError::NoHighlight {
            reason: format!("the bright region at ({x:.1}, {y:.1}) px misses the sphere"),
        });
    }
    // The highlight's radiance is the lobe times the light's cosine n.l, which leans it towards
    // the light; divided by n.l (from the first estimate) it is the lobe alone. A clipped pixel
    // only bounds its lobe value from below, so every value is capped at the smallest such bound:
    // the weight is then a function of the lobe value alone, clipping or not.
    let first = n_sum.normalize();
    let v = -(outline.centre_in_radii() + first).normalize();
    let l = reflect(&first, &v).normalize();
    let cos_l = |p: &LobePixel| p.2.dot(&l).max(0.05);
    let cap = px
        .iter()
        .filter(|p| p.5)
        .map(|p| p.4 / cos_l(p))
        .fold(f64::INFINITY, f64::min);
    let n_sum = mean_normal(&|p| (p.4 / cos_l(p)).min(cap));
    Ok(Highlight {
        centroid_px: [x, y],
        normal: n_sum.normalize(),
        pixels: lobe.len(),
        saturated_pixels: saturated,
        peak: peak_region,
    })
}

/// How far down its peak (over the sphere's own radiance) the highlight's lobe is followed.
const LOBE_FRACTION: f64 = 0.02;

/// The sphere's own radiance without highlights, per pixel (`None` off the sphere): a low
/// quantile of the pixels at the same distance from the outline's centre. What a glossy sphere
/// shows besides the highlight (the mirrored backdrop brightening towards the rim, a dim diffuse
/// base) changes mostly with that distance, and a highlight covers only part of each ring.
fn radial_background(
    eff: &[f32],
    outline: &SphereOutline,
    intr: &Intrinsics,
    w: usize,
    h: usize,
) -> Vec<Option<f64>> {
    const MIN_PER_RING: usize = 16;
    let cos_a = outline.angular_radius_rad.cos();
    let rings = outline.radius_px.ceil().max(1.0) as usize;
    // ring index of each sphere pixel by the angle of its ray from the centre direction
    let mut ring_of = vec![None; w * h];
    let mut members: Vec<Vec<f64>> = vec![Vec::new(); rings];
    for y in 0..h {
        for x in 0..w {
            let ray = intr.ray(x as f64 + 0.5, y as f64 + 0.5);
            let c = ray.dot(&outline.centre_dir);
            if c <= cos_a {
                continue;
            }
            let frac = c.clamp(-1.0, 1.0).acos() / outline.angular_radius_rad;
            let r = ((frac * rings as f64) as usize).min(rings - 1);
            ring_of[y * w + x] = Some(r);
            members[r].push(f64::from(eff[y * w + x]));
        }
    }
    // rings near the centre hold few pixels: pool them outwards until each has enough
    let mut level = vec![None; rings];
    let mut pool: Vec<f64> = Vec::new();
    let mut pending = Vec::new();
    for (r, m) in members.iter().enumerate() {
        pool.extend_from_slice(m);
        pending.push(r);
        if pool.len() >= MIN_PER_RING || r + 1 == rings {
            let q = low_quantile(&mut pool);
            for p in pending.drain(..) {
                level[p] = q;
            }
            pool.clear();
        }
    }
    ring_of.iter().map(|r| r.and_then(|r| level[r])).collect()
}

/// The first quartile: robust to bright outliers covering up to three quarters of the values.
fn low_quantile(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    Some(values[(values.len() - 1) / 4])
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

    /// The rim offset against the rim profile of a true sphere seen in perspective: the radiance
    /// along an image radius from ray-sphere intersections, reduced to its area edge as
    /// `subpixel_edges` does (level windows 3 to 6 px either side of the edge). Spheres 5 to 12
    /// radii away, as a light probe is: the offset assumes the sphere seen from afar.
    #[test]
    fn rim_offset_matches_the_area_edge_of_a_perspective_fresnel_profile() {
        let f0 = 0.04;
        assert!(rim_edge_offset_px(40.0, 0.6).is_none());
        for (f, dist) in [(224.0, 12.0), (448.0, 12.0), (900.0, 12.0), (600.0, 5.0)] {
            let intr = Intrinsics::pinhole(2000, 2000, f, f, 1000.0, 1000.0);
            let centre = Vector3::new(0.0, 0.0, dist);
            let alpha = (1.0f64 / dist).asin();
            let r_true = alpha.tan() * f;
            let radiance = |rho: f64| {
                let ray = intr.ray(1000.0 + rho, 1000.0);
                let b = ray.dot(&centre);
                let disc = b * b - (centre.norm_squared() - 1.0);
                if disc < 0.0 {
                    return 1.0; // the backdrop
                }
                let n = (ray * (b - disc.sqrt()) - centre).normalize();
                let cos = n.dot(&-ray).max(0.0);
                let fr = f0 + (1.0 - f0) * (1.0 - cos).powi(5);
                0.01 + fr * (1.0 - 0.01)
            };
            let level = |from: f64, to: f64| {
                let mut v: Vec<f64> = (0..=300)
                    .map(|i| radiance(from + (to - from) * i as f64 / 300.0))
                    .collect();
                crate::calib::robust::median(&mut v).unwrap()
            };
            // windows re-centred on the edge found, as the detector's second reading does
            let mut edge = r_true;
            for _ in 0..20 {
                let (li, lo) = (level(edge - 6.0, edge - 3.0), level(edge + 3.0, edge + 6.0));
                let steps = 60_000;
                let h = 6.0 / steps as f64;
                let area: f64 = (0..steps)
                    .map(|i| (radiance(edge - 3.0 + (i as f64 + 0.5) * h) - li) / (lo - li) * h)
                    .sum();
                edge += 3.0 - area;
            }
            let depth = r_true - edge; // how far inside the true outline the area edge lies
            let want = rim_edge_offset_px(r_true, f0).unwrap();
            assert!(
                (depth - want).abs() < 0.02,
                "radius {r_true:.1} px: edge {depth:.4} px inside, predicted {want:.4}"
            );
            // and the correction restores the radius from the apparent outline
            let apparent_alpha = ((r_true - depth) / f).atan();
            let apparent = SphereOutline {
                centre_dir: Vector3::z(),
                angular_radius_rad: apparent_alpha,
                centre_px: [1000.0, 1000.0],
                radius_px: r_true - depth,
                edge_points: 100,
                rms_residual_rad: 0.0,
                source: OutlineSource::Detected,
            };
            let fixed = apparent.corrected_for_fresnel_rim(f0, &intr);
            assert!(
                (fixed.radius_px - r_true).abs() < 0.02,
                "{} vs {r_true}",
                fixed.radius_px
            );
        }
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
