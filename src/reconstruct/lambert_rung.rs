//! The reconstruction's own Lambert: the model ladder's Lambert rung and a written Lambert.
//!
//! Least squares on the pixels (what a user fits, `reconstruct::baselines::fit_lambert`, the
//! bar every bench compares against) is pulled by the pixels the mesh explains wrongly: a
//! photogrammetry mesh casts shadows a little off the true ones and its silhouette mixes the
//! object's edge with the background, so a few pixels read far darker than the albedo says,
//! and least squares follows them by their value. On Mitsuba 3's pure Lambertian Bunny (albedo
//! 0.75, 0.6, 0.45; the realistic mesh, one light) it wrote 0.742 in red, 1.1 % low, and
//! rendered 0.0102 against the truth; the exact mesh's pixels give 0.747 (docs/evaluation.md
//! 1aj). [`LambertFit::Median`] (the default) takes the weighted median of the pixels'
//! reflectance instead, each pixel weighted by `cos theta_i` as the pixels' least squares
//! weights it (`brdf::analytic::pixel_weight`): 0.747 on that mesh too, 0.0035.
//!
//! Used by the ladder's Lambert rung (fitted to each fold's training pixels), the written
//! Lambert and the Lambert alternative of `report.json`. Not by the baselines, nor by the
//! Lambert + GGX fits (`reconstruct::fresnel`). Pure: no I/O.

use serde::{Deserialize, Serialize};

use super::baselines::{fit_lambert, reflectance_samples};
use super::observe::Observation;
use crate::brdf::analytic::{Lambert, pixel_weight};

/// How the reconstruction's Lambert albedo is fitted to its pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LambertFit {
    /// Image-space least squares, as the baselines (until session 47; reports written before).
    #[default]
    LeastSquares,
    /// The `cos theta_i`-weighted median of the pixels' reflectance, per channel (the
    /// default since session 47).
    Median,
}

impl LambertFit {
    pub fn name(self) -> &'static str {
        match self {
            Self::LeastSquares => "least-squares",
            Self::Median => "median",
        }
    }

    /// Reads a name of [`LambertFit::name`].
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "least-squares" => Some(Self::LeastSquares),
            "median" => Some(Self::Median),
            _ => None,
        }
    }
}

/// Lambert fitted to the pixels by `rule`; `None` when it cannot be fitted (no pixel above
/// the horizon, or no finite value).
pub fn fit_lambert_rung(obs: &[Observation], rule: LambertFit) -> Option<Lambert> {
    match rule {
        LambertFit::LeastSquares => fit_lambert(obs),
        LambertFit::Median => {
            Lambert::fit_weighted_median(&reflectance_samples(obs), pixel_weight).ok()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    /// Pixels of a grey Lambertian surface of `albedo`, seen from +z, lit 30 degrees from it.
    fn pixels(albedo: f64) -> Vec<Observation> {
        let a = 30f64.to_radians();
        let truth = Lambert {
            albedo: [albedo; 3],
        };
        Observation::lobe_pixels(&truth, Vector3::z(), &[Vector3::new(a.sin(), 0.0, a.cos())])
    }

    #[test]
    fn the_median_rung_ignores_pixels_in_a_shadow_the_mesh_does_not_cast() {
        let albedo = 0.6;
        let mut obs = pixels(albedo);
        // A tenth of the pixels the mesh calls lit lie in the true shadow: a tenth as bright.
        for o in obs.iter_mut().step_by(10) {
            o.reflectance = o.reflectance.map(|r| 0.1 * r);
        }
        let ls = fit_lambert_rung(&obs, LambertFit::LeastSquares).expect("fit");
        let med = fit_lambert_rung(&obs, LambertFit::Median).expect("fit");
        assert!(ls.albedo[0] < 0.93 * albedo, "{ls:?}");
        assert!((med.albedo[0] - albedo).abs() < 1e-9, "{med:?}");
        // Least squares is the baselines' fit, unchanged.
        assert_eq!(Some(ls), fit_lambert(&obs));
    }

    #[test]
    fn no_usable_pixel_gives_none() {
        let mut obs = pixels(0.5);
        for o in &mut obs {
            o.reflectance = [f64::NAN; 3];
        }
        assert_eq!(fit_lambert_rung(&obs, LambertFit::Median), None);
        assert_eq!(fit_lambert_rung(&[], LambertFit::Median), None);
    }

    #[test]
    fn names_round_trip() {
        for f in [LambertFit::LeastSquares, LambertFit::Median] {
            assert_eq!(LambertFit::parse(f.name()), Some(f));
        }
        assert_eq!(LambertFit::parse("mean"), None);
    }
}
