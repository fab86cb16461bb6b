//! The baselines a user would otherwise fit to the same pixels: Lambert and Lambert + GGX,
//! least squares on the pixels themselves (image space: residuals of `f E cos theta_i`, so
//! `brdf::analytic` weights f_r residuals by `cos theta_i`), to every observed pixel, in the
//! local frame of its (rasterised, possibly wrong) normal. Pure.

use super::observe::{Observation, to_local};
use crate::brdf::analytic::{Lambert, LambertGgx, ReflectanceSample, pixel_weight};

/// The observations as samples for `brdf::analytic` fits.
pub fn reflectance_samples(obs: &[Observation]) -> Vec<ReflectanceSample> {
    obs.iter()
        .map(|o| {
            let (wi, wo) = to_local(&o.normal, &o.light, &o.view);
            ReflectanceSample {
                wi,
                wo,
                rgb: o.reflectance,
            }
        })
        .collect()
}

/// Lambert fitted to pixels by image-space least squares; `None` when it cannot be fitted (no
/// pixel, or non-finite values).
pub fn fit_lambert(obs: &[Observation]) -> Option<Lambert> {
    Lambert::fit_weighted(&reflectance_samples(obs), pixel_weight).ok()
}

/// Lambert + GGX fitted to pixels by image-space least squares.
pub fn fit_lambert_ggx(obs: &[Observation]) -> Option<LambertGgx> {
    LambertGgx::fit_weighted(&reflectance_samples(obs), pixel_weight).ok()
}

/// Both baselines.
pub fn fit_baselines(obs: &[Observation]) -> (Option<Lambert>, Option<LambertGgx>) {
    (fit_lambert(obs), fit_lambert_ggx(obs))
}
