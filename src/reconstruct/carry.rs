//! Pixels carried to their basis row's centre before a basis fit (`reconstruct --carry`; on
//! by default since session 42).
//!
//! A basis holds one value per row, the value at the row's centre bin, and a row stands for a
//! block of bins (at the default stride two theta_d and two phi_d bins). A pixel anywhere in
//! the block lends its row's sample its own value: on a steep part of a BRDF (the Fresnel
//! rise towards grazing theta_d) the row's median is then not the value at the centre. Here
//! each pixel's reflectance is multiplied, channel by channel, by the ratio of a smooth model
//! (Lambert + GGX fitted to the same pixels) at the pixel's theta_h and phi_h with the row
//! centre's theta_d and phi_d, to its value at the pixel's own directions (from its normal,
//! light and view): `r * m(centre) / m(pixel)`, the ratio bounded by [`MAX_RATIO`] either way.
//! Where the model is flat the ratio is 1. The brightest pixel (eq. 2, its normal taken as the
//! half vector) is never carried.
//!
//! Measured alone in docs/evaluation.md section 1s (session 33): it lowered the basis fit's
//! error on glossy materials under spread lights and raised it on broad ones; not adopted
//! then. Since session 42 it is the default together with the ladder's lowest basis rung
//! (`LadderSettings::basis_rung`): on the six-seed accuracy grid that pair left no scene
//! worse than the better analytic fit by more than 10 % (section 1ae).
//!
//! Pure: wraps a prior; no I/O. Must not change anything but the values the pixels lend their
//! rows (selection, fits and tabulation are the inner prior's).

use super::observe::{Observation, to_local};
use super::prior::{Candidate, Prior, Sample, delegate_prior};
use crate::brdf::Brdf;
use crate::brdf::analytic::LambertGgx;
use crate::brdf::coords::{HalfDiff, MerlBin};
use crate::brdf::ridge::RidgeError;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// The largest factor a pixel's value is carried by (either way).
pub const MAX_RATIO: f64 = 4.0;

/// Whether the written basis fit sees pixels carried to their row's centre.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Carry {
    /// The pixels as they are (reports written before this existed).
    #[default]
    Off,
    /// Along theta_d and phi_d, the axes the basis grid strides (the pixel's theta_h kept).
    Difference,
}

impl Carry {
    pub fn name(self) -> &'static str {
        match self {
            Self::Off => "off",
            Self::Difference => "difference",
        }
    }

    /// Reads a name of [`Carry::name`].
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "off" => Some(Self::Off),
            "difference" => Some(Self::Difference),
            _ => None,
        }
    }
}

/// A prior whose basis fits see pixels carried to their row's centre by `model`.
pub struct CarriedPrior<'a> {
    pub inner: &'a dyn Prior,
    pub model: LambertGgx,
}

/// `r * m(target) / m(pixel)` per channel for a pixel at `(wi, wo)` (local frame) whose row's
/// centre bin is `centre`, `target` the pixel's theta_h and phi_h with the centre's theta_d and
/// phi_d, the ratio bounded by [`MAX_RATIO`]; the pixel's own value without a centre, below
/// the horizon, or where either value is not positive and finite.
pub fn carried(
    model: &dyn Brdf,
    reflectance: [f64; 3],
    (wi, wo): (Vector3<f64>, Vector3<f64>),
    centre: Option<usize>,
) -> [f64; 3] {
    let Some(b) = centre.and_then(MerlBin::from_index) else {
        return reflectance;
    };
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return reflectance;
    }
    let (p, c) = (HalfDiff::from_directions(&wi, &wo), b.centre());
    let (ci, co) = HalfDiff {
        theta_d: c.theta_d,
        phi_d: c.phi_d,
        ..p
    }
    .to_directions();
    let (at_c, at_p) = (model.eval_local(&ci, &co), model.eval_local(&wi, &wo));
    std::array::from_fn(|c| {
        let ratio = at_c[c] / at_p[c];
        if at_c[c] > 0.0 && at_p[c] > 0.0 && ratio.is_finite() {
            reflectance[c] * ratio.clamp(1.0 / MAX_RATIO, MAX_RATIO)
        } else {
            reflectance[c]
        }
    })
}

impl Prior for CarriedPrior<'_> {
    delegate_prior!();

    fn fit(
        &self,
        samples: &[Sample],
        k: usize,
        eta: f64,
    ) -> Result<Box<dyn Candidate>, RidgeError> {
        self.inner.fit(samples, k, eta)
    }

    fn fit_lazy_each<'b>(
        &'b self,
        samples: &[Sample],
        keys: &[(usize, f64)],
    ) -> Vec<Result<Box<dyn Candidate + 'b>, RidgeError>> {
        self.inner.fit_lazy_each(samples, keys)
    }

    fn fit_lazy<'b>(
        &'b self,
        samples: &[Sample],
        k: usize,
        eta: f64,
    ) -> Result<Box<dyn Candidate + 'b>, RidgeError> {
        self.inner.fit_lazy(samples, k, eta)
    }

    fn row_value(&self, o: &Observation) -> [f64; 3] {
        let centre = self
            .inner
            .row_of(o.bin)
            .and_then(|r| self.inner.row_centre(r));
        carried(
            &self.model,
            o.reflectance,
            to_local(&o.normal, &o.light, &o.view),
            centre,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::super::observation::Seen;
    use super::*;
    use crate::brdf::coords::merl_index;
    use nalgebra::Point3;

    fn glossy() -> LambertGgx {
        LambertGgx {
            kd: [0.3, 0.2, 0.1],
            ks: [0.5, 0.5, 0.5],
            alpha: 0.2,
            f0: 0.04,
        }
    }

    /// Directions with the given half and difference angles (degrees).
    fn dirs(th: f64, td: f64, pd: f64) -> (Vector3<f64>, Vector3<f64>) {
        HalfDiff {
            theta_h: th.to_radians(),
            phi_h: 0.3,
            theta_d: td.to_radians(),
            phi_d: pd.to_radians(),
        }
        .to_directions()
    }

    #[test]
    fn a_pixel_takes_the_models_ratio_to_its_rows_theta_d_and_phi_d() {
        let m = glossy();
        let (wi, wo) = dirs(12.0, 58.3, 80.0);
        let centre = MerlBin {
            theta_h: 20,
            theta_d: 60,
            phi_d: 44,
        };
        let r = [0.2, 0.3, 0.4];
        let got = carried(&m, r, (wi, wo), Some(centre.index()));
        // The model at the pixel's theta_h and phi_h with the centre's theta_d and phi_d.
        let p = HalfDiff::from_directions(&wi, &wo);
        let c = centre.centre();
        let (ti, to) = HalfDiff {
            theta_d: c.theta_d,
            phi_d: c.phi_d,
            ..p
        }
        .to_directions();
        let (at_c, at_p) = (m.eval_local(&ti, &to), m.eval_local(&wi, &wo));
        for k in 0..3 {
            let want = r[k] * at_c[k] / at_p[k];
            assert!(
                (got[k] - want).abs() <= 1e-12 * want,
                "{k}: {} {want}",
                got[k]
            );
        }
        // The Fresnel and 1 / cos factors rise with theta_d: a pixel below its row's theta_d
        // is carried up, not left as it is.
        assert!(got.iter().zip(&r).all(|(g, r)| g > r), "{got:?}");
    }

    #[test]
    fn a_flat_model_a_missing_centre_or_a_pixel_below_the_horizon_leave_the_value() {
        let lambert = LambertGgx {
            ks: [0.0; 3],
            ..glossy()
        };
        let (wi, wo) = dirs(12.0, 58.3, 80.0);
        let centre = MerlBin {
            theta_h: 20,
            theta_d: 60,
            phi_d: 44,
        }
        .index();
        let r = [0.2, 0.3, 0.4];
        assert_eq!(carried(&lambert, r, (wi, wo), Some(centre)), r);
        assert_eq!(carried(&glossy(), r, (wi, wo), None), r);
        let below = Vector3::new(wi.x, wi.y, -wi.z);
        assert_eq!(carried(&glossy(), r, (below, wo), Some(centre)), r);
    }

    #[test]
    fn the_carry_is_bounded() {
        // A mirror-like lobe: at theta_h = 0 moving theta_d from 30 to 89 degrees changes the
        // model by far more than MAX_RATIO.
        let sharp = LambertGgx {
            kd: [0.0; 3],
            ks: [1.0; 3],
            alpha: 0.01,
            f0: 0.02,
        };
        let (wi, wo) = dirs(0.05, 30.0, 90.0);
        let centre = MerlBin {
            theta_h: 0,
            theta_d: 89,
            phi_d: 90,
        }
        .index();
        let got = carried(&sharp, [1.0; 3], (wi, wo), Some(centre));
        assert!(
            got.iter().all(|&v| (v - MAX_RATIO).abs() < 1e-12),
            "{got:?}"
        );
    }

    /// Rows of two theta_d bins (centre: the even one); nothing else is used.
    struct PairRows;

    impl Prior for PairRows {
        fn max_components(&self) -> usize {
            1
        }
        fn row_of(&self, bin: usize) -> Option<usize> {
            let b = MerlBin::from_index(bin)?;
            Some(
                MerlBin {
                    theta_d: b.theta_d / 2 * 2,
                    ..b
                }
                .index(),
            )
        }
        fn select(&self, chosen: &[usize], _: &[usize], _: usize, _: usize, _: u64) -> Vec<usize> {
            chosen.to_vec()
        }
        fn fit(&self, _: &[Sample], _: usize, _: f64) -> Result<Box<dyn Candidate>, RidgeError> {
            Err(RidgeError::Empty)
        }
        fn row_centre(&self, row: usize) -> Option<usize> {
            Some(row)
        }
    }

    #[test]
    fn the_carried_prior_lends_rows_the_carried_values_and_the_inner_one_the_pixels_own() {
        let (wi, wo) = dirs(12.0, 59.4, 80.0);
        // A pixel with the normal +z seeing exactly (wi, wo) in the world.
        let seen = Seen {
            image: 0,
            x: 0,
            y: 0,
            position: Point3::origin(),
            normal: Vector3::z(),
            mean_curvature: 0.0,
            face: 0,
        };
        let o = Observation::new(seen, wi, wo, [0.2, 0.3, 0.4], [1.0; 3]).expect("above");
        let inner = PairRows;
        assert_eq!(inner.row_value(&o), o.reflectance);
        let carried_prior = CarriedPrior {
            inner: &inner,
            model: glossy(),
        };
        let centre = inner
            .row_of(merl_index(&wi, &wo))
            .and_then(|r| inner.row_centre(r));
        let (li, lo) = to_local(&o.normal, &o.light, &o.view);
        let want = carried(&glossy(), o.reflectance, (li, lo), centre);
        assert_eq!(carried_prior.row_value(&o), want);
        assert_ne!(want, o.reflectance);
        // Everything else is the inner prior's.
        assert_eq!(carried_prior.row_of(o.bin), inner.row_of(o.bin));
        assert_eq!(carried_prior.max_components(), 1);
    }
}
