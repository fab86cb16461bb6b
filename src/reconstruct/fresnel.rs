//! Schlick's `F0` where the pixels cannot tell it: the reconstruction's own Lambert + GGX fit.
//!
//! With one light fixed beside the camera every pixel lies near one theta_d, where Schlick's
//! factor is the constant `F0` (its `(1 - cos theta_d)^5` term is below 4e-4 up to 35
//! degrees). A lobe's weight `ks` and its `F0` are then one number, `ks F0`, and a free fit
//! leaves `F0` wherever its search stops along that valley: anywhere from 0.01 (a rise towards
//! grazing theta_d of 60 times what the images show) to 1 (no rise). On the same Bunny and
//! fruitwood-241 the fit stopped at 0.015 at 320x240 and at 1 at 128x96, and the hedge that
//! leans on it (`reconstruct::hedge`) rendered 0.25 and 0.44 (docs/evaluation.md 1ah).
//!
//! The rule here ([`F0Rule::Physical`], the default): where the pixels cannot tell `F0`
//! ([`fresnel_identifiable`]), it is set from physics, not searched: a dielectric's 0.04
//! (index 1.5, [`MIN_HELD_F0`]), raised to the least value that keeps every channel's `ks` at
//! most 1 when the lobe is brighter than a dielectric's can be (a metal's highlight: its
//! `F0` is high and its rise small). `ks F0` is what the free fit determines, so that least
//! value is the largest channel's `ks F0`. A lobe that fit makes at least [`BODY_ALPHA`]
//! rough is not a highlight but the body's reflection (green-latex's and the fabrics' fits put
//! their colour there, with `kd` near 0): light that entered the surface leaves it without
//! the interface's rise towards grazing, so its `F0` is 1 (no rise). Where the pixels do tell
//! `F0` (several lights) the free fit stands.
//!
//! Used by the reconstruction wherever it leans on Lambert + GGX: the ladder's Lambert + GGX
//! rung, the analytic prior of unobserved cells (`reconstruct::plausible`), the hedge, the
//! carry (`reconstruct::carry`) and the halves' check of a chosen Lambert + GGX
//! (`reconstruct::core::half_disagreement`). Not by the baselines a user would fit
//! (`reconstruct::baselines::fit_lambert_ggx`, the bar every bench compares against): those
//! stay the plain least-squares fit. Pure: no I/O.

use super::baselines::{fit_lambert_ggx, reflectance_samples};
use super::observe::Observation;
use crate::brdf::analytic::{LambertGgx, MAX_WEIGHT, pixel_weight};
use serde::{Deserialize, Serialize};

/// Pixels that all lie below this theta_d (degrees; but for [`FRESNEL_MIN_SHARE`] of them)
/// cannot tell a lobe's `F0` from its height: Schlick's factor `(1 - cos theta_d)^5` is below
/// 4e-4 there, so the Fresnel factor is one constant. (It reaches a typical `F0` of 0.02 only
/// at 57 degrees; a rule at 55 degrees, measured in docs/evaluation.md section 1w, also moved
/// materials of spread rigs whose pixels stop short of that, some either way.)
pub const FRESNEL_THETA_D_DEG: f64 = 35.0;

/// The share of pixels at or beyond [`FRESNEL_THETA_D_DEG`] a lobe's `F0` needs to be fitted.
pub const FRESNEL_MIN_SHARE: f64 = 0.01;

/// The least `F0` a lobe may take when its pixels cannot tell it (a dielectric's, index 1.5):
/// its rise towards grazing theta_d is then at most 1 / 0.04 = 25 times what the images show.
pub const MIN_HELD_F0: f64 = 0.04;

/// A lobe at least this rough (GGX alpha) is the body's reflection, not a highlight: its `F0`
/// is 1 where the pixels cannot tell it (the module header). Measured in docs/evaluation.md
/// 1ah: the lobes of green-latex, pink-fabric and pink-fabric2 seen by one light are 0.59-0.85
/// rough, those of alum-bronze, fruitwood-241 and blue-acrylic 0.02-0.16.
pub const BODY_ALPHA: f64 = 0.5;

/// Whether the pixels reach far enough in theta_d to tell a lobe's `F0` from its height.
pub fn fresnel_identifiable(obs: &[Observation]) -> bool {
    let limit = FRESNEL_THETA_D_DEG.to_radians();
    let far = obs.iter().filter(|o| o.angles.theta_d >= limit).count();
    far as f64 >= FRESNEL_MIN_SHARE * obs.len() as f64 && far > 0
}

/// How the reconstruction's Lambert + GGX sets `F0` where the pixels cannot tell it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum F0Rule {
    /// Wherever the least-squares search stops (until session 45; reports written before).
    #[default]
    Free,
    /// A dielectric's 0.04, raised to keep `ks` at most 1 ([`physical_f0`]), or 1 for a
    /// lobe that is the body's reflection ([`BODY_ALPHA`]); the default since session 45
    /// (docs/evaluation.md 1ah).
    Physical,
}

impl F0Rule {
    pub fn name(self) -> &'static str {
        match self {
            Self::Free => "free",
            Self::Physical => "physical",
        }
    }

    /// Reads a name of [`F0Rule::name`].
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "free" => Some(Self::Free),
            "physical" => Some(Self::Physical),
            _ => None,
        }
    }
}

/// The `F0` of [`F0Rule::Physical`] for a lobe whose free fit is `free`: the largest channel's
/// `ks F0` (what one theta_d determines), at least [`MIN_HELD_F0`] and at most 1. `None` when
/// the fit is not finite.
pub fn physical_f0(free: &LambertGgx) -> Option<f64> {
    if !free.ks.iter().chain([&free.f0]).all(|x| x.is_finite()) {
        return None;
    }
    let product = free
        .ks
        .iter()
        .map(|k| k * free.f0 / MAX_WEIGHT)
        .fold(0.0f64, f64::max);
    Some(product.clamp(MIN_HELD_F0, 1.0))
}

/// Lambert + GGX fitted to the pixels as [`fit_lambert_ggx`] does, with `F0` set by `rule`
/// where the pixels cannot tell it. `None` when it cannot be fitted.
pub fn fit_lambert_ggx_held(obs: &[Observation], rule: F0Rule) -> Option<LambertGgx> {
    let free = fit_lambert_ggx(obs)?;
    if rule == F0Rule::Free || fresnel_identifiable(obs) {
        return Some(free);
    }
    // Where the free search already stopped at the rule's F0 it is kept: a second search with
    // F0 fixed can stop in a worse local optimum (pink-fabric's lobe: alpha 1 against 0.85).
    let samples = reflectance_samples(obs);
    let fixed = |f0: f64| {
        if (free.f0 - f0).abs() <= 1e-9 {
            Some(free)
        } else {
            LambertGgx::fit_weighted_f0(&samples, pixel_weight, f0, f0).ok()
        }
    };
    let held = fixed(physical_f0(&free)?)?;
    if held.alpha >= BODY_ALPHA {
        fixed(1.0)
    } else {
        Some(held)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::Brdf;
    use nalgebra::Vector3;

    /// Pixels of `truth` seen from +z and lit `deg` degrees from it (one light beside the
    /// camera: theta_d near deg / 2), plus, with `far`, seen from 60 degrees one side and lit
    /// from 60 degrees the other (theta_d near 60 degrees), as a second image.
    fn pixels(truth: &LambertGgx, deg: f64, far: bool) -> Vec<Observation> {
        let dir = |deg: f64| {
            let a = deg.to_radians();
            Vector3::new(a.sin(), 0.0, a.cos())
        };
        let mut out = Observation::lobe_pixels(truth, Vector3::z(), &[dir(deg)]);
        if far {
            out.extend(
                Observation::lobe_pixels(truth, dir(-60.0), &[dir(60.0)])
                    .into_iter()
                    .map(|mut o| {
                        o.image += 1;
                        o
                    }),
            );
        }
        out
    }

    #[test]
    fn one_theta_d_cannot_tell_f0_and_several_can() {
        let truth = LambertGgx {
            kd: [0.3, 0.2, 0.1],
            ks: [0.5, 0.5, 0.5],
            alpha: 0.2,
            f0: 0.04,
        };
        assert!(!fresnel_identifiable(&pixels(&truth, 30.0, false)));
        assert!(fresnel_identifiable(&pixels(&truth, 30.0, true)));
    }

    #[test]
    fn a_dielectric_lobe_seen_at_one_theta_d_gets_a_dielectric_f0() {
        // a dielectric's lobe, seen only near theta_d 15 degrees: the free fit may stop
        // anywhere along ks F0 = 0.02; the physical rule writes 0.04 and the same ks F0,
        // so the grazing rise is a dielectric's
        let truth = LambertGgx {
            kd: [0.3, 0.2, 0.1],
            ks: [0.5, 0.5, 0.5],
            alpha: 0.2,
            f0: 0.04,
        };
        let obs = pixels(&truth, 30.0, false);
        let held = fit_lambert_ggx_held(&obs, F0Rule::Physical).expect("fits");
        assert!((held.f0 - MIN_HELD_F0).abs() < 1e-12, "F0 {}", held.f0);
        for c in 0..3 {
            let (got, want) = (held.ks[c] * held.f0, truth.ks[c] * truth.f0);
            assert!(
                (got / want - 1.0).abs() < 0.05,
                "ch {c}: ks F0 {got} vs {want}"
            );
        }
        // the table agrees with the truth at grazing theta_d too (the rise is the truth's)
        let (wi, wo) = crate::brdf::coords::HalfDiff {
            theta_h: 0.05,
            phi_h: 0.0,
            theta_d: 80f64.to_radians(),
            phi_d: 1.0,
        }
        .to_directions();
        let (a, b) = (held.eval_local(&wi, &wo), truth.eval_local(&wi, &wo));
        assert!(
            (a[1] / b[1] - 1.0).abs() < 0.1,
            "grazing {} vs {}",
            a[1],
            b[1]
        );
        // and the free fit is what the free rule returns
        assert_eq!(
            fit_lambert_ggx_held(&obs, F0Rule::Free),
            fit_lambert_ggx(&obs)
        );
    }

    #[test]
    fn a_lobe_brighter_than_a_dielectric_gets_the_least_f0_that_keeps_ks_at_most_one() {
        // a metal's coloured highlight: ks F0 = 0.6 in red; F0 0.04 would need ks 15
        let truth = LambertGgx {
            kd: [0.02, 0.02, 0.02],
            ks: [0.75, 0.2, 0.15],
            alpha: 0.25,
            f0: 0.8,
        };
        let obs = pixels(&truth, 30.0, false);
        let held = fit_lambert_ggx_held(&obs, F0Rule::Physical).expect("fits");
        assert!((held.f0 - 0.6).abs() < 0.03, "F0 {}", held.f0);
        assert!(held.ks.iter().all(|&k| k <= MAX_WEIGHT + 1e-12));
        assert!((held.ks[0] - 1.0).abs() < 0.05, "ks {:?}", held.ks);
    }

    #[test]
    fn a_lobe_as_broad_as_a_body_gets_no_rise() {
        // a coloured lobe of alpha 0.7 and almost no kd: the body's reflection (as green-latex
        // is fitted); the physical rule writes F0 1, so nothing rises towards grazing
        let truth = LambertGgx {
            kd: [0.0, 0.02, 0.005],
            ks: [0.2, 0.25, 0.12],
            alpha: 0.7,
            f0: 1.0,
        };
        let held =
            fit_lambert_ggx_held(&pixels(&truth, 30.0, false), F0Rule::Physical).expect("fits");
        assert!(held.alpha >= BODY_ALPHA, "alpha {}", held.alpha);
        assert_eq!(held.f0, 1.0);
        // the same lobe made sharp is a highlight and rises as a dielectric's
        let sharp = LambertGgx {
            alpha: 0.2,
            ks: [0.2, 0.25, 0.12].map(|k| k * 0.04),
            f0: 0.04,
            ..truth
        };
        let held =
            fit_lambert_ggx_held(&pixels(&sharp, 30.0, false), F0Rule::Physical).expect("fits");
        assert!(held.alpha < BODY_ALPHA, "alpha {}", held.alpha);
        assert!((held.f0 - MIN_HELD_F0).abs() < 1e-12, "F0 {}", held.f0);
    }

    #[test]
    fn where_several_lights_tell_f0_the_free_fit_stands() {
        let truth = LambertGgx {
            kd: [0.3, 0.2, 0.1],
            ks: [0.5, 0.5, 0.5],
            alpha: 0.2,
            f0: 0.3,
        };
        let obs = pixels(&truth, 30.0, true);
        assert_eq!(
            fit_lambert_ggx_held(&obs, F0Rule::Physical),
            fit_lambert_ggx(&obs)
        );
    }

    #[test]
    fn the_rule_names_read_back() {
        for r in [F0Rule::Free, F0Rule::Physical] {
            assert_eq!(F0Rule::parse(r.name()), Some(r));
        }
        assert_eq!(F0Rule::parse("dielectric"), None);
        let bad = LambertGgx {
            kd: [0.0; 3],
            ks: [f64::NAN, 0.0, 0.0],
            alpha: 0.1,
            f0: 0.5,
        };
        assert_eq!(physical_f0(&bad), None);
    }
}
