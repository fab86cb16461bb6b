//! Finding the sphere's outline in an image. Candidate circles come from the image's edges
//! (`seed`: a Hough transform, so a holder, a post, a textured backdrop or the frame edge close
//! by do not bend them). Around each candidate, radial intensity profiles are fitted with the
//! rim model of a glossy sphere (`rim`); the profiles that fit it give sub-pixel edge points,
//! the others (across a holder, a highlight at the rim, a clipped pixel, something else in
//! front) are left out. The edge points are back-projected to rays and fitted with the tangent
//! cone ([`SphereOutline::from_edge_rays`]). The candidate whose outline most profiles support
//! is the sphere; it is measured a second time with the profiles centred on its outline.
//!
//! When no candidate is supported all round, or the outline leaves the frame, the error says
//! what was seen (where the best circle is and how much of it has an edge).
//!
//! Conventions: as `calib::sphere` (pixel centres at half-integers). Pure: no I/O.

use super::outline::tangent_ray;
use super::rim::{OUTSIDE_PX, RimModel};
use super::scale;
use super::seed::{self, Seed};
use super::{SphereError, SphereOptions, SphereOutline, check_size};
use crate::calib::regions::{self, Plane};
use crate::geometry::camera::Intrinsics;
use crate::render::image::LinearImage;
use nalgebra::Vector3;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Sampling step of the radial profiles (pixels).
const PROFILE_STEP: f64 = 0.1;
/// How far (pixels) the outline may lie from the seed circle along a profile; from the circle of
/// a fitted outline, in the final pass.
const SEARCH_PX: f64 = 3.0;
const FINAL_SEARCH_PX: f64 = 1.5;
/// Least step between the backdrop and the sphere, in residuals of the profile's fit: a smooth
/// shading or noise fits the model too, with no step to speak of.
const MIN_CONTRAST_RMS: f64 = 8.0;
/// Least fraction of the outline whose profiles must fit the rim model.
const MIN_SUPPORT: f64 = 0.3;
/// How far out (times the radius) an outline is looked for around a ring already found, and
/// the least step across it, relative to the ring's.
const OUTER_SEARCH: f64 = 1.3;
const MIN_OUTER_CONTRAST: f64 = 0.1;
/// Largest scatter (RMS) of the edge points about the fitted outline, in pixels and relative to
/// the outline's radius in pixels; the larger applies ([`max_outline_rms_px`]). A sphere's edge
/// points scatter by about 0.1 px (0.06 to 0.11 px on the Mitsuba fixtures, defocus and noise
/// included, radius about 60 px; 0.09 px on the 24 MP fixture, radius 1037 px); a rectangle's
/// sides near a circle scatter by a pixel or more at that radius (over 1.5 % of it), and by as
/// much relative to its size at any size. Telling a shape from a circle is a matter of relative
/// scatter, so above a radius of 125 px the limit grows with it (0.4 %); below, the absolute
/// 0.5 px leaves room for noise and aliasing.
const MAX_OUTLINE_RMS_PX: f64 = 0.5;
const MAX_OUTLINE_RMS_REL: f64 = 0.004;

/// The largest scatter (pixels) allowed about an outline of `radius_px`.
fn max_outline_rms_px(radius_px: f64) -> f64 {
    MAX_OUTLINE_RMS_PX.max(MAX_OUTLINE_RMS_REL * radius_px)
}
/// Most profiles around an outline (one per pixel of circumference below), and in the first
/// full-resolution pass of a large image, which only re-centres the final pass's windows.
const MAX_PROFILES: usize = 1440;
const FIRST_PASS_PROFILES: usize = 360;
/// Circle candidates tried.
const CANDIDATES: usize = 4;
/// At most this many profiles search the blur width; the rest use their median.
const BLUR_PROFILES: usize = 48;

/// Finds the sphere outline in an image where the sphere stands out from its surround (ambient
/// light with a lighter or darker backdrop, or the single-light image when its backdrop is lit).
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
    let lum = Plane::luminance(img);
    let f = scale::factor(w, h);
    if f == 1 {
        return locate(&lum, intr, opts);
    }
    // A large image: the outline is found on the image downsampled to about 500 px (a small
    // sphere: 1500 px), then measured again at full resolution along profiles across it (twice,
    // the second time centred on the first full-resolution fit), so that only a band around it
    // is read.
    let at = |f: usize| {
        let coarse_opts = SphereOptions {
            min_radius_px: (opts.min_radius_px / f as f64).max(3.0),
            ..*opts
        };
        locate(
            &lum.box_down(f),
            &scale::coarse_intrinsics(intr, f),
            &coarse_opts,
        )
    };
    let coarse = match (at(f), scale::retry_factor(w, h)) {
        (Err(SphereError::NoSphere { .. }), Some(finer)) => at(finer)?,
        (first, _) => first?,
    };
    let circle = outline_circle(&coarse, intr, w, h);
    let first = match measure(
        &lum,
        &Guide::along(&coarse, circle),
        SEARCH_PX,
        FIRST_PASS_PROFILES,
        None,
        intr,
        opts,
    ) {
        Some(m) if m.rms_px > max_outline_rms_px(m.outline.radius_px) => {
            return Err(not_a_sphere(&m));
        }
        Some(m) => m,
        None => return Err(no_sphere(&circle, None)),
    };
    // the final pass keeps the first's blur: the same lens on the same edge
    finish(&lum, intr, opts, &first.outline, &first, Some(first.sigma))
}

/// The outline in the image as given (the whole search: candidates, the outermost concentric
/// outline, the final measurement and the checks).
fn locate(
    lum: &Plane,
    intr: &Intrinsics,
    opts: &SphereOptions,
) -> Result<SphereOutline, SphereError> {
    let (w, h) = (lum.width, lum.height);
    let lo = regions::quantile(&lum.data, 0.001).unwrap_or(0.0);
    let hi = regions::quantile(&lum.data, 0.999).unwrap_or(0.0);
    if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
        return Err(SphereError::NoSphere {
            reason: "the image has no contrast to separate a sphere from its surround".into(),
        });
    }
    let r_max = 0.5 * w.min(h) as f64 + SEARCH_PX;
    let seeds = seed::circles(lum, opts.min_radius_px, r_max, CANDIDATES);
    let Some(&first) = seeds.first() else {
        return Err(SphereError::NoSphere {
            reason: format!(
                "the image has no round edge of radius {} to {r_max:.0} px",
                opts.min_radius_px
            ),
        });
    };
    let (measured, not_round): (Vec<Measured>, Vec<Measured>) = seeds
        .par_iter()
        .filter_map(|s| {
            measure(
                lum,
                &Guide::circle(*s),
                SEARCH_PX,
                MAX_PROFILES,
                None,
                intr,
                opts,
            )
        })
        .collect::<Vec<_>>()
        .into_iter()
        .partition(|m| m.rms_px <= max_outline_rms_px(m.outline.radius_px));
    let Some(best) = measured
        .iter()
        .max_by(|a, b| a.support.total_cmp(&b.support))
    else {
        return Err(
            match not_round
                .iter()
                .max_by(|a, b| a.support.total_cmp(&b.support))
            {
                Some(m) => not_a_sphere(m),
                None => no_sphere(&first, None),
            },
        );
    };
    // The sphere hides what lies behind it and everything on it lies inside its outline: of
    // the well supported circles concentric with the best one (a ring where the sphere mirrors
    // its backdrop's edge is one), the outline is the outermost.
    let concentric = |m: &Measured| {
        let (a, b) = (&m.outline, &best.outline);
        (a.centre_px[0] - b.centre_px[0]).hypot(a.centre_px[1] - b.centre_px[1]) < 0.2 * b.radius_px
    };
    let enough = MIN_SUPPORT.max(0.7 * best.support);
    let best = measured
        .iter()
        .filter(|m| m.support >= enough && concentric(m))
        .max_by(|a, b| a.outline.radius_px.total_cmp(&b.outline.radius_px))
        .unwrap_or(best);
    // A strong ring can hide a weaker outline outside it (a dark backdrop that the rim mirrors
    // out to some angle): look for a well supported edge further out, around the same centre,
    // with each search window clear of the edge already found.
    // The probes are independent: measured in parallel, the outermost that passes is taken.
    let inner = outline_circle(&best.outline, intr, w, h);
    let probes: Vec<f64> = (1..)
        .map(|step| inner.r + 1.5 + SEARCH_PX * step as f64)
        .take_while(|&r| r <= OUTER_SEARCH * inner.r)
        .collect();
    let outer = probes
        .par_iter()
        .filter_map(|&r| {
            let probe = Seed { r, ..inner };
            measure(
                lum,
                &Guide::circle(probe),
                SEARCH_PX,
                MAX_PROFILES,
                None,
                intr,
                opts,
            )
            .filter(|m| m.support >= enough && m.contrast >= MIN_OUTER_CONTRAST * best.contrast)
        })
        .collect::<Vec<_>>()
        .pop();
    let around = outer.as_ref().map_or(&best.outline, |m| &m.outline);
    finish(lum, intr, opts, around, best, None)
}

/// The outline measured once more with the profiles centred on `around`, and checked: enough
/// support, inside the frame; `fitted` stands when no profile fits there. `blur`: the profiles'
/// blur when already known, else searched again.
fn finish(
    lum: &Plane,
    intr: &Intrinsics,
    opts: &SphereOptions,
    around: &SphereOutline,
    fitted: &Measured,
    blur: Option<f64>,
) -> Result<SphereOutline, SphereError> {
    let (w, h) = (lum.width, lum.height);
    let circle = outline_circle(around, intr, w, h);
    let guide = Guide::along(around, circle);
    let (outline, support) =
        match measure(lum, &guide, FINAL_SEARCH_PX, MAX_PROFILES, blur, intr, opts) {
            Some(m) if m.rms_px > max_outline_rms_px(m.outline.radius_px) => {
                return Err(not_a_sphere(&m));
            }
            Some(m) => (m.outline, m.support),
            None => (fitted.outline.clone(), fitted.support),
        };
    if support < MIN_SUPPORT {
        return Err(no_sphere(&circle, Some(support)));
    }
    let cut = SphereError::SphereCut {
        cx: outline.centre_px[0],
        cy: outline.centre_px[1],
        radius_px: outline.radius_px,
        width: w,
        height: h,
    };
    // the fitted outline itself must lie inside the frame
    for i in 0..72 {
        let a = i as f64 * 2.0 * PI / 72.0;
        let inside = intr
            .project(&tangent_ray(&outline, a))
            .is_some_and(|(x, y)| x > 0.5 && y > 0.5 && x < w as f64 - 0.5 && y < h as f64 - 0.5);
        if !inside {
            return Err(cut);
        }
    }
    Ok(outline)
}

/// What "no sphere" saw: the best circle and how much of it had an edge.
fn no_sphere(s: &Seed, support: Option<f64>) -> SphereError {
    let fitted = match support {
        Some(f) => format!(
            "the profiles across it fit a sphere's rim on {:.0} % of it (at least {:.0} % needed)",
            100.0 * f,
            100.0 * MIN_SUPPORT
        ),
        None => "no profile across it fits a sphere's rim".into(),
    };
    SphereError::NoSphere {
        reason: format!(
            "the most round edge in the image, centred at ({:.1}, {:.1}) px with radius {:.1} px, \
             has an edge facing its centre in {:.0} % of the directions around it, and {fitted}",
            s.cx,
            s.cy,
            s.r,
            100.0 * s.coverage
        ),
    }
}

/// Edges were found around a circle but they do not lie on one: a rectangle, a polygon, a ring
/// of unrelated edges.
fn not_a_sphere(m: &Measured) -> SphereError {
    SphereError::NoSphere {
        reason: format!(
            "the best circle of edges, centred at ({:.1}, {:.1}) px with radius {:.1} px, has edges \
             on {:.0} % of it, but they scatter by {:.2} px about it where a sphere's outline \
             scatters by less than {:.2} px at that radius: what is there is not round (a board, \
             a box, a polygon?)",
            m.outline.centre_px[0],
            m.outline.centre_px[1],
            m.outline.radius_px,
            100.0 * m.support,
            m.rms_px,
            max_outline_rms_px(m.outline.radius_px)
        ),
    }
}

/// The circle through the projected outline (centre of its points, mean distance to them).
fn outline_circle(o: &SphereOutline, intr: &Intrinsics, w: usize, h: usize) -> Seed {
    let pts: Vec<(f64, f64)> = (0..90)
        .filter_map(|i| intr.project(&tangent_ray(o, i as f64 * 2.0 * PI / 90.0)))
        .collect();
    let n = pts.len().max(1) as f64;
    let (cx, cy) = pts
        .iter()
        .fold((0.0, 0.0), |(a, b), p| (a + p.0 / n, b + p.1 / n));
    let r = pts.iter().map(|p| (p.0 - cx).hypot(p.1 - cy)).sum::<f64>() / n;
    Seed {
        cx: cx.clamp(0.0, w as f64),
        cy: cy.clamp(0.0, h as f64),
        r,
        coverage: 1.0,
    }
}

/// Where the radial profiles of a measurement start and where along each the outline is
/// expected: on a circle (a Hough seed, a probe further out), or on a fitted outline. Under
/// perspective an outline is an ellipse, and the centroid of its points (the profiles' origin)
/// is not its centre: at 24 MP the sphere of the calibration fixtures lies 3 px further from that
/// origin on one side than on the other, and an ellipse's axes differ by 2 px, more than the
/// final pass's search window. Each profile's window is therefore centred on where the outline
/// crosses it.
struct Guide<'a> {
    circle: Seed,
    outline: Option<&'a SphereOutline>,
}

impl<'a> Guide<'a> {
    fn circle(circle: Seed) -> Self {
        Self {
            circle,
            outline: None,
        }
    }

    fn along(outline: &'a SphereOutline, circle: Seed) -> Self {
        Self {
            circle,
            outline: Some(outline),
        }
    }

    /// Distance (pixels) from the circle's centre to the expected outline in direction
    /// `(ux, uy)`: where the back-projected ray meets the outline's cone (secant steps on
    /// `ray . d - cos(alpha)`, which falls steadily outwards); the circle's radius when that
    /// fails (the centre outside the outline, a distortion model that folds).
    fn expected(&self, intr: &Intrinsics, ux: f64, uy: f64) -> f64 {
        let c = &self.circle;
        let Some(o) = self.outline else {
            return c.r;
        };
        let cos_a = o.angular_radius_rad.cos();
        let g = |s: f64| intr.ray(c.cx + s * ux, c.cy + s * uy).dot(&o.centre_dir) - cos_a;
        let (mut s0, mut s1) = (c.r, c.r + 1.0);
        let (mut g0, mut g1) = (g(s0), g(s1));
        for _ in 0..8 {
            let slope = g1 - g0;
            if slope.abs() < f64::MIN_POSITIVE || !slope.is_finite() {
                break;
            }
            let s2 = s1 - g1 * (s1 - s0) / slope;
            (s0, g0) = (s1, g1);
            s1 = s2;
            g1 = g(s1);
            if (s1 - s0).abs() < 1e-4 {
                break;
            }
        }
        if s1.is_finite() && (s1 - c.r).abs() < 0.5 * c.r {
            s1
        } else {
            c.r
        }
    }
}

/// How far (pixels) the outline may lie from a profile's steepest point: a glossy rim is
/// steepest just inside the outline, a blurred step at it.
const STEEPEST_TO_EDGE_PX: f64 = 1.5;

/// Where the profile changes fastest within `[lo, hi]` (central differences over 0.3 px).
fn steepest_point(positions: &[f64], samples: &[f64], lo: f64, hi: f64) -> Option<f64> {
    (3..samples.len().saturating_sub(3))
        .filter(|&j| positions[j] >= lo && positions[j] <= hi)
        .max_by(|&a, &b| {
            let slope = |j: usize| (samples[j + 3] - samples[j - 3]).abs();
            slope(a).total_cmp(&slope(b))
        })
        .map(|j| positions[j])
}

/// An outline measured around a candidate circle.
struct Measured {
    outline: SphereOutline,
    /// The blur (pixels) the profiles were fitted with.
    sigma: f64,
    /// Fraction of the profiles around the circle whose edge was kept by the fit.
    support: f64,
    /// Median step between backdrop and sphere across the kept profiles.
    contrast: f64,
    /// RMS distance (pixels) of the kept edge points from the fitted outline.
    rms_px: f64,
}

/// One radial profile: its direction, where the outline is expected along it, and its samples
/// at the measurement's offsets from there.
struct Profile {
    ux: f64,
    uy: f64,
    base: f64,
    samples: Vec<f64>,
}

/// Fits the rim model along radial profiles around `guide` and the tangent cone to their edges.
fn measure(
    lum: &Plane,
    guide: &Guide<'_>,
    search_px: f64,
    max_profiles: usize,
    blur: Option<f64>,
    intr: &Intrinsics,
    opts: &SphereOptions,
) -> Option<Measured> {
    let seed = &guide.circle;
    let fresnel_f0 = opts.rim_fresnel_f0.filter(|f| (0.0..0.5).contains(f));
    let model = RimModel::new(fresnel_f0, seed.r);
    // sample offsets from the expected outline (positive outwards)
    let (from, to) = (
        -(search_px + model.inside_px + 1.0),
        search_px + OUTSIDE_PX + 1.0,
    );
    if seed.r + from <= 1.0 {
        return None;
    }
    let ns = ((to - from) / PROFILE_STEP).round() as usize + 1;
    let positions: Vec<f64> = (0..ns).map(|j| from + j as f64 * PROFILE_STEP).collect();
    let n_angles = ((2.0 * PI * seed.r).round() as usize).clamp(64, max_profiles.max(64));
    let clip = opts.saturation.map(|s| 0.98 * f64::from(s));
    let profiles: Vec<Profile> = (0..n_angles)
        .into_par_iter()
        .filter_map(|k| {
            let a = k as f64 * 2.0 * PI / n_angles as f64;
            let (ux, uy) = (a.cos(), a.sin());
            let base = guide.expected(intr, ux, uy);
            if base + from <= 1.0 {
                return None;
            }
            let samples = positions
                .iter()
                .map(|&s| {
                    let s = base + s;
                    regions::bilinear(lum, seed.cx + s * ux, seed.cy + s * uy)
                })
                .collect::<Option<Vec<f64>>>()?;
            if clip.is_some_and(|c| samples.iter().any(|&v| v >= c)) {
                return None;
            }
            Some(Profile {
                ux,
                uy,
                base,
                samples,
            })
        })
        .collect();
    // Each profile's edge is searched within a pixel of its steepest point: the model fits a
    // flat stretch of backdrop perfectly, so a free search would wander off the edge.
    let range = |p: &Profile| {
        let steepest = steepest_point(&positions, &p.samples, -search_px, search_px)?;
        Some((
            steepest - STEEPEST_TO_EDGE_PX,
            steepest + STEEPEST_TO_EDGE_PX,
        ))
    };
    // the blur: given, or searched on a subset of the profiles, the median used for all
    let sigma = match blur {
        Some(s) => s,
        None => {
            let stride = (profiles.len() / BLUR_PROFILES).max(1);
            let mut sigmas: Vec<f64> = profiles
                .par_iter()
                .step_by(stride)
                .filter_map(|p| {
                    let (lo, hi) = range(p)?;
                    model.fit(&positions, &p.samples, lo, hi, None)
                })
                .map(|f| f.sigma)
                .collect();
            crate::stats::median(&mut sigmas)?
        }
    };
    let fits: Vec<(&Profile, super::rim::RimFit)> = profiles
        .par_iter()
        .filter_map(|p| {
            let (lo, hi) = range(p)?;
            model
                .fit(&positions, &p.samples, lo, hi, Some(sigma))
                .map(|f| (p, f))
        })
        .collect();
    // the sphere is darker (or brighter) than its surround all round: the majority decides
    let mut contrasts: Vec<f64> = fits.iter().map(|(_, f)| f.outside - f.inside).collect();
    let contrast = crate::stats::median(&mut contrasts)?;
    let mut rms: Vec<f64> = fits.iter().map(|(_, f)| f.rms).collect();
    let typical_rms = crate::stats::median(&mut rms)?;
    let kept: Vec<&(&Profile, super::rim::RimFit)> = fits
        .iter()
        .filter(|(p, f)| {
            let c = f.outside - f.inside;
            // something much brighter than both levels in the fitted stretch (a highlight at
            // the rim) spoils it
            let top = f.inside.max(f.outside) + c.abs();
            let window = f.edge - model.inside_px..=f.edge + OUTSIDE_PX;
            c * contrast > 0.0
                && c.abs() >= 0.3 * contrast.abs()
                && c.abs() >= MIN_CONTRAST_RMS * f.rms
                && f.rms <= 3.0 * typical_rms + 1e-6 * contrast.abs()
                && !positions
                    .iter()
                    .zip(&p.samples)
                    .any(|(x, &v)| window.contains(x) && v > top)
        })
        .collect();
    let rays: Vec<Vector3<f64>> = kept
        .iter()
        .map(|(p, f)| {
            let e = p.base + f.edge;
            intr.ray(seed.cx + e * p.ux, seed.cy + e * p.uy)
        })
        .collect();
    let mut steps: Vec<f64> = kept
        .iter()
        .map(|(_, f)| (f.outside - f.inside).abs())
        .collect();
    if rays.len() < 16 {
        return None;
    }
    let outline = SphereOutline::from_edge_rays(&rays, intr)?;
    let support = outline.edge_points as f64 / n_angles as f64;
    let rms_px = outline.rms_residual_rad * 0.5 * (intr.fx + intr.fy);
    Some(Measured {
        outline,
        sigma,
        support,
        rms_px,
        contrast: crate::stats::median(&mut steps)?,
    })
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;
    use crate::calib::sphere::OutlineSource;

    /// The 24 MP fixture's sphere (off the optical axis, radius 1037 px): the profiles' origin
    /// (the centroid of the outline's points) lies pixels off the ellipse's centre, so a circle
    /// about it misses the outline by more than the final search window on some sides, while
    /// the guide's expected distances land on the outline's cone.
    #[test]
    fn the_guide_follows_an_off_axis_outline_where_a_circle_does_not() {
        let f = 8666.666666666666;
        let intr = Intrinsics::pinhole(6000, 4000, f, f, 3021.6666666666665, 1981.6666666666667);
        let centre = Vector3::<f64>::new(0.025, -0.012, 0.42);
        let alpha = (0.05 / centre.norm()).asin();
        let outline = SphereOutline {
            centre_dir: centre.normalize(),
            angular_radius_rad: alpha,
            centre_px: [0.0; 2],
            radius_px: alpha.tan() * f,
            edge_points: 0,
            rms_residual_rad: 0.0,
            source: OutlineSource::Detected,
        };
        let circle = outline_circle(&outline, &intr, 6000, 4000);
        let guide = Guide::along(&outline, circle);
        let mut worst_circle = 0.0f64;
        for k in 0..360 {
            let a = (k as f64).to_radians();
            let (ux, uy) = (a.cos(), a.sin());
            let s = guide.expected(&intr, ux, uy);
            let on_cone = |s: f64| {
                let ray = intr.ray(circle.cx + s * ux, circle.cy + s * uy);
                (ray.dot(&outline.centre_dir).clamp(-1.0, 1.0).acos() - alpha) * f
            };
            // within a thousandth of a pixel of the outline
            assert!(on_cone(s).abs() < 1e-3, "angle {k}: {} px", on_cone(s));
            worst_circle = worst_circle.max((s - circle.r).abs());
        }
        assert!(worst_circle > FINAL_SEARCH_PX, "{worst_circle}");
        // a circle guide expects the circle
        assert_eq!(Guide::circle(circle).expected(&intr, 1.0, 0.0), circle.r);
    }
}
