//! The theta_d extrapolation check: how each model family carries what it learnt at lower
//! theta_d to higher theta_d, on the scene's own pixels.
//!
//! Why: the ladder holds out whole images, and a held-out image's pixels fall between the
//! training images' theta_d; none tests the extrapolation to grazing theta_d that a rendered
//! sphere's rim reads (docs/evaluation.md sections 1d, 1n, 1r: fruitwood-241's spread losses are
//! a grazing Fresnel rise the basis's prior gets wrong from the rows below it). Here the
//! reliable pixels are split at a quantile of their theta_d (theta_d = the angle between light
//! and half vector: it does not depend on the normal, so the split is not moved by the normals'
//! error); Lambert, Lambert + GGX, the chosen basis rung and that basis with a GGX peak are
//! fitted to the pixels below it, as the ladder fits them, and scored, in the ladder's log
//! space, on the pixels above it.
//!
//! A report and a study knob (`bench ... --extrapolation`), off by default: on the 72-scene grid
//! the splits reach theta_d 47 degrees, the losses lie at 60-75, and the check does not point
//! at them (docs/evaluation.md section 1t). No choice reads the check.
//!
//! The ladder's `--basis-rung extrapolates` (a study knob since session 50) scores every basis
//! rung on a split of its own (`ladder_extrapolation.rs`), sharing this check's folds
//! (`ladder::split_fold`).
//!
//! Pure: no I/O. Must not change a fit or a choice: it only scores (the ladder chooses).

use super::baselines::{fit_lambert, fit_lambert_ggx};
use super::ladder::{
    AnalyticCandidate, FoldData, WithPeak, fit_peak, log_error, split_fold, subset,
};
use super::observation::Observation;
use super::prior::Prior;
use super::reliable::{Reliable, ReliableSettings};
use super::trials::{BasisFit, basis_samples};
use crate::stats::percentile_sorted;
use serde::{Deserialize, Serialize};

/// Knobs of the check.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExtrapolationSettings {
    /// Quantiles of the reliable pixels' theta_d to split at (one check each; empty: none).
    pub quantiles: Vec<f64>,
    /// No check when the reliable pixels' theta_d spans less than this (5 % to 95 %), degrees:
    /// one light at the camera gives one theta_d, and nothing to extrapolate from.
    pub min_span_deg: f64,
    /// No check with fewer pixels than this on either side of the split.
    pub min_pixels: usize,
}

impl Default for ExtrapolationSettings {
    fn default() -> Self {
        Self {
            quantiles: vec![0.8],
            min_span_deg: 10.0,
            min_pixels: 200,
        }
    }
}

impl ExtrapolationSettings {
    /// No check.
    pub fn off() -> Self {
        Self {
            quantiles: Vec::new(),
            ..Self::default()
        }
    }
}

/// One split's outcome (log-space held-out errors of each family above the split).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Extrapolation {
    pub quantile: f64,
    /// theta_d at the split, degrees.
    pub split_deg: f64,
    pub train_pixels: usize,
    pub held_pixels: usize,
    pub lambert: Option<f64>,
    pub lambert_ggx: Option<f64>,
    pub basis: Option<f64>,
    pub basis_peak: Option<f64>,
}

impl Extrapolation {
    /// The basis's error over Lambert + GGX's (above 1: the lobe extrapolates better).
    pub fn basis_over_analytic(&self) -> Option<f64> {
        match (self.basis, self.lambert_ggx) {
            (Some(b), Some(a)) if a > 0.0 && b.is_finite() => Some(b / a),
            _ => None,
        }
    }
}

/// theta_d of an observation, degrees.
fn theta_d_deg(o: &Observation) -> f64 {
    o.angles.theta_d.to_degrees()
}

/// What the check needs of the reconstruction.
pub struct ExtrapolationInput<'a> {
    pub prior: &'a dyn Prior,
    pub reliable: &'a Reliable,
    pub reliable_settings: &'a ReliableSettings,
    /// The pixels the analytic rungs fit (all observed, or the reliable ones).
    pub analytic_pixels: &'a [Observation],
    pub analytic_max_pixels: usize,
    pub samples: usize,
    pub basis_fit: BasisFit,
    /// The chosen basis rung.
    pub k: usize,
    pub eta: f64,
    pub seed: u64,
}

/// The checks at each of `settings.quantiles`; empty when the theta_d span or the pixels are
/// too few.
pub fn check(input: &ExtrapolationInput, settings: &ExtrapolationSettings) -> Vec<Extrapolation> {
    let pool = &input.reliable.pixels;
    let mut td: Vec<f64> = pool
        .iter()
        .map(theta_d_deg)
        .filter(|x| x.is_finite())
        .collect();
    if td.len() < 2 * settings.min_pixels.max(1) {
        return Vec::new();
    }
    td.sort_by(f64::total_cmp);
    if percentile_sorted(&td, 0.95) - percentile_sorted(&td, 0.05) < settings.min_span_deg {
        return Vec::new();
    }
    settings
        .quantiles
        .iter()
        .filter_map(|&q| check_at(input, settings, q, percentile_sorted(&td, q)))
        .collect()
}

fn check_at(
    input: &ExtrapolationInput,
    settings: &ExtrapolationSettings,
    q: f64,
    split: f64,
) -> Option<Extrapolation> {
    let below = |o: &Observation| theta_d_deg(o) < split;
    let FoldData {
        train,
        held,
        anchor,
    } = split_fold(input.reliable, input.reliable_settings.use_brightest, |o| {
        !below(o)
    });
    if train.len() < settings.min_pixels || held.len() < settings.min_pixels {
        return None;
    }
    let analytic_train: Vec<Observation> = input
        .analytic_pixels
        .iter()
        .filter(|o| below(o))
        .copied()
        .collect();
    let analytic_train = subset(
        &analytic_train,
        input.analytic_max_pixels,
        input.seed ^ 0xE7,
    );
    let lambert =
        fit_lambert(&analytic_train).and_then(|m| log_error(&AnalyticCandidate(m), &held));
    let lambert_ggx =
        fit_lambert_ggx(&analytic_train).and_then(|m| log_error(&AnalyticCandidate(m), &held));
    let fit = basis_samples(
        input.prior,
        &train,
        anchor.as_ref(),
        input.reliable_settings,
        input.samples,
        input.k,
        input.seed,
        input.basis_fit,
    );
    let (basis, basis_peak) =
        match input
            .prior
            .fit_lazy(&fit.samples, input.k, input.eta * fit.eta_scale)
        {
            Ok(base) => {
                let plain = log_error(base.as_ref(), &held);
                let peak_train = subset(&train, input.analytic_max_pixels, input.seed ^ 0xE8);
                let peaked = fit_peak(base.as_ref(), &peak_train)
                    .and_then(|peak| log_error(&WithPeak { base, peak }, &held));
                (plain, peaked)
            }
            Err(_) => (None, None),
        };
    Some(Extrapolation {
        quantile: q,
        split_deg: split,
        train_pixels: train.len(),
        held_pixels: held.len(),
        lambert,
        lambert_ggx,
        basis,
        basis_peak,
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::reconstruct::observation::Seen;
    use crate::reconstruct::prior::synthetic::CosinePrior;
    use crate::reconstruct::reliable::select_reliable;
    use nalgebra::Vector3;

    /// A Lambertian cap (albedo 0.3) seen from +z under `lights` lights spread from 10 to 70
    /// degrees off the view.
    pub(crate) fn pixels(lights: usize) -> Vec<Observation> {
        pixels_of(lights, |_| 0.3 / std::f64::consts::PI)
    }

    /// The same cap with the reflectance `f(theta_d)`.
    fn pixels_of(lights: usize, f: impl Fn(f64) -> f64) -> Vec<Observation> {
        let v = Vector3::z();
        let mut out = Vec::new();
        for j in 0..lights {
            let a = if lights == 1 {
                30f64
            } else {
                10.0 + 60.0 * j as f64 / (lights - 1) as f64
            }
            .to_radians();
            let l = Vector3::new(a.sin(), 0.0, a.cos());
            for i in 0..400 {
                let t = i as f64 * 2.399;
                let r = 0.4 * ((i as f64 + 0.5) / 400.0).sqrt();
                let n = Vector3::new(r * t.cos(), r * t.sin(), 1.0).normalize();
                let Some(mut o) =
                    Observation::new(Seen::pixel(j, i as u32, 0, n), l, v, [1.0; 3], [1.0; 3])
                else {
                    continue;
                };
                o.reflectance = [f(o.angles.theta_d); 3];
                o.radiance = o.reflectance.map(|x| x * o.cos_theta_i);
                out.push(o);
            }
        }
        out
    }

    fn run(obs: &[Observation]) -> Vec<Extrapolation> {
        let rs = ReliableSettings::none();
        let reliable = select_reliable(obs, &rs);
        check(
            &ExtrapolationInput {
                prior: &CosinePrior { k: 4 },
                reliable: &reliable,
                reliable_settings: &rs,
                analytic_pixels: obs,
                analytic_max_pixels: 4000,
                samples: 40,
                basis_fit: BasisFit::Samples,
                k: 4,
                eta: 1e-6,
                seed: 1,
            },
            &ExtrapolationSettings {
                quantiles: vec![0.5, 0.8],
                ..Default::default()
            },
        )
    }

    #[test]
    fn the_pixels_above_the_split_score_fits_to_those_below_it() {
        let obs = pixels(7);
        let checks = run(&obs);
        assert_eq!(checks.len(), 2, "{checks:#?}");
        let (a, b) = (&checks[0], &checks[1]);
        assert!(a.split_deg < b.split_deg, "{checks:#?}");
        assert_eq!(a.train_pixels + a.held_pixels, obs.len());
        assert!(b.held_pixels < a.held_pixels);
        // A Lambertian surface: Lambert carries it to any theta_d (up to bins whose centre
        // lies below the horizon, read as zero).
        let lambert = a.lambert.expect("Lambert scored");
        assert!(lambert < 0.01, "{a:#?}");
        assert!(
            a.lambert_ggx.expect("Lambert + GGX scored") < 0.05,
            "{a:#?}"
        );
        assert!(a.basis.is_some() && a.basis_peak.is_some(), "{a:#?}");
    }

    #[test]
    fn a_rise_above_the_split_is_what_a_fit_below_it_misses() {
        let obs = pixels_of(7, |td| 0.1 * (1.0 + 3.0 * td.sin().powi(2)));
        let checks = run(&obs);
        let a = &checks[0];
        let lambert = a.lambert.expect("Lambert scored");
        assert!(lambert > 0.05, "{a:#?}");
    }

    #[test]
    fn one_light_gives_no_check() {
        let obs = pixels(1);
        assert!(!obs.is_empty());
        assert!(run(&obs).is_empty());
    }

    #[test]
    fn quantiles_are_nearest_rank() {
        let v: Vec<f64> = (0..11).map(f64::from).collect();
        assert_eq!(percentile_sorted(&v, 0.0), 0.0);
        assert_eq!(percentile_sorted(&v, 0.8), 8.0);
        assert_eq!(percentile_sorted(&v, 1.0), 10.0);
        assert!(percentile_sorted(&[], 0.5).is_nan());
    }
}
