//! Error metrics between a true and a reconstructed BRDF (METHOD.md section 7; definitions in
//! `docs/error-metrics.md`).
//!
//! Over a set of MERL bins `D` (bins whose centre directions are both above the horizon; others
//! are skipped), summing over the bins and the three channels:
//! - `relative = ||t - r|| / ||t||` (the paper's error);
//! - `cosine_weighted = ||c (t - r)|| / ||c t||`, `c` the basis cosine map
//!   `clip(cos theta_i cos theta_o, 0.01, 1)`: errors weighted as they appear in images, so the
//!   grazing bins, where f_r is large but little light arrives, do not dominate;
//! - `near_specular`: `relative` restricted to `theta_h` (bin centre) below
//!   [`NEAR_SPECULAR_THETA_H_DEG`] = 10 degrees;
//! - `cosine_weighted_off_peak`: `cosine_weighted` restricted to `theta_h` at or above
//!   [`OFF_PEAK_THETA_H_DEG`] = 2 degrees. For a mirror-like material nearly all of
//!   `cosine_weighted` sits in the sub-degree peak (docs/evaluation.md, "Why the shiny materials
//!   fail"); this one says whether the rest of the BRDF is right.
//! - `solid_angle`: `||w^(1/2) c' (t - r)|| / ||w^(1/2) c' t||` with `c' = cos theta_i cos
//!   theta_o` (no floor) and `w` each bin's share of the (wi, wo) domain's solid angle
//!   ([`bin_solid_angle`]). MERL spaces `theta_h` as `sqrt(theta_h)`, so without `w` the
//!   sub-degree peak bins, a tiny part of the domain, count as much as any other bin: the
//!   metrics above over-count the peak by orders of magnitude (METHOD.md section 7).
//! - `log`: Loew et al.'s log-space error, solid-angle weighted and relative:
//!   `||w^(1/2) (ln(1 + t cos_i) - ln(1 + r cos_i))|| / ||w^(1/2) ln(1 + t cos_i)||`
//!   (negative reconstructed values count as zero).
//!
//! Every error is 0 for a perfect reconstruction and 1 for one that is zero everywhere.
//! The errors of rendered images (what a user sees) are in `render::probe`.
//!
//! Values are f_r in 1/sr. Pure: no files; must not depend on how the BRDFs were made (basis,
//! network, fits): it sees values at bins only.

use super::BinValues;
use super::basis::cos_map;
use super::coords::{MerlBin, THETA_H_BINS};

/// The `theta_h` bound of the near-specular domain, degrees.
pub const NEAR_SPECULAR_THETA_H_DEG: f64 = 10.0;

/// The `theta_h` bound below which `cosine_weighted_off_peak` does not look, degrees.
pub const OFF_PEAK_THETA_H_DEG: f64 = 2.0;

/// The three errors, and how many bins each was computed over.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorReport {
    pub relative: f64,
    pub cosine_weighted: f64,
    pub near_specular: f64,
    pub cosine_weighted_off_peak: f64,
    /// Solid-angle weighted, image-cosine weighted relative error.
    pub solid_angle: f64,
    /// Solid-angle weighted relative error of `ln(1 + f cos theta_i)`.
    pub log: f64,
    pub bins: usize,
    pub near_specular_bins: usize,
}

#[derive(Default)]
struct Acc {
    num: f64,
    den: f64,
}

impl Acc {
    fn add(&mut self, w: f64, t: &[f64; 3], r: &[f64; 3]) {
        for ch in 0..3 {
            self.num += (w * (t[ch] - r[ch])).powi(2);
            self.den += (w * t[ch]).powi(2);
        }
    }
    /// Adds `weight * (t - r)^2` and `weight * t^2` (the weight is not squared).
    fn add_weighted(&mut self, weight: f64, t: &[f64; 3], r: &[f64; 3]) {
        for ch in 0..3 {
            self.num += weight * (t[ch] - r[ch]).powi(2);
            self.den += weight * t[ch].powi(2);
        }
    }
    fn ratio(&self) -> f64 {
        if self.den > 0.0 {
            (self.num / self.den).sqrt()
        } else {
            f64::NAN
        }
    }
}

/// A bin's share of the solid angle of the (wi, wo) domain, up to a constant factor:
/// `d omega_i d omega_o = 4 cos theta_d d omega_h d omega_d` (Rusinkiewicz 1998), so a bin weighs
/// `cos theta_d sin theta_d sin theta_h` times its `theta_h` width, which MERL's square-root
/// spacing makes proportional to `2 i + 1` for `theta_h` bin `i` (the `theta_d`, `phi_d` and
/// `phi_h` widths are the same for every bin).
pub fn bin_solid_angle(bin: &MerlBin) -> f64 {
    let c = bin.centre();
    let width = (2 * bin.theta_h + 1) as f64 / (THETA_H_BINS * THETA_H_BINS) as f64;
    c.theta_d.cos() * c.theta_d.sin() * c.theta_h.sin() * width
}

/// Errors of `rec` against `truth`, both given at `bins` (same order).
pub fn compare_values(bins: &[usize], truth: &[[f64; 3]], rec: &[[f64; 3]]) -> ErrorReport {
    let limit = NEAR_SPECULAR_THETA_H_DEG.to_radians();
    let off_peak = OFF_PEAK_THETA_H_DEG.to_radians();
    let (mut rel, mut cos, mut spec) = (Acc::default(), Acc::default(), Acc::default());
    let mut cos_off = Acc::default();
    let (mut sa, mut log) = (Acc::default(), Acc::default());
    let (mut n, mut n_spec) = (0, 0);
    for ((&bin, t), r) in bins.iter().zip(truth).zip(rec) {
        let Some(b) = MerlBin::from_index(bin) else {
            continue;
        };
        if !b.is_above_horizon() {
            continue;
        }
        n += 1;
        rel.add(1.0, t, r);
        cos.add(cos_map(bin), t, r);
        if b.centre().theta_h >= off_peak {
            cos_off.add(cos_map(bin), t, r);
        }
        if b.centre().theta_h < limit {
            n_spec += 1;
            spec.add(1.0, t, r);
        }
        let w = bin_solid_angle(&b);
        let (ci, co) = b.centre_cosines();
        let c = ci * co;
        sa.add_weighted(w, &t.map(|x| c * x), &r.map(|x| c * x));
        let ln = |f: [f64; 3]| f.map(|x| (1.0 + x.max(0.0) * ci).ln());
        log.add_weighted(w, &ln(*t), &ln(*r));
    }
    ErrorReport {
        relative: rel.ratio(),
        cosine_weighted: cos.ratio(),
        near_specular: spec.ratio(),
        cosine_weighted_off_peak: cos_off.ratio(),
        solid_angle: sa.ratio(),
        log: log.ratio(),
        bins: n,
        near_specular_bins: n_spec,
    }
}

/// Errors of `rec` against `truth` over `bins`.
pub fn compare(bins: &[usize], truth: &dyn BinValues, rec: &dyn BinValues) -> ErrorReport {
    compare_values(bins, &truth.values_at(bins), &rec.values_at(bins))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::coords::MERL_BINS;

    #[test]
    fn bin_solid_angles_add_up_to_the_measure_of_direction_pairs() {
        // The constant dropped by `bin_solid_angle`: 4 (jacobian) x pi/2 (theta_h, over the
        // 8100 of the width) x pi/180 (theta_d) x 2 pi/180 (phi_d, folded) x 2 pi (phi_h).
        use std::f64::consts::PI;
        let k = 4.0 * PI / 2.0 * PI / 180.0 * 2.0 * PI / 180.0 * 2.0 * PI;
        let (mut all, mut above) = (0.0, 0.0);
        for i in 0..MERL_BINS {
            let b = MerlBin::from_index(i).expect("bin");
            let w = k * bin_solid_angle(&b);
            all += w;
            if b.is_above_horizon() {
                above += w;
            }
        }
        // theta_h and theta_d in [0, pi/2]: 4 (2 pi)^2 x 1 x 1/2; both directions above the
        // horizon: (2 pi)^2.
        assert!((all / (8.0 * PI * PI) - 1.0).abs() < 0.01, "{all}");
        assert!((above / (4.0 * PI * PI) - 1.0).abs() < 0.03, "{above}");
    }

    #[test]
    fn closed_form_errors() {
        let bins: Vec<usize> = (0..MERL_BINS).step_by(101).collect();
        let truth: Vec<[f64; 3]> = bins
            .iter()
            .map(|&b| [1.0 + (b % 7) as f64, 2.0, 0.5])
            .collect();
        // r = t (1 + e) everywhere: every relative error is exactly |e|, whatever the weights.
        let rec: Vec<[f64; 3]> = truth.iter().map(|t| t.map(|x| 1.1 * x)).collect();
        let e = compare_values(&bins, &truth, &rec);
        assert!((e.relative - 0.1).abs() < 1e-12);
        assert!((e.cosine_weighted - 0.1).abs() < 1e-12);
        assert!((e.near_specular - 0.1).abs() < 1e-12);
        assert!((e.cosine_weighted_off_peak - 0.1).abs() < 1e-12);
        assert!((e.solid_angle - 0.1).abs() < 1e-12);
        assert!(e.log > 0.0 && e.log < 0.1, "{}", e.log);
        let zero = compare_values(&bins, &truth, &vec![[0.0; 3]; bins.len()]);
        assert!((zero.solid_angle - 1.0).abs() < 1e-12 && (zero.log - 1.0).abs() < 1e-12);
        // An error confined to the sub-2-degree peak is invisible off the peak.
        let peaked: Vec<[f64; 3]> = bins
            .iter()
            .zip(&truth)
            .map(|(&b, t)| {
                let m = MerlBin::from_index(b).expect("bin");
                if m.centre().theta_h < OFF_PEAK_THETA_H_DEG.to_radians() {
                    t.map(|x| 3.0 * x)
                } else {
                    *t
                }
            })
            .collect();
        let p = compare_values(&bins, &truth, &peaked);
        assert!(p.cosine_weighted > 0.1);
        assert_eq!(p.cosine_weighted_off_peak, 0.0);
        // Solid-angle weighting: the sub-2-degree bins are a sliver of the domain.
        assert!(p.solid_angle < p.cosine_weighted / 5.0, "{p:?}");
        assert!(e.bins > 0 && e.near_specular_bins > 0 && e.near_specular_bins < e.bins);
        assert_eq!(compare_values(&bins, &truth, &truth).relative, 0.0);
        // An error only in one grazing bin (tiny cosine map) counts less when weighted.
        let grazing = bins
            .iter()
            .position(|&b| {
                let m = MerlBin::from_index(b).expect("bin");
                m.is_above_horizon() && cos_map(b) <= 0.011
            })
            .expect("a grazing bin");
        let mut rec = truth.clone();
        rec[grazing][0] += 50.0;
        let e = compare_values(&bins, &truth, &rec);
        assert!(e.cosine_weighted < e.relative / 10.0);
        // Below-horizon bins are skipped.
        let below = (0..MERL_BINS)
            .find(|&b| !MerlBin::from_index(b).expect("bin").is_above_horizon())
            .expect("a bin below");
        let e = compare_values(&[below], &[[1.0; 3]], &[[5.0; 3]]);
        assert_eq!(e.bins, 0);
        assert!(e.relative.is_nan());
    }
}
