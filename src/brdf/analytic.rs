//! Analytic baselines: Lambert, and Lambert + isotropic GGX with Schlick Fresnel, each with a
//! least-squares fit to observed reflectances: what users would otherwise fit to their pixels,
//! and what the data-driven reconstruction must beat.
//!
//! Model, per channel `c` (f_r in 1/sr, no cosine):
//! `f_c = kd_c / pi + ks_c D(h) G(wi, wo) F(wi.h) / (4 cos_i cos_o)`, with
//! `D = a^2 / (pi (cos^2 theta_h (a^2 - 1) + 1)^2)` (GGX, `a` = roughness alpha),
//! `G = G1(wi) G1(wo)`, `G1(v) = 2 cos / (cos + sqrt(a^2 + (1 - a^2) cos^2))` (separable Smith),
//! `F = F0 + (1 - F0)(1 - wi.h)^5` (Schlick, one F0 for all channels; the colour of the
//! highlight is in `ks`).
//!
//! Fits minimise the sum of squared differences in f_r over all observations and channels,
//! optionally weighted per observation (e.g. by the cosine map, to fit what images see).
//! Lambert: `kd_c = pi mean(r_c)`, closed form (or a weighted median, robust to outlying
//! pixels: the reconstruction's own Lambert rung, `reconstruct::lambert_rung`). Lambert + GGX: `kd` and `ks` are linear and
//! solved in closed form for each `(alpha, F0)`, bounded to `[0, 1]` per channel
//! ([`MAX_WEIGHT`]: a physical albedo, and what a material editor allows); those two are found
//! by a grid search followed by Nelder-Mead. Directions as in [`crate::brdf`]: local frame, n = +z.
//! Pure: no files; must not depend on the network, the basis (beyond its cosine-map floor, so
//! the weighted fit and the cosine-weighted error agree) or any I/O.

use super::Brdf;
use nalgebra::Vector3;
use std::f64::consts::PI;

/// One observation: f_r (1/sr, RGB) for the pair `(wi, wo)` (unit vectors, local frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReflectanceSample {
    pub wi: Vector3<f64>,
    pub wo: Vector3<f64>,
    pub rgb: [f64; 3],
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FitError {
    #[error("no observations above the horizon to fit")]
    Empty,
    #[error("an observation is not finite")]
    NonFinite,
}

/// A Lambertian BRDF, `albedo / pi`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lambert {
    pub albedo: [f64; 3],
}

impl Brdf for Lambert {
    fn eval_local(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> [f64; 3] {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return [0.0; 3];
        }
        self.albedo.map(|a| a / PI)
    }
}

/// Lambert + GGX (see the module header).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LambertGgx {
    pub kd: [f64; 3],
    pub ks: [f64; 3],
    /// GGX roughness alpha (> 0).
    pub alpha: f64,
    /// Schlick reflectance at normal incidence, in [0, 1].
    pub f0: f64,
}

/// The GGX normal distribution at `cos theta_h`.
pub fn ggx_d(cos_h: f64, alpha: f64) -> f64 {
    let a2 = alpha * alpha;
    let t = cos_h * cos_h * (a2 - 1.0) + 1.0;
    a2 / (PI * t * t)
}

fn smith_g1(cos: f64, alpha: f64) -> f64 {
    let a2 = alpha * alpha;
    2.0 * cos / (cos + (a2 + (1.0 - a2) * cos * cos).sqrt())
}

/// The specular lobe without its colour: `D G F / (4 cos_i cos_o)`; zero below the horizon.
pub fn ggx_lobe(wi: &Vector3<f64>, wo: &Vector3<f64>, alpha: f64, f0: f64) -> f64 {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return 0.0;
    }
    LobeGeometry::new(wi, wo).lobe(alpha, f0)
}

/// What [`ggx_lobe`] needs of a pair of directions above the horizon, computed once: a fit
/// evaluates the lobe at the same directions for hundreds of (alpha, F0), and the half vector
/// and Schlick's power are most of an evaluation. [`Self::lobe`] is `ggx_lobe`, bit for bit.
#[derive(Clone, Copy, Debug)]
struct LobeGeometry {
    cos_h: f64,
    cos_i: f64,
    cos_o: f64,
    /// `(1 - wi . h)^5`, Schlick's factor.
    schlick: f64,
    /// `4 cos_i cos_o`.
    denominator: f64,
}

impl LobeGeometry {
    fn new(wi: &Vector3<f64>, wo: &Vector3<f64>) -> Self {
        let h = (wi + wo).normalize();
        Self {
            cos_h: h.z,
            cos_i: wi.z,
            cos_o: wo.z,
            schlick: (1.0 - wi.dot(&h).clamp(0.0, 1.0)).powi(5),
            denominator: 4.0 * wi.z * wo.z,
        }
    }

    fn lobe(&self, alpha: f64, f0: f64) -> f64 {
        let d = ggx_d(self.cos_h, alpha);
        let g = smith_g1(self.cos_i, alpha) * smith_g1(self.cos_o, alpha);
        let f = f0 + (1.0 - f0) * self.schlick;
        d * g * f / self.denominator
    }
}

impl Brdf for LambertGgx {
    fn eval_local(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> [f64; 3] {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return [0.0; 3];
        }
        let s = ggx_lobe(wi, wo, self.alpha, self.f0);
        std::array::from_fn(|c| self.kd[c] / PI + self.ks[c] * s)
    }
}

fn usable(samples: &[ReflectanceSample]) -> Result<Vec<&ReflectanceSample>, FitError> {
    let mut out = Vec::with_capacity(samples.len());
    for s in samples {
        let finite = s.rgb.iter().all(|v| v.is_finite())
            && s.wi.iter().all(|v| v.is_finite())
            && s.wo.iter().all(|v| v.is_finite());
        if !finite {
            return Err(FitError::NonFinite);
        }
        if s.wi.z > 0.0 && s.wo.z > 0.0 {
            out.push(s);
        }
    }
    if out.is_empty() {
        return Err(FitError::Empty);
    }
    Ok(out)
}

/// The cosine-map weight `clip(cos theta_i cos theta_o, 0.01, 1)` of an observation: weighting
/// residuals by it fits what images see (radiance), so grazing bins, where f_r is large but
/// little light arrives, do not dominate the fit.
pub fn cosine_map_weight(s: &ReflectanceSample) -> f64 {
    (s.wi.z * s.wo.z).clamp(super::basis::COS_MAP_MIN, 1.0)
}

/// The image-space weight `cos theta_i` of an observation: weighting residuals of f_r by it
/// is least squares on the pixels themselves (radiance `f E cos theta_i`, for a common E),
/// which is what a user fitting a model to photographs minimises.
pub fn pixel_weight(s: &ReflectanceSample) -> f64 {
    s.wi.z.max(0.0)
}

impl Lambert {
    /// Least squares: `albedo_c = pi mean(r_c)` over the observations above the horizon.
    pub fn fit(samples: &[ReflectanceSample]) -> Result<Self, FitError> {
        Self::fit_weighted(samples, |_| 1.0)
    }

    /// Weighted least squares, minimising `sum (w (f - r))^2`:
    /// `albedo_c = pi sum(w^2 r_c) / sum(w^2)`.
    pub fn fit_weighted(
        samples: &[ReflectanceSample],
        weight: impl Fn(&ReflectanceSample) -> f64,
    ) -> Result<Self, FitError> {
        let s = usable(samples)?;
        let w2: Vec<f64> = s.iter().map(|x| weight(x).powi(2)).collect();
        let total: f64 = w2.iter().sum();
        if total.is_nan() || total <= 0.0 {
            return Err(FitError::Empty);
        }
        let albedo = std::array::from_fn(|c| {
            PI * s.iter().zip(&w2).map(|(x, w)| w * x.rgb[c]).sum::<f64>() / total
        });
        Ok(Self { albedo })
    }

    /// Weighted median: `albedo_c = pi m_c`, `m_c` the value of `r_c` below which half the
    /// observations' weight lies (the lower one at an exact half; `crate::stats`). Unlike least
    /// squares it ignores how far an outlier lies: a pixel in a shadow the model does not cast,
    /// or one mixing the object's edge with the background, moves it by one rank, not by its
    /// value. Non-finite values and zero or negative weights are skipped.
    pub fn fit_weighted_median(
        samples: &[ReflectanceSample],
        weight: impl Fn(&ReflectanceSample) -> f64,
    ) -> Result<Self, FitError> {
        let s = usable(samples)?;
        let mut albedo = [0.0; 3];
        for (c, a) in albedo.iter_mut().enumerate() {
            let mut v: Vec<(f64, f64)> = s
                .iter()
                .map(|x| (x.rgb[c], weight(x)))
                .filter(|(r, w)| r.is_finite() && w.is_finite() && *w > 0.0)
                .collect();
            *a = PI * crate::stats::weighted_median(&mut v).ok_or(FitError::Empty)?;
        }
        Ok(Self { albedo })
    }
}

/// The largest diffuse albedo `kd` and specular weight `ks` a fit may take, per channel: a
/// physical albedo is at most 1 (and a material editor bounds both the same way), so a few
/// bright pixels cannot drive an unbounded lobe.
pub const MAX_WEIGHT: f64 = 1.0;

/// Box-constrained weighted least squares for `r = kd/pi + ks lobe` on one channel, minimising
/// `sum w2 (kd/pi + ks lobe - r)^2` with `kd, ks` in `[0, MAX_WEIGHT]`; returns
/// `(kd, ks, that sum)`. Without `diffuse`, kd = 0.
fn solve_linear(lobe: &[f64], r: &[f64], w2: &[f64], diffuse: bool) -> (f64, f64, f64) {
    let (mut sw, mut sl, mut sll, mut sr, mut slr, mut srr) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for ((l, y), w) in lobe.iter().zip(r).zip(w2) {
        sw += w;
        sl += w * l;
        sll += w * l * l;
        sr += w * y;
        slr += w * l * y;
        srr += w * y * y;
    }
    // The sum of squares as a quadratic in (a = kd/pi, ks).
    let ssr = |a: f64, ks: f64| -> f64 {
        (a * a * sw + ks * ks * sll + srr + 2.0 * a * ks * sl - 2.0 * a * sr - 2.0 * ks * slr)
            .max(0.0)
    };
    let a_max = if diffuse { MAX_WEIGHT / PI } else { 0.0 };
    let ks_of = |a: f64| {
        if sll > 0.0 {
            ((slr - a * sl) / sll).clamp(0.0, MAX_WEIGHT)
        } else {
            0.0
        }
    };
    let a_of = |ks: f64| {
        if sw > 0.0 {
            ((sr - ks * sl) / sw).clamp(0.0, a_max)
        } else {
            0.0
        }
    };
    // A convex quadratic on a box: the minimum is the free one if inside, else on an edge,
    // where the other variable is the clamped 1-D minimiser.
    let mut cands = vec![(0.0, ks_of(0.0)), (a_max, ks_of(a_max))];
    if diffuse {
        cands.push((a_of(0.0), 0.0));
        cands.push((a_of(MAX_WEIGHT), MAX_WEIGHT));
        let det = sw * sll - sl * sl;
        if det.abs() > 1e-300 {
            let a = (sll * sr - sl * slr) / det;
            let ks = (sw * slr - sl * sr) / det;
            if (0.0..=a_max).contains(&a) && (0.0..=MAX_WEIGHT).contains(&ks) {
                cands.push((a, ks));
            }
        }
    }
    let best = cands
        .into_iter()
        .map(|(a, ks)| (a, ks, ssr(a, ks)))
        .min_by(|x, y| x.2.total_cmp(&y.2))
        .unwrap_or((0.0, 0.0, ssr(0.0, 0.0)));
    (best.0 * PI, best.1, best.2)
}

/// The narrowest GGX roughness a fit may take: a lobe left there is narrower than the pixels
/// resolved.
pub const ALPHA_MIN: f64 = 0.002;
const ALPHA_MAX: f64 = 1.0;

impl LambertGgx {
    /// Least-squares fit (see the module header).
    pub fn fit(samples: &[ReflectanceSample]) -> Result<Self, FitError> {
        Self::fit_weighted(samples, |_| 1.0)
    }

    /// Weighted least squares, minimising `sum (w (f - r))^2` over observations and channels
    /// (e.g. with [`cosine_map_weight`]).
    pub fn fit_weighted(
        samples: &[ReflectanceSample],
        weight: impl Fn(&ReflectanceSample) -> f64,
    ) -> Result<Self, FitError> {
        Self::fit_impl(samples, weight, true, [0.0, 1.0])
    }

    /// [`LambertGgx::fit_weighted`] with Schlick's `F0` kept within `[lo, hi]` (each clamped to
    /// [0, 1]).
    pub fn fit_weighted_f0(
        samples: &[ReflectanceSample],
        weight: impl Fn(&ReflectanceSample) -> f64,
        lo: f64,
        hi: f64,
    ) -> Result<Self, FitError> {
        Self::fit_impl(samples, weight, true, f0_range(lo, hi))
    }

    /// A specular lobe alone (`kd` = 0), fitted the same way: what a residual peak on top of
    /// another model needs (the hybrid rung of `reconstruct::ladder`). Residuals may be
    /// negative; `ks` stays non-negative.
    pub fn fit_lobe_weighted(
        samples: &[ReflectanceSample],
        weight: impl Fn(&ReflectanceSample) -> f64,
    ) -> Result<Self, FitError> {
        Self::fit_impl(samples, weight, false, [0.0, 1.0])
    }

    /// [`LambertGgx::fit_lobe_weighted`] with Schlick's `F0` kept within `[lo, hi]` (each
    /// clamped to [0, 1]): for samples whose theta_d is too narrow to tell `F0` from `ks` (the
    /// Fresnel factor is then one constant, and a free `F0` sets the grazing rise at random).
    pub fn fit_lobe_weighted_f0(
        samples: &[ReflectanceSample],
        weight: impl Fn(&ReflectanceSample) -> f64,
        lo: f64,
        hi: f64,
    ) -> Result<Self, FitError> {
        Self::fit_impl(samples, weight, false, f0_range(lo, hi))
    }

    fn fit_impl(
        samples: &[ReflectanceSample],
        weight: impl Fn(&ReflectanceSample) -> f64,
        diffuse: bool,
        f0_range: [f64; 2],
    ) -> Result<Self, FitError> {
        let s = usable(samples)?;
        let w2: Vec<f64> = s.iter().map(|x| weight(x).powi(2)).collect();
        if !w2.iter().all(|w| w.is_finite()) || w2.iter().sum::<f64>() <= 0.0 {
            return Err(FitError::Empty);
        }
        let channels: [Vec<f64>; 3] = std::array::from_fn(|c| s.iter().map(|x| x.rgb[c]).collect());
        // every usable sample is above the horizon: ggx_lobe's own test always passes
        let geometry: Vec<LobeGeometry> =
            s.iter().map(|x| LobeGeometry::new(&x.wi, &x.wo)).collect();
        let clamp = |p: [f64; 2]| -> (f64, f64) {
            (
                p[0].exp().clamp(ALPHA_MIN, ALPHA_MAX),
                p[1].clamp(f0_range[0], f0_range[1]),
            )
        };
        let solve = |p: [f64; 2]| -> ([f64; 3], [f64; 3], f64) {
            let (alpha, f0) = clamp(p);
            let lobe: Vec<f64> = geometry.iter().map(|g| g.lobe(alpha, f0)).collect();
            let mut kd = [0.0; 3];
            let mut ks = [0.0; 3];
            let mut total = 0.0;
            for c in 0..3 {
                let (d, k, e) = solve_linear(&lobe, &channels[c], &w2, diffuse);
                kd[c] = d;
                ks[c] = k;
                total += e;
            }
            (kd, ks, total)
        };
        let cost = |p: [f64; 2]| solve(p).2;

        // Grid search over log alpha and F0, then Nelder-Mead from the best point.
        let mut start = ([0.1f64.ln(), 0.04], f64::INFINITY);
        for i in 0..16 {
            let la = ALPHA_MIN.ln() + (ALPHA_MAX.ln() - ALPHA_MIN.ln()) * i as f64 / 15.0;
            for f0 in [0.02, 0.05, 0.15, 0.4, 0.8] {
                let c = cost([la, f0]);
                if c < start.1 {
                    start = ([la, f0], c);
                }
            }
        }
        let best = nelder_mead(cost, start.0, [0.2, 0.05], 300);
        let (alpha, f0) = clamp(best);
        let (kd, ks, _) = solve(best);
        Ok(Self { kd, ks, alpha, f0 })
    }
}

/// `[lo, hi]` as an `F0` range: each clamped to [0, 1], `hi` at least `lo`.
fn f0_range(lo: f64, hi: f64) -> [f64; 2] {
    let lo = lo.clamp(0.0, 1.0);
    [lo, hi.clamp(lo, 1.0)]
}

/// Minimises `f` over two variables from `x0` with initial steps `step`.
fn nelder_mead(
    f: impl Fn([f64; 2]) -> f64,
    x0: [f64; 2],
    step: [f64; 2],
    iters: usize,
) -> [f64; 2] {
    let mut simplex = [x0, [x0[0] + step[0], x0[1]], [x0[0], x0[1] + step[1]]];
    let mut values = simplex.map(&f);
    let lerp =
        |a: [f64; 2], b: [f64; 2], t: f64| [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
    for _ in 0..iters {
        let mut idx = [0usize, 1, 2];
        idx.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
        let [b, m, w] = idx;
        if (values[w] - values[b]).abs() <= 1e-14 * values[b].abs().max(1e-300) {
            break;
        }
        let centroid = lerp(simplex[b], simplex[m], 0.5);
        let reflect = lerp(centroid, simplex[w], -1.0);
        let fr = f(reflect);
        if fr < values[b] {
            let expand = lerp(centroid, simplex[w], -2.0);
            let fe = f(expand);
            if fe < fr {
                (simplex[w], values[w]) = (expand, fe);
            } else {
                (simplex[w], values[w]) = (reflect, fr);
            }
        } else if fr < values[m] {
            (simplex[w], values[w]) = (reflect, fr);
        } else {
            let contract = lerp(centroid, simplex[w], 0.5);
            let fc = f(contract);
            if fc < values[w] {
                (simplex[w], values[w]) = (contract, fc);
            } else {
                for i in [m, w] {
                    simplex[i] = lerp(simplex[b], simplex[i], 0.5);
                    values[i] = f(simplex[i]);
                }
            }
        }
    }
    let mut best = 0;
    for i in 1..3 {
        if values[i] < values[best] {
            best = i;
        }
    }
    simplex[best]
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;
    use crate::brdf::coords::HalfDiff;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn the_box_constrained_solve_is_the_least_sum_of_squares_on_the_box() {
        // against a search of the box: no (kd, ks) in it does better than the solve
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for trial in 0..40 {
            let n = rng.gen_range(3..40);
            let lobe: Vec<f64> = (0..n).map(|_| rng.gen_range(0.0..5.0)).collect();
            let w2: Vec<f64> = (0..n).map(|_| rng.gen_range(0.1..2.0)).collect();
            // a lobe plus a diffuse level, either of which may lean negative (the box's edges)
            let (a0, k0) = (rng.gen_range(-0.1..0.3), rng.gen_range(-0.5..1.5));
            let r: Vec<f64> = lobe
                .iter()
                .map(|l| a0 + k0 * l + rng.gen_range(-0.05..0.05))
                .collect();
            let ssr = |kd: f64, ks: f64| -> f64 {
                (0..n)
                    .map(|i| w2[i] * (kd / PI + ks * lobe[i] - r[i]).powi(2))
                    .sum()
            };
            for diffuse in [true, false] {
                let (kd, ks, e) = solve_linear(&lobe, &r, &w2, diffuse);
                assert!(
                    (0.0..=MAX_WEIGHT).contains(&ks) && (0.0..=MAX_WEIGHT).contains(&kd),
                    "{trial}: {kd} {ks}"
                );
                if !diffuse {
                    assert_eq!(kd, 0.0);
                }
                assert!((e - ssr(kd, ks)).abs() <= 1e-9 * (1.0 + e), "{trial}: {e}");
                let kd_max = if diffuse { MAX_WEIGHT } else { 0.0 };
                for i in 0..=200 {
                    for j in 0..=200 {
                        let (kd_t, ks_t) =
                            (kd_max * i as f64 / 200.0, MAX_WEIGHT * j as f64 / 200.0);
                        assert!(
                            e <= ssr(kd_t, ks_t) + 1e-9 * (1.0 + e),
                            "{trial} {diffuse}: ({kd}, {ks}) {e} > ({kd_t}, {ks_t})"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn the_lobe_is_the_textbook_ggx_lobe() {
        // D G F / (4 cos_i cos_o) written out from the half-difference angles, a second route
        // to what the precomputed geometry of a fit gives
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for _ in 0..200 {
            let dir = |rng: &mut ChaCha8Rng| {
                let (t, p): (f64, f64) = (
                    rng.gen_range(0.0..1.5),
                    rng.gen_range(0.0..std::f64::consts::TAU),
                );
                Vector3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
            };
            let (wi, wo) = (dir(&mut rng), dir(&mut rng));
            let (alpha, f0) = (rng.gen_range(0.01..0.9), rng.gen_range(0.0..1.0));
            let hd = HalfDiff::from_directions(&wi, &wo);
            let a2 = alpha * alpha;
            let d = a2 / (PI * (hd.theta_h.cos().powi(2) * (a2 - 1.0) + 1.0).powi(2));
            let g1 = |c: f64| 2.0 * c / (c + (a2 + (1.0 - a2) * c * c).sqrt());
            let f = f0 + (1.0 - f0) * (1.0 - hd.theta_d.cos()).powi(5);
            let want = d * g1(wi.z) * g1(wo.z) * f / (4.0 * wi.z * wo.z);
            let got = ggx_lobe(&wi, &wo, alpha, f0);
            assert!(
                (got - want).abs() <= 1e-9 * want.abs().max(1e-12),
                "{got} {want}"
            );
        }
        assert_eq!(
            ggx_lobe(&Vector3::new(0.0, 0.6, -0.8), &Vector3::z(), 0.3, 0.04),
            0.0
        );
    }

    fn samples(truth: &dyn Brdf, n: usize, seed: u64) -> Vec<ReflectanceSample> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut out = Vec::new();
        while out.len() < n {
            // Half of them near the specular direction, where the lobe is.
            let theta_h = if out.len() % 2 == 0 {
                rng.gen_range(0.0..0.3)
            } else {
                rng.gen_range(0.0..1.4)
            };
            let hd = HalfDiff {
                theta_h,
                phi_h: rng.gen_range(0.0..2.0 * PI),
                theta_d: rng.gen_range(0.0..1.3),
                phi_d: rng.gen_range(0.0..2.0 * PI),
            };
            let (wi, wo) = hd.to_directions();
            if wi.z > 0.05 && wo.z > 0.05 {
                out.push(ReflectanceSample {
                    wi,
                    wo,
                    rgb: truth.eval_local(&wi, &wo),
                });
            }
        }
        out
    }

    #[test]
    fn ggx_distribution_is_normalised() {
        // Closed form: the projected area of the microfacets is one, int D cos theta_h dw = 1.
        for alpha in [0.05, 0.2, 0.7] {
            let n = 200_000;
            let mut sum = 0.0;
            for i in 0..n {
                // With u = cos^2 theta_h: int D cos dw = pi int_0^1 D(sqrt u) du (midpoint rule).
                let u = (i as f64 + 0.5) / n as f64;
                sum += PI * ggx_d(u.sqrt(), alpha) / n as f64;
            }
            assert!((sum - 1.0).abs() < 1e-3, "alpha {alpha}: {sum}");
        }
    }

    #[test]
    fn lambert_fit_is_exact_on_lambertian_data() {
        let truth = Lambert {
            albedo: [0.2, 0.5, 0.8],
        };
        let fit = Lambert::fit(&samples(&truth, 50, 1)).expect("fit");
        for c in 0..3 {
            assert!((fit.albedo[c] - truth.albedo[c]).abs() < 1e-12);
        }
        assert_eq!(Lambert::fit(&[]), Err(FitError::Empty));
        // Weights do not move an exact fit.
        let w = Lambert::fit_weighted(&samples(&truth, 50, 3), cosine_map_weight).expect("fit");
        assert!((0..3).all(|c| (w.albedo[c] - truth.albedo[c]).abs() < 1e-12));
    }

    #[test]
    fn lambert_median_ignores_outliers_that_pull_least_squares() {
        let truth = Lambert {
            albedo: [0.2, 0.5, 0.8],
        };
        let mut data = samples(&truth, 60, 4);
        // Exact data: the median is the albedo.
        let m = Lambert::fit_weighted_median(&data, pixel_weight).expect("fit");
        assert!((0..3).all(|c| (m.albedo[c] - truth.albedo[c]).abs() < 1e-12));
        // A tenth of the pixels in an unmodelled shadow (a tenth of their value): least
        // squares drops by about 9 %, the median stays.
        for s in data.iter_mut().step_by(10) {
            s.rgb = s.rgb.map(|r| 0.1 * r);
        }
        let ls = Lambert::fit_weighted(&data, pixel_weight).expect("fit");
        let m = Lambert::fit_weighted_median(&data, pixel_weight).expect("fit");
        for c in 0..3 {
            assert!(ls.albedo[c] < 0.95 * truth.albedo[c], "{ls:?}");
            assert!((m.albedo[c] - truth.albedo[c]).abs() < 1e-12, "{m:?}");
        }
        // The weights decide where the half lies: all weight on the shadowed ones.
        let shadowed = Lambert::fit_weighted_median(&data, |s| {
            if s.rgb[0] < 0.5 * truth.albedo[0] / PI {
                1.0
            } else {
                0.0
            }
        })
        .expect("fit");
        assert!((shadowed.albedo[1] - 0.1 * truth.albedo[1]).abs() < 1e-12);
        // Nothing usable: an error, not a panic.
        assert_eq!(
            Lambert::fit_weighted_median(&data, |_| 0.0),
            Err(FitError::Empty)
        );
        assert_eq!(
            Lambert::fit_weighted_median(&[], pixel_weight),
            Err(FitError::Empty)
        );
    }

    #[test]
    fn lambert_ggx_fit_recovers_its_parameters() {
        let truth = LambertGgx {
            kd: [0.3, 0.2, 0.1],
            ks: [1.0, 0.8, 0.6],
            alpha: 0.15,
            f0: 0.05,
        };
        let data = samples(&truth, 400, 2);
        let fit = LambertGgx::fit(&data).expect("fit");
        assert!(
            (fit.alpha - truth.alpha).abs() < 0.01 * truth.alpha,
            "{fit:?}"
        );
        for c in 0..3 {
            assert!(
                (fit.kd[c] - truth.kd[c]).abs() < 0.01 * truth.kd[c],
                "{fit:?}"
            );
            assert!(
                (fit.ks[c] - truth.ks[c]).abs() < 0.05 * truth.ks[c],
                "{fit:?}"
            );
        }
        // Weighted, on the same exact data: the same answer.
        let wfit = LambertGgx::fit_weighted(&data, cosine_map_weight).expect("fit");
        assert!(
            (wfit.alpha - truth.alpha).abs() < 0.01 * truth.alpha,
            "{wfit:?}"
        );
        // Whatever F0 it settles on, the fitted model reproduces the data.
        for s in &data {
            let got = fit.eval_local(&s.wi, &s.wo);
            for c in 0..3 {
                assert!((got[c] - s.rgb[c]).abs() < 0.02 * s.rgb[c] + 1e-4);
            }
        }
    }
}
