//! Choosing the number of basis components k (and the ridge weight eta) per scene: the best k
//! ranges from 5 to 80 depending on the material, so a fixed k costs accuracy somewhere; eta
//! scales with the basis (its entries grow with the square root of the number of materials), so
//! Nielsen's 40 for 100 materials is not right for every basis.
//!
//! Validation on held-back pixels: a seeded random fraction of the reliable pixels is held back;
//! samples are selected from the rest exactly as a trial does (brightest first, eq. 1, prior's
//! conditioning); for every k of the grid not above the number of samples, a BRDF is fitted and
//! its prediction compared with the held-back pixels. The error is the relative error of the
//! predicted against the observed `f cos(theta_i)` (the image-space quantity, so grazing pixels
//! weigh less), summed over channels:
//! `sqrt(sum (cos_i (f_pred - r))^2) / sqrt(sum (cos_i r)^2)`.
//! The chosen pair is the simplest whose error is within `tolerance` (relative) of the minimum:
//! smallest k first, then largest eta (the most regularised).
//!
//! Pure: no I/O.

use super::observe::Observation;
use super::prior::{Candidate, Prior};
use super::reliable::{Reliable, ReliableSettings};
use super::trials::{samples_of, select_pixels};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ComponentSettings {
    /// Candidate k; capped by the number of samples and by the basis.
    pub grid: Vec<usize>,
    /// Candidate ridge weights.
    pub etas: Vec<f64>,
    /// Fraction of reliable pixels held back.
    pub held_out_fraction: f64,
    /// Choose the smallest k whose error is at most (1 + tolerance) times the minimum.
    pub tolerance: f64,
    /// Used when validation is impossible (too few pixels) or switched off (`grid` of one).
    pub fallback: usize,
    pub fallback_eta: f64,
}

impl Default for ComponentSettings {
    fn default() -> Self {
        Self {
            grid: vec![5, 10, 20, 40, 80],
            etas: vec![1.0, 10.0, 40.0],
            held_out_fraction: 0.25,
            tolerance: 0.02,
            fallback: 20,
            fallback_eta: 40.0,
        }
    }
}

/// One point of the validation curve.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ValidationPoint {
    pub k: usize,
    pub eta: f64,
    /// Relative error on the held-back pixels; `None` when the fit failed.
    pub error: Option<f64>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ComponentChoice {
    pub k: usize,
    pub eta: f64,
    pub curve: Vec<ValidationPoint>,
    pub held_out_pixels: usize,
    pub samples: usize,
    /// Why the fallback was used, if it was.
    pub note: Option<String>,
}

/// Relative error of a candidate's `f cos_i` against the observed reflectance.
#[allow(clippy::needless_range_loop)] // three parallel RGB arrays
pub fn held_out_error(candidate: &dyn Candidate, held: &[Observation]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for o in held {
        let f = candidate.eval_bin(o.bin);
        for c in 0..3 {
            let d = o.cos_theta_i * (f[c] - o.reflectance[c]);
            num += d * d;
            den += (o.cos_theta_i * o.reflectance[c]).powi(2);
        }
    }
    if den <= 0.0 {
        return f64::INFINITY;
    }
    (num / den).sqrt()
}

/// Picks k by validation on held-back pixels (see the module header).
pub fn choose_components(
    prior: &dyn Prior,
    reliable: &Reliable,
    reliable_settings: &ReliableSettings,
    samples: usize,
    settings: &ComponentSettings,
    seed: u64,
) -> ComponentChoice {
    let max_k = prior.max_components();
    let fallback = settings.fallback.min(max_k).max(1);
    let mut pool = reliable.pixels.clone();
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xC0FF_EE00);
    pool.shuffle(&mut rng);
    let held_n = (pool.len() as f64 * settings.held_out_fraction).round() as usize;
    if held_n < 10 || pool.len() - held_n < 10 || settings.grid.len() * settings.etas.len() < 2 {
        return ComponentChoice {
            k: fallback,
            eta: settings.fallback_eta,
            curve: Vec::new(),
            held_out_pixels: 0,
            samples: 0,
            note: Some(format!(
                "validation skipped ({} reliable pixels, grid of {}): k = {fallback}",
                pool.len(),
                settings.grid.len()
            )),
        };
    }
    let held = pool.split_off(pool.len() - held_n);
    let sel = select_pixels(
        prior,
        &pool,
        reliable.brightest.as_ref(),
        reliable_settings,
        samples,
        // Selection conditions on the fallback's columns: as cheap as a trial's, where the
        // largest k of the grid would make every condition number an 80-column SVD.
        fallback,
        seed,
    );
    let fit_samples = samples_of(&sel.pixels);
    let mut grid: Vec<usize> = settings
        .grid
        .iter()
        .map(|&k| k.min(fit_samples.len()).min(max_k))
        .filter(|&k| k > 0)
        .collect();
    grid.sort_unstable();
    grid.dedup();
    let mut etas = settings.etas.clone();
    if etas.is_empty() {
        etas.push(settings.fallback_eta);
    }
    // Most regularised first, so among equals the first found is the simplest.
    etas.sort_by(|a, b| b.total_cmp(a));
    let curve: Vec<ValidationPoint> = grid
        .iter()
        .flat_map(|&k| etas.iter().map(move |&eta| (k, eta)))
        .map(|(k, eta)| ValidationPoint {
            k,
            eta,
            error: prior
                .fit(&fit_samples, k, eta)
                .ok()
                .map(|c| held_out_error(c.as_ref(), &held))
                .filter(|e| e.is_finite()),
        })
        .collect();
    let best = curve
        .iter()
        .filter_map(|p| p.error)
        .fold(f64::INFINITY, f64::min);
    let chosen = curve
        .iter()
        .find(|p| {
            p.error
                .is_some_and(|e| e <= best * (1.0 + settings.tolerance))
        })
        .map(|p| (p.k, p.eta));
    ComponentChoice {
        k: chosen.map_or(fallback, |c| c.0),
        eta: chosen.map_or(settings.fallback_eta, |c| c.1),
        note: chosen
            .is_none()
            .then(|| format!("every validation fit failed: k = {fallback}")),
        curve,
        held_out_pixels: held.len(),
        samples: fit_samples.len(),
    }
}

#[cfg(test)]
mod tests {
    use super::super::prior::synthetic::{CosinePrior, phi};
    use super::*;
    use crate::reconstruct::reliable::select_reliable;

    fn pixels(truth: impl Fn(usize) -> f64, count: usize) -> Vec<Observation> {
        super::super::prior::synthetic::cap_pixels(truth, count, [1.0, 0.5, 2.0])
    }

    #[test]
    fn validation_picks_the_smallest_k_that_explains_held_back_pixels() {
        let truth = |bin: usize| 1.0 + 0.5 * phi(1, bin) - 0.3 * phi(2, bin);
        let obs = pixels(truth, 400);
        let prior = CosinePrior { k: 8 };
        let settings = ReliableSettings::none();
        let reliable = select_reliable(&obs, &settings);
        let choice = choose_components(
            &prior,
            &reliable,
            &settings,
            30,
            &ComponentSettings {
                grid: vec![1, 2, 3, 5, 8],
                etas: vec![1.0],
                ..Default::default()
            },
            7,
        );
        assert_eq!(choice.k, 3, "{choice:?}");
        assert_eq!(choice.curve.len(), 5);
        let err = |k| {
            choice
                .curve
                .iter()
                .find(|p| p.k == k)
                .unwrap()
                .error
                .unwrap()
        };
        assert!(err(2) > 0.01 && err(3) < 1e-6, "{choice:?}");
        assert_eq!(choice.held_out_pixels, 100);
    }

    #[test]
    fn too_few_pixels_fall_back() {
        let obs = pixels(|_| 1.0, 12);
        let settings = ReliableSettings::none();
        let reliable = select_reliable(&obs, &settings);
        let choice = choose_components(
            &CosinePrior { k: 8 },
            &reliable,
            &settings,
            30,
            &ComponentSettings::default(),
            1,
        );
        assert_eq!(choice.k, 8);
        assert!(choice.note.is_some());
    }
}
