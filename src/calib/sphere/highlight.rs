//! The specular highlight on the sphere, located in normal space (see `calib::sphere`).
//!
//! Conventions: as `calib::sphere`. Pure: no I/O.

use super::scale;
use super::uncertainty;
use super::{SphereError, SphereOptions, SphereOutline, check_size};
use crate::calib::regions::{self, Plane};
use crate::geometry::camera::Intrinsics;
use crate::geometry::reflect;
use crate::render::image::LinearImage;
use nalgebra::Vector3;
use rayon::prelude::*;

/// The specular highlight on the sphere.
#[derive(Clone, Debug, PartialEq)]
pub struct Highlight {
    /// Weighted image centroid of the highlight region (for reports).
    pub centroid_px: [f64; 2],
    /// Sphere normal at the highlight (weighted mean in normal space).
    pub normal: Vector3<f64>,
    /// RMS angle (radians) by which `normal` may be off from the highlight alone: its noise,
    /// its sampling and its lobe's shape (`uncertainty`).
    pub uncertainty_rad: f64,
    /// The lobe's width (pixels, RMS along its narrower axis).
    pub width_px: f64,
    /// Pixels in the highlight region, and how many of them are clipped.
    pub pixels: usize,
    pub saturated_pixels: usize,
    /// Brightest luminance in the region (the clip level when clipped).
    pub peak: f32,
    /// Unclipped pixels of the half-peak region that share its largest channel value: a
    /// plateau that a camera's clipping would make (the caller warns when no clip level was
    /// given; it is never taken for one).
    pub flat_top_pixels: usize,
}

/// Finds the highlight: among the connected regions above half way from the sphere's typical
/// level to its brightest pixel, centred on the sphere, the one with the largest summed excess
/// (so a small second highlight or a hot pixel loses to the real one). Clipped pixels count at
/// the clip level. Brighter things elsewhere in the frame (a lamp, a lit wall) are ignored; when
/// nothing on the sphere stands out but a compact bright spot lies off it, the outline and the
/// light image disagree: [`SphereError::HighlightOutsideSphere`].
/// On a large image only a window around the sphere is searched (`scale`), so a bright spot
/// far off the sphere is not reported as such.
pub fn find_highlight(
    img: &LinearImage,
    outline: &SphereOutline,
    intr: &Intrinsics,
    opts: &SphereOptions,
) -> Result<Highlight, SphereError> {
    check_size(img, intr, "the light image")?;
    let Some((crop, k, o, [x0, y0])) = scale::sphere_window(img, outline, intr) else {
        return find_in(img, outline, intr, opts);
    };
    let (dx, dy) = (x0 as f64, y0 as f64);
    match find_in(&crop, &o, &k, opts) {
        Ok(mut hl) => {
            hl.centroid_px[0] += dx;
            hl.centroid_px[1] += dy;
            Ok(hl)
        }
        Err(SphereError::HighlightAtRim {
            x,
            y,
            normal_from_view_deg,
        }) => Err(SphereError::HighlightAtRim {
            x: x + dx,
            y: y + dy,
            normal_from_view_deg,
        }),
        Err(SphereError::HighlightOutsideSphere { x, y, .. }) => {
            Err(SphereError::HighlightOutsideSphere {
                x: x + dx,
                y: y + dy,
                cx: outline.centre_px[0],
                cy: outline.centre_px[1],
                radius_px: outline.radius_px,
            })
        }
        Err(e) => Err(e),
    }
}

/// [`find_highlight`] in the image as given.
fn find_in(
    img: &LinearImage,
    outline: &SphereOutline,
    intr: &Intrinsics,
    opts: &SphereOptions,
) -> Result<Highlight, SphereError> {
    let (w, h) = (img.width(), img.height());
    let sat = opts.saturation;
    let lum = Plane::luminance(img);
    let maxc = Plane::max_channel(img);
    let cap = sat.unwrap_or(f32::INFINITY);
    let eff: Vec<f32> = lum.data.iter().map(|&v| v.min(cap)).collect();
    // the sphere's own pixels, two pixels in from the rim (rim pixels mix with the backdrop)
    let f = 0.5 * (intr.fx + intr.fy);
    let cos_inner = (outline.angular_radius_rad - 2.0 / f).max(0.0).cos();
    // each pixel's ray against the sphere's centre direction, once (rows in parallel)
    let cos_c: Vec<f64> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            intr.ray((i % w) as f64 + 0.5, (i / w) as f64 + 0.5)
                .dot(&outline.centre_dir)
        })
        .collect();
    let mut inside = Vec::new();
    let mut peak_inside = f32::MIN;
    for (&c, &v) in cos_c.iter().zip(&eff) {
        if c > cos_inner {
            inside.push(v as f64);
            peak_inside = peak_inside.max(v);
        }
    }
    let mut sorted = inside.clone();
    let level = crate::stats::median(&mut sorted).ok_or_else(|| SphereError::NoHighlight {
        reason: "the sphere covers no pixel".into(),
    })?;
    let sigma = crate::calib::robust::mad_sigma(&inside, level).unwrap_or(0.0);
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
                // a spot on the rim band itself: the light is behind the sphere
                let from_centre = intr
                    .ray(x, y)
                    .dot(&outline.centre_dir)
                    .clamp(-1.0, 1.0)
                    .acos();
                if (from_centre - outline.angular_radius_rad).abs() <= RIM_BAND_PX / f {
                    return Err(at_rim(outline, intr, x, y));
                }
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
        let cos_a = outline.angular_radius_rad.cos();
        let pixel_on = |i: &&usize| cos_c[**i] > cos_a;
        outline.contains_pixel(intr, x, y)
            && 2 * c.pixels.iter().filter(pixel_on).count() >= c.pixels.len()
    };
    let best = bright_regions(&eff, w, h, thr)
        .into_iter()
        .filter(|(c, (x, y), _)| on_sphere(c, *x, *y))
        .max_by(|a, b| a.2.total_cmp(&b.2))
        .map(|(c, xy, _)| (c, xy))
        .ok_or_else(|| SphereError::NoHighlight {
            reason: "no bright region is centred on the sphere".into(),
        })?;
    let best_xy = best.1;
    let best = best.0;
    // The half-peak region picks *which* highlight; its position comes from the whole lobe:
    // the region grown down to a few percent of its peak over the sphere's own radiance, each
    // pixel weighted by its excess. The tails carry the sub-pixel position, and any weight that
    // is a function of the brightness alone (clipping included) keeps the mean on the mirror
    // normal of an isotropic lobe.
    let background = RadialBackground::new(&eff, &cos_c, outline);
    let excess = |i: usize| background.at(i).map(|b| f64::from(eff[i]) - b);
    let peak_excess = best
        .pixels
        .iter()
        .filter_map(|&i| excess(i))
        .fold(0.0f64, f64::max);
    let excess_all: Vec<f64> = (0..w * h).filter_map(excess).collect();
    let noise = crate::calib::robust::mad_sigma(&excess_all, 0.0).unwrap_or(0.0);
    let low = (LOBE_FRACTION * peak_excess).max(5.0 * noise);
    // A highlight on the rim is cut by the limb and seen edge-on: a pixel there spans degrees
    // of normal, and its lobe's centre cannot be found.
    let rim_gap = RIM_BAND_PX / f;
    let on_rim = best
        .pixels
        .iter()
        .any(|&i| cos_c[i].clamp(-1.0, 1.0).acos() > outline.angular_radius_rad - rim_gap);
    if on_rim {
        return Err(at_rim(outline, intr, best_xy.0, best_xy.1));
    }
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
    let weight = |p: &LobePixel| (p.4 / cos_l(p)).min(cap);
    let n_sum = mean_normal(&weight);
    let normal = n_sum.normalize();
    // how far that mean may be off (`uncertainty`): each pixel's weight and its noise (none
    // where the cap holds it), the view at the highlight, a pixel's span of normal there
    let samples: Vec<uncertainty::LobePixel> = px
        .iter()
        .filter(|p| p.3 > 0.0)
        .map(|p| uncertainty::LobePixel {
            x: p.0,
            y: p.1,
            normal: p.2,
            weight: weight(p) * p.3,
            weight_sigma: noise / cos_l(p) * p.3,
            capped: p.4 / cos_l(p) >= cap,
        })
        .collect();
    let view = -(outline.centre_in_radii() + normal).normalize();
    let normal_per_px = 1.0 / (outline.radius_px.max(1.0) * normal.dot(&view).max(0.05));
    let (uncertainty_rad, width_px) =
        uncertainty::highlight_rms_rad(&samples, &normal, &view, normal_per_px);
    let top = best
        .pixels
        .iter()
        .map(|&i| maxc.data[i])
        .fold(f32::MIN, f32::max);
    let flat_top_pixels = best
        .pixels
        .iter()
        .filter(|&&i| maxc.data[i] >= top && sat.is_none_or(|s| maxc.data[i] < s))
        .count();
    Ok(Highlight {
        centroid_px: [x, y],
        normal,
        uncertainty_rad,
        width_px,
        pixels: lobe.len(),
        saturated_pixels: saturated,
        peak: peak_region,
        flat_top_pixels,
    })
}

/// The error for a highlight at `(x, y)` on the rim, with the angle of the sphere's normal there
/// from the view (90 deg just outside the outline).
fn at_rim(outline: &SphereOutline, intr: &Intrinsics, x: f64, y: f64) -> SphereError {
    let normal_from_view_deg = outline
        .intersect(&intr.ray(x, y))
        .map(|(p, n)| n.dot(&-p.normalize()).clamp(-1.0, 1.0).acos().to_degrees())
        .unwrap_or(90.0);
    SphereError::HighlightAtRim {
        x,
        y,
        normal_from_view_deg,
    }
}

/// Width (pixels) of the band along the outline where a highlight cannot be measured: a pixel
/// there spans many degrees of normal.
const RIM_BAND_PX: f64 = 2.0;

/// How far down its peak (over the sphere's own radiance) the highlight's lobe is followed.
const LOBE_FRACTION: f64 = 0.02;

/// The sphere's own radiance without highlights, per pixel (`None` off the sphere): a low
/// quantile of the pixels at the same distance from the outline's centre. What a glossy sphere
/// shows besides the highlight (the mirrored backdrop brightening towards the rim, a dim diffuse
/// base) changes mostly with that distance, and a highlight covers only part of each ring.
struct RadialBackground {
    /// Ring of each pixel (`u32::MAX` off the sphere) and each ring's level.
    ring_of: Vec<u32>,
    level: Vec<Option<f64>>,
}

impl RadialBackground {
    /// From the effective luminance and each pixel's ray cosine to the centre direction.
    fn new(eff: &[f32], cos_c: &[f64], outline: &SphereOutline) -> Self {
        const MIN_PER_RING: usize = 16;
        let cos_a = outline.angular_radius_rad.cos();
        let rings = outline.radius_px.ceil().max(1.0) as usize;
        // ring index of each sphere pixel by the angle of its ray from the centre direction
        let mut ring_of = vec![u32::MAX; eff.len()];
        let mut members: Vec<Vec<f64>> = vec![Vec::new(); rings];
        for (i, &c) in cos_c.iter().enumerate() {
            if c <= cos_a {
                continue;
            }
            let frac = c.clamp(-1.0, 1.0).acos() / outline.angular_radius_rad;
            let r = ((frac * rings as f64) as usize).min(rings - 1);
            ring_of[i] = r as u32;
            members[r].push(f64::from(eff[i]));
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
        Self { ring_of, level }
    }

    /// The level at pixel `i`; `None` off the sphere.
    fn at(&self, i: usize) -> Option<f64> {
        let r = *self.ring_of.get(i)?;
        self.level.get(r as usize).copied().flatten()
    }
}

/// The first quartile: robust to bright outliers covering up to three quarters of the values.
fn low_quantile(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let i = (values.len() - 1) / 4;
    Some(*values.select_nth_unstable_by(i, f64::total_cmp).1)
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
