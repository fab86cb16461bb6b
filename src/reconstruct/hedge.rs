//! Model averaging where the images cannot judge the result: the chosen data-driven table
//! (the basis, or the basis with an analytic peak) blended, bin by bin and geometrically, with
//! the Lambert + GGX fit of the same pixels, in proportion to the share of the result's
//! environment render that comes from (theta_h, theta_d) cells no pixel observed.
//!
//! Why: the model ladder chooses by held-out images, and held-out images only see the cells
//! the training images saw. With one light fixed to the camera (one theta_d) most of a rendered
//! sphere comes from cells no image saw (44-67 % on the 320x240 grid), and there the basis's
//! extrapolation and Lambert + GGX's are two guesses that no held-out error can rank; which
//! one is nearer the truth changes from material to material (docs/evaluation.md section 1m).
//! Averaging the two guesses, in log space, bounds how far the written table can be from the
//! better of them, at a small cost where the chosen one was right. Where every cell a render
//! needs was seen (several lights), the weight is near zero and the result is the chosen model.
//!
//! The weight given to Lambert + GGX is `strength * unseen_share` (`strength` 0 turns the step
//! off). The default strength is 1 (0.5 from session 26 to 46): the basis's own extrapolation
//! keeps the weight of the share of the render the images observed. Once the lobe's `F0` came
//! from physics where one theta_d cannot tell it (`reconstruct::fresnel`, session 45), the
//! stronger average lifted the worst one-light scene of every set (the grids' 1.03-1.04 to
//! 1.13-1.14, Mitsuba 3's painted metal 0.27 to 0.71, four of seven found materials back over
//! the bar) at the cost of the one-light geometric means (docs/evaluation.md 1aj).
//!
//! Both tables are already plausible (non-negative, directional albedo at most 1); the weighted
//! geometric mean is at most the weighted arithmetic mean, and the albedo is linear in the
//! table, so the blend's albedo stays at most 1 as well.
//!
//! One exception: a Lambert + GGX whose lobe the fit left at both of its bounds, the narrowest
//! width and the largest weight ([`unresolved_lobe`]), is not averaged in. Its width is below
//! what the pixels resolve, so its height is not determined either, and with the weight at
//! its bound (Schlick's `F0` raised above a dielectric's to keep it there) its extrapolation
//! towards grazing is a mirror's: on the unrefined 128x96 Spot of blue-acrylic with one light
//! (seed 0) that table alone rendered 2.69 against the truth, and the hedge at strength 1
//! took the written table from 0.11 to 0.81 (docs/evaluation.md 1aj).
//!
//! Pure: no I/O. Must not refit anything: it only combines two finished tables.

use crate::brdf::analytic::{ALPHA_MIN, LambertGgx, MAX_WEIGHT};
use crate::brdf::merl::MerlTable;
use serde::{Deserialize, Serialize};

/// Knobs of the hedge.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct HedgeSettings {
    /// The weight of Lambert + GGX per unit share of the render from unobserved cells (0 to 1;
    /// 0: off).
    pub strength: f64,
}

impl Default for HedgeSettings {
    fn default() -> Self {
        Self { strength: 1.0 }
    }
}

impl HedgeSettings {
    /// No averaging (what a reconstruction did before the hedge existed).
    pub fn off() -> Self {
        Self { strength: 0.0 }
    }

    /// The weight Lambert + GGX gets for a result whose render is `unseen_share` unobserved.
    pub fn analytic_weight(&self, unseen_share: f64) -> f64 {
        let u = if unseen_share.is_finite() {
            unseen_share.clamp(0.0, 1.0)
        } else {
            0.0
        };
        (self.strength.clamp(0.0, 1.0) * u).clamp(0.0, 1.0)
    }
}

/// What the hedge did, for `report.json` (inside `plausibility`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Hedge {
    /// Share of the chosen model's environment render from never-observed cells.
    pub unseen_share: f64,
    /// The weight given to Lambert + GGX (the exponent of its table in the geometric blend).
    pub analytic_weight: f64,
    /// Lambert + GGX's Schlick `F0`, and whether it was set by `reconstruct::fresnel`'s
    /// physical rule (one theta_d cannot tell it) rather than fitted. Absent in reports
    /// written before session 45.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub f0: Option<f64>,
    #[serde(default)]
    pub f0_held: bool,
    /// Lambert + GGX's lobe lay at both bounds of its fit ([`unresolved_lobe`]), so it was not
    /// averaged in (weight 0). Absent (false) in reports written before session 47.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub unresolved_lobe: bool,
}

/// Whether a Lambert + GGX fit left its lobe at both bounds: the narrowest roughness
/// ([`ALPHA_MIN`]) and, in some channel, the largest weight ([`MAX_WEIGHT`]).
pub fn unresolved_lobe(m: &LambertGgx) -> bool {
    m.alpha <= ALPHA_MIN * (1.0 + 1e-9) && m.ks.iter().any(|k| *k >= MAX_WEIGHT * (1.0 - 1e-6))
}

impl Hedge {
    /// What the hedge did, in words (the command line and the HTML report).
    pub fn describe(&self) -> String {
        let f0 = match self.f0 {
            Some(f) if self.f0_held => format!(
                " (its F0 {f:.3}: one theta_d cannot tell it, so a dielectric's 0.04, raised to \
                 keep the lobe's weight at most 1, or 1 for a lobe as broad as a body's; \
                 --lambert-ggx-f0)"
            ),
            Some(f) => format!(" (its F0 {f:.3}, fitted)"),
            None => String::new(),
        };
        if self.unresolved_lobe {
            return format!(
                "{:.0} % of the rendered sphere from cells no pixel observed; Lambert + GGX not \
                 averaged in: its lobe lies at the fit's narrowest width and largest weight, \
                 narrower than the pixels resolve{f0}",
                100.0 * self.unseen_share
            );
        }
        format!(
            "{:.0} % of the rendered sphere from cells no pixel observed; Lambert + GGX's weight \
             in the written table {:.2}{f0}",
            100.0 * self.unseen_share,
            self.analytic_weight
        )
    }
}

/// `table^(1 - w) * analytic^w`, bin by bin and channel by channel. A bin missing from either
/// table keeps the other's value; a zero in either gives zero (the geometric mean's own rule).
pub fn blend(table: &MerlTable, analytic: &MerlTable, w: f64) -> MerlTable {
    let mut out = table.clone();
    blend_into(&mut out, analytic, w);
    out
}

/// [`blend`] in place: `table` becomes the blend (the same values, without a third table).
pub fn blend_into(table: &mut MerlTable, analytic: &MerlTable, w: f64) {
    let w = if w.is_finite() {
        w.clamp(0.0, 1.0)
    } else {
        0.0
    };
    table.update(|index, current| match (current, analytic.get(index)) {
        (Some(a), Some(b)) => Some([0, 1, 2].map(|c| {
            let (x, y) = (a[c].max(0.0), b[c].max(0.0));
            if x == 0.0 || y == 0.0 {
                0.0
            } else {
                ((1.0 - w) * x.ln() + w * y.ln()).exp()
            }
        })),
        (a, b) => a.or(b),
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::coords::{MERL_BINS, MerlBin};
    use crate::reconstruct::plausible::albedo_curve;

    fn constant(v: [f64; 3]) -> MerlTable {
        let mut t = MerlTable::empty();
        for i in 0..MERL_BINS {
            if MerlBin::from_index(i).is_some_and(|b| b.is_above_horizon()) {
                t.set(i, v);
            }
        }
        t
    }

    #[test]
    fn the_weight_follows_the_unseen_share_and_zero_strength_turns_it_off() {
        let s = HedgeSettings { strength: 0.5 };
        assert_eq!(s.analytic_weight(0.0), 0.0);
        assert!((s.analytic_weight(0.6) - 0.3).abs() < 1e-12);
        assert_eq!(s.analytic_weight(f64::NAN), 0.0);
        assert_eq!(s.analytic_weight(3.0), 0.5);
        assert_eq!(HedgeSettings { strength: 0.0 }.analytic_weight(0.9), 0.0);
    }

    #[test]
    fn the_default_strength_is_one_the_weight_the_unseen_share() {
        let s = HedgeSettings::default();
        assert_eq!(s.strength, 1.0);
        assert!((s.analytic_weight(0.57) - 0.57).abs() < 1e-12);
    }

    #[test]
    fn a_lobe_at_both_bounds_of_its_fit_is_unresolved_and_said_so() {
        // The unrefined 128x96 Spot of blue-acrylic, one light: the narrowest width, red's
        // weight at its bound after F0 was raised to 0.07.
        let spike = LambertGgx {
            kd: [0.013, 0.038, 0.109],
            ks: [0.999_999_2, 0.79, 0.77],
            alpha: ALPHA_MIN,
            f0: 0.0706,
        };
        assert!(unresolved_lobe(&spike));
        // Either bound alone is a resolved fit: a narrow lobe of moderate weight (the same
        // scene refined), or a metal's lobe whose F0 the rule raised (weight 1, width 0.2).
        let narrow = LambertGgx {
            ks: [0.41, 0.32, 0.32],
            f0: 0.04,
            ..spike
        };
        let metal = LambertGgx {
            alpha: 0.2,
            ..spike
        };
        assert!(!unresolved_lobe(&narrow));
        assert!(!unresolved_lobe(&metal));
        let report = Hedge {
            unseen_share: 0.57,
            analytic_weight: 0.0,
            f0: Some(spike.f0),
            f0_held: true,
            unresolved_lobe: true,
        };
        let text = report.describe();
        assert!(
            text.contains("57 %") && text.contains("not averaged in"),
            "{text}"
        );
        // A report written before the field reads back without it.
        let mut json = serde_json::to_value(report).expect("serialises");
        json.as_object_mut()
            .expect("object")
            .remove("unresolved_lobe");
        let old: Hedge = serde_json::from_value(json).expect("reads back");
        assert!(!old.unresolved_lobe);
    }

    #[test]
    fn the_blend_is_the_weighted_geometric_mean_and_keeps_the_albedo_at_most_one() {
        // Two Lambertian tables (f = a / pi), albedo 0.3 and 0.99.
        let a = constant([0.3 / std::f64::consts::PI; 3]);
        let b = constant([0.99 / std::f64::consts::PI; 3]);
        let m = blend(&a, &b, 0.25);
        let i = MerlBin {
            theta_h: 10,
            theta_d: 20,
            phi_d: 30,
        }
        .index();
        let got = m.get(i).map(|v| v[0]);
        let want = (0.75 * (0.3f64).ln() + 0.25 * (0.99f64).ln()).exp() / std::f64::consts::PI;
        assert!(
            got.is_some_and(|g| (g - want).abs() < 1e-12),
            "{got:?} vs {want}"
        );
        let near = |x: Option<[f64; 3]>, y: Option<[f64; 3]>| {
            x.zip(y)
                .is_some_and(|(x, y)| (0..3).all(|c| (x[c] - y[c]).abs() < 1e-12))
        };
        assert!(near(blend(&a, &b, 0.0).get(i), a.get(i)));
        assert!(near(blend(&a, &b, 1.0).get(i), b.get(i)));
        let top = albedo_curve(&m).into_iter().fold(0.0, f64::max);
        assert!(top <= 1.0, "largest albedo {top}");
        assert!(top > 0.3, "largest albedo {top}");
    }
}
