//! The basis rungs' extrapolation along theta_d, for `BasisRung::Extrapolates` (a study knob
//! since session 50, measured and not adopted: docs/materials.md, "The basis rung by its
//! extrapolation").
//!
//! The ladder's folds hold out whole images, and a held-out image shares the training images'
//! theta_d: it cannot tell how a basis rung carries the pixels to the grazing theta_d no image
//! saw well, which the ridge weight decides (on alum-bronze on the half Spot with spread lights
//! the weak ridge, eta 1, rendered 1.8-2.9x worse than eta 40 (k 10-64) within noise of it on held-out images;
//! on fruitwood-241 the other way round). Here the reliable pixels are split at
//! [`RUNG_QUANTILE`] of their theta_d (the angle between light and half vector: the normals'
//! error does not move it), every basis rung is fitted to those at or below the split and
//! scored, in the ladder's log space, on those above it, as session 34's report-only check
//! (`reconstruct::extrapolation`) scores the families; the folds are the ladder's
//! (`split_fold`). Only when the two sides' median theta_d lie [`RUNG_MIN_GAP_DEG`] apart (one
//! light beside the camera sees one theta_d).
//!
//! Pure: no I/O. Deterministic for a seed. Must not choose: the ladder reads the errors.

use super::{Observation, Prior, Reliable, ReliableSettings, basis_samples, log_error, split_fold};
use crate::reconstruct::trials::BasisFit;
use crate::stats::percentile_sorted;

/// theta_d of an observation, degrees.
fn theta_d_deg(o: &Observation) -> f64 {
    o.angles.theta_d.to_degrees()
}

/// The pixels above this quantile of theta_d score the basis rungs ([`score_rungs`]).
pub const RUNG_QUANTILE: f64 = 0.7;

/// The held-out pixels' median theta_d must exceed the training pixels' by this much, degrees.
pub const RUNG_MIN_GAP_DEG: f64 = 10.0;

/// What the ladder's reason says when the images do not span theta_d.
pub const NOT_SPANNED: &str = "the images do not span theta_d enough to score the basis rungs' \
     extrapolation, so the lowest held-out error is written";

/// What [`score_rungs`] needs.
pub struct RungInput<'a> {
    pub prior: &'a dyn Prior,
    pub reliable: &'a Reliable,
    pub reliable_settings: &'a ReliableSettings,
    pub samples: usize,
    /// k of the fit's samples where a rung gives none (the ladder's fallback).
    pub fallback: usize,
    pub basis_fit: BasisFit,
    /// `(k, eta)` of each basis rung, in order (eta before the fit's scale).
    pub keys: &'a [(usize, f64)],
    pub seed: u64,
}

/// The split of [`score_rungs`] and each rung's log-space error on it.
#[derive(Clone, Debug, PartialEq)]
pub struct RungScores {
    pub split_deg: f64,
    pub train_median_deg: f64,
    pub held_median_deg: f64,
    pub held_pixels: usize,
    /// One per key, `None` where the fit failed.
    pub errors: Vec<Option<f64>>,
}

impl RungScores {
    /// One clause for the ladder's reason.
    pub fn describe(&self) -> String {
        format!(
            "extrapolation scored on the {} pixels of theta_d above {:.1} degrees (median {:.1}) \
             fitted to the others (median {:.1})",
            self.held_pixels, self.split_deg, self.held_median_deg, self.train_median_deg
        )
    }
}

/// The split at [`RUNG_QUANTILE`] of `theta_d` (degrees) and the medians below and above it
/// (at or below the split, above it); `None` when the pixels are too few or the medians lie
/// less than [`RUNG_MIN_GAP_DEG`] apart.
pub fn rung_split(theta_d: &[f64]) -> Option<(f64, f64, f64)> {
    if theta_d.len() < 20 || theta_d.iter().any(|t| !t.is_finite()) {
        return None;
    }
    let mut sorted = theta_d.to_vec();
    sorted.sort_by(f64::total_cmp);
    let split = percentile_sorted(&sorted, RUNG_QUANTILE);
    let n_below = sorted.partition_point(|&t| t <= split);
    let (below, above) = sorted.split_at(n_below);
    if above.len() < 10 {
        return None;
    }
    let (train, held) = (percentile_sorted(below, 0.5), percentile_sorted(above, 0.5));
    (held - train >= RUNG_MIN_GAP_DEG).then_some((split, train, held))
}

/// Every basis rung of `input.keys` fitted to the reliable pixels at or below the split and
/// scored, in the ladder's log space, on those above it; `None` when the pixels do not span
/// theta_d.
pub fn score_rungs(input: &RungInput) -> Option<RungScores> {
    let theta_d: Vec<f64> = input.reliable.pixels.iter().map(theta_d_deg).collect();
    let (split, train_median_deg, held_median_deg) = rung_split(&theta_d)?;
    let data = split_fold(input.reliable, input.reliable_settings.use_brightest, |o| {
        theta_d_deg(o) > split
    });
    if data.train.len() < 5 || data.held.is_empty() {
        return None;
    }
    let fit = basis_samples(
        input.prior,
        &data.train,
        data.anchor.as_ref(),
        input.reliable_settings,
        input.samples,
        input.fallback,
        input.seed,
        input.basis_fit,
    );
    let keys: Vec<(usize, f64)> = input
        .keys
        .iter()
        .map(|&(k, eta)| (k, eta * fit.eta_scale))
        .collect();
    let errors = input
        .prior
        .fit_lazy_each(&fit.samples, &keys)
        .into_iter()
        .map(|c| log_error(c.ok()?.as_ref(), &data.held))
        .collect();
    Some(RungScores {
        split_deg: split,
        train_median_deg,
        held_median_deg,
        held_pixels: data.held.len(),
        errors,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reconstruct::extrapolation::tests::pixels;
    use crate::reconstruct::prior::synthetic::CosinePrior;
    use crate::reconstruct::reliable::select_reliable;

    #[test]
    fn a_spread_of_theta_d_splits_the_rungs_above_the_quantile() {
        // theta_d from 5 to 75 degrees, evenly
        let t: Vec<f64> = (0..100).map(|i| 5.0 + 70.0 * i as f64 / 99.0).collect();
        let (split, train, held) = rung_split(&t).expect("spans theta_d");
        assert!((split - 53.3).abs() < 0.5, "{split}");
        assert_eq!(t.iter().filter(|&&x| x > split).count(), 30);
        assert!(held - train > 30.0, "{train} {held}");
    }

    #[test]
    fn one_theta_d_does_not_split_the_rungs() {
        // one light beside the camera: theta_d 14-17 degrees
        let t: Vec<f64> = (0..200)
            .map(|i| 14.0 + 3.0 * (i % 7) as f64 / 6.0)
            .collect();
        assert!(rung_split(&t).is_none());
        assert!(rung_split(&[17.0; 5]).is_none());
        assert!(rung_split(&[f64::NAN; 50]).is_none());
    }

    #[test]
    fn the_rungs_are_scored_above_the_split() {
        let obs = pixels(7);
        let rs = ReliableSettings::none();
        let reliable = select_reliable(&obs, &rs);
        let input = RungInput {
            prior: &CosinePrior { k: 4 },
            reliable: &reliable,
            reliable_settings: &rs,
            samples: 40,
            fallback: 4,
            basis_fit: BasisFit::Samples,
            keys: &[(1, 1e-6), (4, 1e-6)],
            seed: 1,
        };
        let scores = score_rungs(&input).expect("seven lights span theta_d");
        assert_eq!(scores.errors.len(), 2);
        assert!(scores.held_pixels > 0, "{scores:?}");
        assert!(
            scores.errors.iter().all(|e| e.is_some_and(f64::is_finite)),
            "{scores:?}"
        );
        assert!(scores.held_median_deg - scores.train_median_deg >= RUNG_MIN_GAP_DEG);
        assert!(
            scores.describe().contains("extrapolation scored"),
            "{}",
            scores.describe()
        );
        // one light: nothing to extrapolate to
        let one = pixels(1);
        let reliable = select_reliable(&one, &rs);
        assert!(
            score_rungs(&RungInput {
                reliable: &reliable,
                ..input
            })
            .is_none()
        );
    }
}
