//! The baselines a user would otherwise fit to the same pixels: Lambert and Lambert + GGX
//! least-squares fits (`brdf::analytic`) to every observed pixel's reflectance, in the local
//! frame of its (rasterised, possibly wrong) normal. Pure.

use super::observe::{Observation, to_local};
use crate::brdf::analytic::{FitError, Lambert, LambertGgx, ReflectanceSample};

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

/// Lambert and Lambert + GGX fitted to the observations.
pub fn fit_baselines(obs: &[Observation]) -> Result<(Lambert, LambertGgx), FitError> {
    let samples = reflectance_samples(obs);
    Ok((Lambert::fit(&samples)?, LambertGgx::fit(&samples)?))
}
