//! What a radial intensity profile looks like across the outline of a glossy sphere, and the fit
//! of the outline's position to it.
//!
//! Physics. Near its silhouette a glossy sphere mirrors what lies just behind it, which is the
//! backdrop seen beside it, with a Fresnel reflectance rising to 1 at grazing: its rim fades into
//! the backdrop, brighter or darker than the sphere's middle. At depth `d` (pixels inside the
//! outline of radius `R`) the radiance is `D + (B - D) g(d)`: `B` the backdrop's radiance, `D`
//! what the sphere shows where it barely mirrors the backdrop (its diffuse base and what it
//! mirrors further in), and `g = (F - f0) / (1 - f0)` with `F` the dielectric's Fresnel
//! reflectance (unpolarised, exact; its refractive index from `f0`) at
//! `n.v = sqrt(1 - (1 - d/R)^2)` (a sphere seen from afar). `g` depends little on `f0` (under
//! Schlick's approximation, `(1 - n.v)^5`, not at all), so the default serves black plastic and
//! glass alike. Outside the outline the profile is `B`. A matte outline image, or a metal whose
//! rim does not fade, is a step: `g = 0` inside.
//! The lens, the pixel's area and the bilinear sampling blur the profile by about a Gaussian of
//! width `sigma`, fitted.
//!
//! Where the model holds: the rim mirrors the backdrop only out to some angle from the line of
//! sight; deeper in it mirrors the room beside or behind the backdrop. So the fit uses the band
//! where the reflection stays within 40 degrees of the line of sight (`d < R (1 - cos 20 deg)`,
//! less two blur widths, which the blur spreads the room beyond it into; at least 2 px) and 4 px
//! of backdrop outside, with a linear trend across the window for a
//! backdrop or light that varies across the edge. `D`, `B` and the trend are solved linearly for
//! each trial position; the position and `sigma` by search (coarse grid, then fine).
//!
//! Not modelled: a rough coat's rim is weaker near grazing (its microfacets shadow each other),
//! which the fit reads as an outline slightly too large: +0.03 to +0.09 px for GGX roughness 0.01
//! to 0.03, +0.21 px for 0.08, on the Mitsuba fixtures (docs/calibration.md).
//!
//! Conventions: profile positions in pixels along the outward radial direction. Pure: no I/O.

use nalgebra::{Matrix3, Vector3};

/// Blur widths (pixels) the fit tries: from a sharp lens with pixel-area integration and
/// bilinear sampling (about 0.4 px) to a clearly defocused one.
const SIGMAS: [f64; 18] = [
    0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.15, 1.3, 1.45, 1.6, 1.8, 2.0, 2.25, 2.5, 2.75, 3.0,
];

/// Backdrop kept outside the outline for the fit (pixels).
pub(super) const OUTSIDE_PX: f64 = 4.0;

/// Table step of the blurred shapes (pixels).
const TABLE_STEP: f64 = 0.02;
/// Depth range of the raw shape: from `-TABLE_OUT` (outside) to `TABLE_IN` (inside), deeper for a
/// large sphere whose band runs further in.
const TABLE_OUT: f64 = 12.0;
const TABLE_IN: f64 = 40.0;

/// The blurred edge shapes `(g * Gaussian_sigma)(depth)` for one outline radius, per sigma.
pub(super) struct RimModel {
    /// Depth of the band where the model holds (pixels inside the outline).
    pub inside_px: f64,
    /// Per sigma, the blurred shape on the grid `depth = i TABLE_STEP - TABLE_OUT` from index
    /// `first` on: the depths the fits read.
    first: usize,
    tables: Vec<Vec<f64>>,
}

/// The fitted edge of one profile.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct RimFit {
    /// Position of the outline along the profile (pixels, same origin as the samples).
    pub edge: f64,
    pub sigma: f64,
    /// `D` and `B` of the model: the levels just inside and outside.
    pub inside: f64,
    pub outside: f64,
    /// RMS residual of the fit.
    pub rms: f64,
}

impl RimModel {
    /// The shapes for an outline of `radius_px`; `fresnel_f0`: the fade of a glossy dielectric
    /// of that normal-incidence reflectance (below 0.5), else (`None`) a step.
    pub fn new(fresnel_f0: Option<f64>, radius_px: f64) -> Self {
        let r = radius_px.max(4.0);
        let inside_px = if fresnel_f0.is_some() {
            (r * (1.0 - 20f64.to_radians().cos())).max(2.0)
        } else {
            3.0
        };
        // the shape on the table's grid, deep enough that the blur of the band's deepest
        // samples reads the shape itself (a large sphere's band runs past TABLE_IN)
        let blur_reach = 4.0 * SIGMAS[SIGMAS.len() - 1] + 1.0;
        let table_in = TABLE_IN.max(inside_px + blur_reach);
        let n = ((TABLE_OUT + table_in) / TABLE_STEP).round() as usize + 1;
        let depth = |i: usize| i as f64 * TABLE_STEP - TABLE_OUT;
        let raw: Vec<f64> = (0..n).map(|i| shape(fresnel_f0, r, depth(i))).collect();
        // only the entries the fits read are blurred: depths from -OUTSIDE_PX to the band's
        // depth, two steps spare each side
        let lo = (((TABLE_OUT - OUTSIDE_PX) / TABLE_STEP).floor() as usize).saturating_sub(2);
        let hi = (((TABLE_OUT + inside_px) / TABLE_STEP).ceil() as usize + 2).min(n - 1);
        let tables = SIGMAS
            .iter()
            .map(|&sigma| {
                let half = (4.0 * sigma / TABLE_STEP).ceil() as i64;
                let weights: Vec<f64> = (-half..=half)
                    .map(|k| (-0.5 * (k as f64 * TABLE_STEP / sigma).powi(2)).exp())
                    .collect();
                let total: f64 = weights.iter().sum();
                (lo as i64..=hi as i64)
                    .map(|i| {
                        let mut acc = 0.0;
                        for (j, w) in (-half..=half).zip(&weights) {
                            // beyond the table: 1 outside, the deepest value inside
                            let k = (i + j).clamp(0, n as i64 - 1) as usize;
                            acc += w * raw[k];
                        }
                        acc / total
                    })
                    .collect()
            })
            .collect();
        Self {
            inside_px,
            first: lo,
            tables,
        }
    }

    /// The blurred shape at `depth` (pixels inside the outline; negative outside).
    fn blurred(&self, sigma_index: usize, depth: f64) -> f64 {
        let t = &self.tables[sigma_index];
        let (lo, hi) = (self.first, self.first + t.len() - 1);
        let x = ((depth + TABLE_OUT) / TABLE_STEP).clamp(lo as f64, hi as f64);
        // x >= 0: truncation is the floor (and needs no call into libm)
        let i = (x as usize).min(hi - 1);
        let f = x - i as f64;
        t[i - lo] * (1.0 - f) + t[i + 1 - lo] * f
    }

    /// Sum of squared residuals of the best linear fit (`D`, `B`, trend) with the outline at
    /// `edge`: `(sse, D, B, samples used)`. `positions[j]` is where `samples[j]` lies.
    fn sse_at(
        &self,
        positions: &[f64],
        samples: &[f64],
        sigma_index: usize,
        edge: f64,
    ) -> Option<(f64, f64, f64, usize)> {
        // the six distinct entries of A^T A, A^T p and p.p, summed over the window
        let (mut a00, mut a01, mut a02, mut a11, mut a12, mut a22) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let mut atb = Vector3::<f64>::zeros();
        let mut rows = 0;
        let mut sum_pp = 0.0;
        // the blur spreads what lies beyond the band (the room the rim mirrors further in) over
        // about two sigmas into it: those samples are left out
        let inside = (self.inside_px - 2.0 * SIGMAS[sigma_index]).max(2.0);
        // positions ascend: only the window (one sample wider each side, the test decides) is
        // visited
        let first = positions
            .partition_point(|&s| s < edge - inside)
            .saturating_sub(1);
        let last =
            (positions.partition_point(|&s| s <= edge + OUTSIDE_PX) + 1).min(positions.len());
        for (&s, &p) in positions[first..last].iter().zip(&samples[first..last]) {
            let depth = edge - s;
            if depth > inside || depth < -OUTSIDE_PX {
                continue;
            }
            let b = self.blurred(sigma_index, depth);
            let (r0, r1, r2) = (1.0 - b, b, s - edge);
            a00 += r0 * r0;
            a01 += r0 * r1;
            a02 += r0 * r2;
            a11 += r1 * r1;
            a12 += r1 * r2;
            a22 += r2 * r2;
            atb += Vector3::new(r0 * p, r1 * p, r2 * p);
            sum_pp += p * p;
            rows += 1;
        }
        let ata = Matrix3::new(a00, a01, a02, a01, a11, a12, a02, a12, a22);
        if rows < 8 {
            return None;
        }
        let coef = ata.try_inverse()? * atb;
        // sse = p.p - 2 c.A^T p + c.A^T A c = p.p - c.A^T p at the least-squares solution
        let sse = (sum_pp - coef.dot(&atb)).max(0.0);
        Some((sse, coef[0], coef[1], rows))
    }

    /// The best edge position in `[lo, hi]` for one blur: a 0.1 px scan, then 0.01 px around
    /// the best. `None` when the best lies on the range's boundary (no edge inside it).
    fn best_edge(
        &self,
        positions: &[f64],
        samples: &[f64],
        sigma_index: usize,
        lo: f64,
        hi: f64,
    ) -> Option<RimFit> {
        let scan = |from: f64, to: f64, step: f64| {
            let n = ((to - from) / step).round() as usize;
            let mut best: Option<(f64, f64, f64, f64, usize)> = None;
            for k in 0..=n {
                let e = from + k as f64 * step;
                if let Some((sse, d, b, rows)) = self.sse_at(positions, samples, sigma_index, e) {
                    // compare as mean squares: the window holds a varying number of samples
                    let ms = sse / rows as f64;
                    if best.is_none_or(|x| ms < x.1) {
                        best = Some((e, ms, d, b, rows));
                    }
                }
            }
            best
        };
        let (coarse, ..) = scan(lo, hi, 0.1)?;
        if coarse <= lo + 0.05 || coarse >= hi - 0.05 {
            return None;
        }
        let (edge, ms, inside, outside, _) = scan(coarse - 0.1, coarse + 0.1, 0.01)?;
        Some(RimFit {
            edge,
            sigma: SIGMAS[sigma_index],
            inside,
            outside,
            rms: ms.sqrt(),
        })
    }

    /// Fits the edge of one profile in `[lo, hi]`, with the blur given (`sigma`, one of the
    /// fitted values) or searched.
    pub fn fit(
        &self,
        positions: &[f64],
        samples: &[f64],
        lo: f64,
        hi: f64,
        sigma: Option<f64>,
    ) -> Option<RimFit> {
        match sigma {
            Some(s) => {
                let i = SIGMAS
                    .iter()
                    .enumerate()
                    .min_by(|a, b| (a.1 - s).abs().total_cmp(&(b.1 - s).abs()))
                    .map(|(i, _)| i)?;
                self.best_edge(positions, samples, i, lo, hi)
            }
            None => (0..SIGMAS.len())
                .filter_map(|i| self.best_edge(positions, samples, i, lo, hi))
                .min_by(|a, b| a.rms.total_cmp(&b.rms)),
        }
    }
}

/// The unblurred shape `g` at `depth`: 1 outside (the backdrop), the Fresnel fade or 0 inside.
fn shape(fresnel_f0: Option<f64>, radius: f64, depth: f64) -> f64 {
    if depth <= 0.0 {
        return 1.0;
    }
    let Some(f0) = fresnel_f0 else {
        return 0.0;
    };
    let t = 1.0 - (depth / radius).min(1.0);
    let cos = (1.0 - t * t).max(0.0).sqrt();
    let f0 = f0.clamp(1e-6, 0.49);
    ((fresnel_dielectric(cos, f0) - f0) / (1.0 - f0)).clamp(0.0, 1.0)
}

/// Unpolarised Fresnel reflectance of a dielectric at incidence cosine `cos`, its refractive
/// index from the normal-incidence reflectance `f0`: `n = (1 + sqrt f0) / (1 - sqrt f0)`.
pub(super) fn fresnel_dielectric(cos: f64, f0: f64) -> f64 {
    let n = (1.0 + f0.sqrt()) / (1.0 - f0.sqrt());
    let cos = cos.clamp(1e-9, 1.0);
    let cos_t = (1.0 - (1.0 - cos * cos) / (n * n)).max(0.0).sqrt();
    let rs = (cos - n * cos_t) / (cos + n * cos_t);
    let rp = (n * cos - cos_t) / (n * cos + cos_t);
    0.5 * (rs * rs + rp * rp)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;
    use crate::geometry::camera::Intrinsics;

    /// A perspective-exact rim profile (rays through a true sphere, Schlick Fresnel mirroring a
    /// backdrop out to 40 deg from the line of sight and a brighter room beyond, pixel-area
    /// integrated and blurred): the fit finds the true outline to a few hundredths of a pixel,
    /// where a half-level crossing lies most of a pixel inside.
    #[test]
    fn the_fit_finds_the_outline_of_a_rendered_fresnel_rim() {
        // the bound: what the band's lower edge lets in of the room mirrored further in; a
        // defocused lens spreads it over more than the band at 43 px (0.21 px measured)
        for (f, dist, blur, (d_level, b_level), bound) in [
            (600.0, 14.0, 0.5, (0.03, 0.3), 0.04),
            (1200.0, 14.0, 0.8, (0.03, 0.3), 0.04),
            (300.0, 8.0, 0.4, (0.5, 0.05), 0.04), // a sphere brighter than a dark backdrop
            (600.0, 14.0, 1.8, (0.03, 0.3), 0.25), // defocused
        ] {
            let intr = Intrinsics::pinhole(4000, 10, f, f, 2000.0, 5.0);
            let centre = Vector3::new(0.0, 0.0, dist);
            let r_true = (1.0f64 / dist).asin().tan() * f;
            let f0 = 0.04;
            // continuous radiance along the image row through the centre
            let radiance = |rho: f64| {
                let ray = intr.ray(2000.0 + rho, 5.0);
                let b = ray.dot(&centre);
                let disc = b * b - (centre.norm_squared() - 1.0);
                if disc < 0.0 {
                    return b_level;
                }
                let n = (ray * (b - disc.sqrt()) - centre).normalize();
                let cos = n.dot(&-ray).max(0.0);
                let fr = fresnel_dielectric(cos, f0);
                // the mirrored direction's angle from the line of sight: backdrop within 40 deg
                let deviation = 2.0 * cos.asin();
                let mirrored = if deviation < 40f64.to_radians() {
                    b_level
                } else {
                    2.0 * b_level
                };
                d_level + fr * (mirrored - d_level)
            };
            // pixel integration (1 px box, 20 sub-samples) and a Gaussian blur, sampled at 0.1 px
            let pixel = |x: f64| {
                (0..20)
                    .map(|k| radiance(x - 0.5 + (k as f64 + 0.5) / 20.0))
                    .sum::<f64>()
                    / 20.0
            };
            let blurred = |x: f64| {
                let (mut acc, mut tot) = (0.0, 0.0);
                for k in -40..=40 {
                    let u = k as f64 * 0.1;
                    let w = (-0.5 * (u / blur).powi(2)).exp();
                    acc += w * pixel(x + u);
                    tot += w;
                }
                acc / tot
            };
            let positions: Vec<f64> = (0..140).map(|j| r_true - 8.0 + j as f64 * 0.1).collect();
            let samples: Vec<f64> = positions.iter().map(|&x| blurred(x)).collect();
            let model = RimModel::new(Some(f0), r_true);
            let fit = model
                .fit(&positions, &samples, r_true - 2.5, r_true + 2.5, None)
                .unwrap();
            println!(
                "R {r_true:.1} px, blur {blur}: edge {:+.3} px from the truth",
                fit.edge - r_true
            );
            assert!(
                (fit.edge - r_true).abs() < bound,
                "R {r_true:.1} px, blur {blur}: edge {:.3} px from the truth",
                fit.edge - r_true
            );
            // the half-level crossing, for comparison, lies well inside
            let half = 0.5 * (d_level + b_level);
            let crossing = positions
                .iter()
                .zip(&samples)
                .find(|(_, v)| (**v - half) * (b_level - d_level) > 0.0)
                .map(|(x, _)| *x)
                .unwrap();
            assert!(r_true - crossing > 0.3, "crossing {:.3}", r_true - crossing);
        }
    }

    /// A plain blurred step (a matte outline): the step model finds it; the Fresnel model,
    /// wrongly assumed, is biased outwards.
    #[test]
    fn a_step_is_found_by_the_step_model() {
        let edge = 30.37;
        let positions: Vec<f64> = (0..140).map(|j| 22.0 + j as f64 * 0.1).collect();
        let samples: Vec<f64> = positions
            .iter()
            .map(|&x| {
                let z = (x - edge) / 0.7;
                0.1 + 0.5 * 0.5 * (1.0 + erf(z / std::f64::consts::SQRT_2))
            })
            .collect();
        let step = RimModel::new(None, 40.0)
            .fit(&positions, &samples, 27.0, 33.0, None)
            .unwrap();
        assert!((step.edge - edge).abs() < 0.02, "{step:?}");
        assert!((step.sigma - 0.7).abs() < 0.11 && (step.outside - 0.6).abs() < 0.01);
        let fresnel = RimModel::new(Some(0.04), 40.0)
            .fit(&positions, &samples, 27.0, 33.0, None)
            .unwrap();
        assert!(fresnel.rms > 3.0 * step.rms.max(1e-6));
    }

    /// The exact Fresnel reflectance against textbook values for glass (n = 1.5).
    #[test]
    fn fresnel_of_glass() {
        assert!((fresnel_dielectric(1.0, 0.04) - 0.04).abs() < 1e-12);
        // 60 deg: Rs 0.1766, Rp 0.0018 (Hecht)
        assert!((fresnel_dielectric(0.5, 0.04) - 0.5 * (0.1766 + 0.0018)).abs() < 2e-4);
        assert!(fresnel_dielectric(1e-6, 0.04) > 0.999);
    }

    /// Abramowitz-Stegun 7.1.26 (|error| < 1.5e-7), for the test's blurred step.
    fn erf(x: f64) -> f64 {
        let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
        let y = 1.0
            - (((((1.061_405_429 * t - 1.453_152_027) * t) + 1.421_413_741) * t - 0.284_496_736)
                * t
                + 0.254_829_592)
                * t
                * (-x * x).exp();
        y.copysign(x)
    }
}
