//! Several random trials and the choice among them by cosine similarity (METHOD.md sections 5-6,
//! the paper's 3.2-3.3).
//!
//! Each trial draws a random subset of the reliable pixels, selects sample pixels among them
//! (bins chosen by the prior for the conditioning of the basis, each pixel checked against the
//! monotonicity assumption as it is added, the brightest pixel always first), fits a BRDF, and
//! "renders" it: every observed pixel of every light image is shaded with the candidate,
//! `I_rend = f(bin) E cos(theta_i)`, using the same rasterised geometry (the one the captured
//! image was observed through; shadowed, masked, grazing, saturated and black pixels are left
//! out of both). Eq. 3 is then the cosine similarity of two vectors: the captured RGB values
//! and the rendered RGB values of all those pixels, concatenated over all images and channels.
//! The trial with the highest similarity wins.
//!
//! Pure: no I/O. Deterministic for a given seed (each trial derives its own).

use super::observe::Observation;
use super::prior::{Candidate, Prior, Sample};
use super::reliable::{MonotonicSet, Reliable, ReliableSettings};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;

/// Settings of the trials.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrialSettings {
    pub trials: usize,
    /// Fraction of the reliable pixels each trial draws.
    pub subset_fraction: f64,
    /// Sample pixels per trial (the brightest pixel included).
    pub samples: usize,
    pub seed: u64,
    /// What each basis fit is given (files written before it existed used the paper's).
    #[serde(default = "BasisFit::paper")]
    pub basis_fit: BasisFit,
}

/// What a basis fit is given.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BasisFit {
    /// The paper's: `samples` pixels, their basis rows chosen for the conditioning of the
    /// basis sub-matrix, each checked against eq. 1 as it is added (`select_pixels`).
    Samples,
    /// Every pixel the fit may use, one sample per basis row: the median of the row's pixels
    /// (`dense_samples`); the ridge weight is scaled by rows / `samples`, so that the prior
    /// weighs as it does against `samples` pixels. No draw of 80 pixels decides the
    /// extrapolation (docs/evaluation.md 1k).
    Rows,
}

impl BasisFit {
    pub fn paper() -> Self {
        Self::Samples
    }

    /// The name the command line takes (`--basis-fit`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Rows => "rows",
            Self::Samples => "samples",
        }
    }
}

impl Default for TrialSettings {
    fn default() -> Self {
        Self {
            trials: 10,
            subset_fraction: 0.5,
            samples: 80,
            seed: 1,
            basis_fit: BasisFit::Rows,
        }
    }
}

/// One sample per basis row from every pixel of `pool`: the per-channel median of the values
/// the row's pixels lend it (`Prior::row_value`: their reflectance, unless the prior carries
/// them to the row's centre; the median is robust to the few whose normal is far off;
/// `stats::median`), `first` (the brightest pixel, eq. 2) as its own sample, its row's other
/// pixels left out as `select_pixels` does. A row whose values are not all numbers gives no sample.
pub fn dense_samples(
    prior: &dyn Prior,
    pool: &[Observation],
    first: Option<&Observation>,
) -> Vec<Sample> {
    let mut by_row: HashMap<usize, Vec<&Observation>> = HashMap::new();
    for o in pool {
        if let Some(row) = prior.row_of(o.bin) {
            by_row.entry(row).or_default().push(o);
        }
    }
    let mut out = Vec::with_capacity(by_row.len() + 1);
    if let Some(b) = first {
        if let Some(row) = prior.row_of(b.bin) {
            by_row.remove(&row);
        }
        out.push(Sample {
            bin: b.bin,
            reflectance: b.reflectance,
        });
    }
    let mut rows: Vec<(usize, Vec<&Observation>)> = by_row.into_iter().collect();
    rows.sort_unstable_by_key(|(r, _)| *r);
    for (_, px) in rows {
        let values: Vec<[f64; 3]> = px.iter().map(|o| prior.row_value(o)).collect();
        let medians: [Option<f64>; 3] = std::array::from_fn(|c| {
            let mut v: Vec<f64> = values.iter().map(|r| r[c]).collect();
            crate::stats::median(&mut v)
        });
        if let [Some(r), Some(g), Some(b)] = medians {
            out.push(Sample {
                bin: px[0].bin,
                reflectance: [r, g, b],
            });
        }
    }
    out
}

/// What a basis fit is given.
pub struct BasisSamples {
    pub samples: Vec<Sample>,
    /// The pixels to report: the chosen ones, or with `BasisFit::Rows` the brightest alone.
    pub pixels: Vec<SamplePixel>,
    /// Factor of the ridge weight.
    pub eta_scale: f64,
    pub rejected_by_monotonicity: usize,
}

/// The samples a basis fit uses, and the factor its ridge weight is scaled by (see
/// [`BasisFit`]).
#[allow(clippy::too_many_arguments)]
pub fn basis_samples(
    prior: &dyn Prior,
    pool: &[Observation],
    first: Option<&Observation>,
    reliable: &ReliableSettings,
    samples: usize,
    k: usize,
    seed: u64,
    fit: BasisFit,
) -> BasisSamples {
    match fit {
        BasisFit::Rows => {
            let s = dense_samples(prior, pool, first);
            let scale = (s.len() as f64 / samples.max(1) as f64).max(1.0);
            BasisSamples {
                samples: s,
                pixels: first.map(SamplePixel::from).into_iter().collect(),
                eta_scale: scale,
                rejected_by_monotonicity: 0,
            }
        }
        BasisFit::Samples => {
            let sel = select_pixels(prior, pool, first, reliable, samples, k, seed);
            BasisSamples {
                samples: samples_of(&sel.pixels),
                pixels: sel.pixels.iter().map(SamplePixel::from).collect(),
                eta_scale: 1.0,
                rejected_by_monotonicity: sel.rejected_by_monotonicity,
            }
        }
    }
}

/// A chosen sample pixel, as reported.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SamplePixel {
    pub image: usize,
    pub x: u32,
    pub y: u32,
    pub bin: usize,
    pub reflectance: [f64; 3],
}

impl From<&Observation> for SamplePixel {
    fn from(o: &Observation) -> Self {
        Self {
            image: o.image,
            x: o.x,
            y: o.y,
            bin: o.bin,
            reflectance: o.reflectance,
        }
    }
}

/// One trial's outcome.
#[derive(Serialize, Deserialize)]
pub struct Trial {
    pub index: usize,
    pub similarity: f64,
    /// Pixels rejected by the monotonicity check while selecting.
    pub rejected_by_monotonicity: usize,
    /// Samples the basis fit was given (one per basis row with `BasisFit::Rows`).
    #[serde(default)]
    pub fitted_samples: usize,
    /// The chosen sample pixels (`BasisFit::Samples`), or the brightest pixel alone
    /// (`BasisFit::Rows`: every row is a sample, too many to list).
    pub samples: Vec<SamplePixel>,
    #[serde(skip)]
    pub candidate: Option<Box<dyn Candidate>>,
}

/// Eq. 3: cosine similarity between captured and rendered RGB over the observed pixels.
pub fn cosine_similarity(candidate: &dyn Candidate, observations: &[Observation]) -> f64 {
    similarity_of(observations, |i| candidate.eval_bin(observations[i].bin))
}

/// Eq. 3 with the candidate's value at observation `i` given by `value`.
#[allow(clippy::needless_range_loop)] // three parallel RGB arrays
fn similarity_of(observations: &[Observation], value: impl Fn(usize) -> [f64; 3]) -> f64 {
    let (mut dot, mut nc, mut nr) = (0.0, 0.0, 0.0);
    for (i, o) in observations.iter().enumerate() {
        let f = value(i);
        for c in 0..3 {
            let captured = o.radiance[c];
            let rendered = f[c] * o.irradiance[c] * o.cos_theta_i;
            if rendered.is_finite() {
                dot += captured * rendered;
                nr += rendered * rendered;
            }
            nc += captured * captured;
        }
    }
    if nc <= 0.0 || nr <= 0.0 {
        return 0.0;
    }
    dot / (nc.sqrt() * nr.sqrt())
}

/// Selected sample pixels and how many were rejected by eq. 1.
pub struct Selection {
    pub pixels: Vec<Observation>,
    pub rejected_by_monotonicity: usize,
}

/// Rounds of the prior's selection: after a round whose rows partly failed eq. 1, the prior
/// re-selects the missing samples around the pixels accepted so far.
const MAX_ROUNDS: usize = 3;

/// Chooses up to `n` pixels among `pool`: basis rows by the prior (conditioning on the first
/// `min(|S|, k)` components), for each row the first pixel (pool order) that satisfies eq. 1
/// against every pixel already chosen; `first` always first (the brightest pixel when
/// assumption 3 is on). A row none of whose pixels passes is dropped from the candidates.
pub fn select_pixels(
    prior: &dyn Prior,
    pool: &[Observation],
    first: Option<&Observation>,
    reliable: &ReliableSettings,
    n: usize,
    k: usize,
    seed: u64,
) -> Selection {
    // Pixels grouped by the basis row of their bin: the prior chooses rows.
    let mut by_row: HashMap<usize, Vec<&Observation>> = HashMap::new();
    for o in pool {
        if let Some(row) = prior.row_of(o.bin) {
            by_row.entry(row).or_default().push(o);
        }
    }
    let mut mono = MonotonicSet::new(reliable);
    let mut pixels: Vec<Observation> = Vec::with_capacity(n);
    if let Some(b) = first {
        mono.push(b);
        pixels.push(*b);
        if let Some(row) = prior.row_of(b.bin) {
            by_row.remove(&row);
        }
    }
    let mut candidates: Vec<usize> = by_row.keys().copied().collect();
    candidates.sort_unstable();
    let mut rejected = 0;
    for round in 0..MAX_ROUNDS {
        if pixels.len() >= n || candidates.is_empty() {
            break;
        }
        let chosen: Vec<usize> = pixels.iter().filter_map(|p| prior.row_of(p.bin)).collect();
        let order = prior.select(&chosen, &candidates, n, k, seed.wrapping_add(round as u64));
        let new: Vec<usize> = order
            .into_iter()
            .skip(chosen.len())
            .filter(|r| by_row.contains_key(r))
            .collect();
        if new.is_empty() {
            break;
        }
        for row in new {
            if pixels.len() >= n {
                break;
            }
            candidates.retain(|&c| c != row);
            for o in by_row.get(&row).map(Vec::as_slice).unwrap_or(&[]) {
                if mono.accepts(o) {
                    mono.push(o);
                    pixels.push(**o);
                    break;
                }
                rejected += 1;
            }
        }
    }
    Selection {
        pixels,
        rejected_by_monotonicity: rejected,
    }
}

/// Samples for a fit.
pub fn samples_of(pixels: &[Observation]) -> Vec<Sample> {
    pixels
        .iter()
        .map(|o| Sample {
            bin: o.bin,
            reflectance: o.reflectance,
        })
        .collect()
}

/// A trial's fit as the trials use it: evaluated on demand (the prior need not tabulate it; a
/// Nielsen fit holds its coefficients, not 364 000 synthesised rows), with what it was fitted
/// to, so that the chosen trial, and others when asked, can be fitted again as a table
/// ([`TrialFit::tabulate`], the same values bit for bit: the same samples, k and eta).
pub struct TrialFit<'a> {
    pub candidate: Box<dyn Candidate + 'a>,
    samples: Vec<Sample>,
    k: usize,
    eta: f64,
}

impl TrialFit<'_> {
    /// The fit again, tabulated by the prior (what `Prior::fit` gives; owned).
    pub fn tabulate(&self, prior: &dyn Prior) -> Option<Box<dyn Candidate>> {
        prior.fit(&self.samples, self.k, self.eta).ok()
    }

    /// The same samples fitted at `k` components and the ridge weight times `eta_factor`,
    /// tabulated by the prior.
    pub fn tabulate_at(
        &self,
        prior: &dyn Prior,
        k: usize,
        eta_factor: f64,
    ) -> Option<Box<dyn Candidate>> {
        prior.fit(&self.samples, k, self.eta * eta_factor).ok()
    }
}

/// The observations' bins, each basis row once: a fit of the prior has one value per row
/// (`Prior::row_of`), so a trial's fit is evaluated once per distinct row instead of once per
/// pixel (at the paper's scale there are more pixels than rows). A bin without a row is its
/// own entry.
struct DistinctRows {
    /// A bin of each distinct row (or row-less bin), in first-seen order.
    bins: Vec<usize>,
    /// Per observation, its entry in `bins`.
    of: Vec<usize>,
}

impl DistinctRows {
    fn new(prior: &dyn Prior, observations: &[Observation]) -> Self {
        let mut index: HashMap<(bool, usize), usize> = HashMap::new();
        let mut bins = Vec::new();
        let of = observations
            .iter()
            .map(|o| {
                let key = prior.row_of(o.bin).map_or((false, o.bin), |r| (true, r));
                *index.entry(key).or_insert_with(|| {
                    bins.push(o.bin);
                    bins.len() - 1
                })
            })
            .collect();
        Self { bins, of }
    }
}

/// [`cosine_similarity`] of a fit of the prior, evaluated once per distinct row; the same sums
/// in the same order, so the same value.
fn similarity_by_rows(
    candidate: &dyn Candidate,
    observations: &[Observation],
    rows: &DistinctRows,
) -> f64 {
    let values: Vec<[f64; 3]> = rows.bins.iter().map(|&b| candidate.eval_bin(b)).collect();
    similarity_of(observations, |i| values[rows.of[i]])
}

/// Runs the trials; `observations` are every observed pixel (for eq. 3). Returns the trials in
/// index order (their `candidate` empty) and, beside each, its fit (`None` where the fit
/// failed); the best is the one with the highest similarity.
pub fn run_trials<'a>(
    prior: &'a dyn Prior,
    reliable: &Reliable,
    observations: &[Observation],
    reliable_settings: &ReliableSettings,
    settings: &TrialSettings,
    k: usize,
    eta: f64,
) -> (Vec<Trial>, Vec<Option<TrialFit<'a>>>) {
    let rows = DistinctRows::new(prior, observations);
    (0..settings.trials.max(1))
        .into_par_iter()
        .map(|index| {
            let seed = settings
                .seed
                .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                .wrapping_add(index as u64);
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut pool = reliable.pixels.clone();
            pool.shuffle(&mut rng);
            let keep = ((pool.len() as f64 * settings.subset_fraction).ceil() as usize)
                .clamp(1.min(pool.len()), pool.len());
            pool.truncate(keep);
            let fit = basis_samples(
                prior,
                &pool,
                reliable.brightest.as_ref(),
                reliable_settings,
                settings.samples,
                k,
                seed,
                settings.basis_fit,
            );
            let eta = eta * fit.eta_scale;
            let candidate = prior.fit_lazy(&fit.samples, k, eta).ok();
            let similarity = candidate
                .as_deref()
                .map(|c| similarity_by_rows(c, observations, &rows))
                .unwrap_or(f64::NEG_INFINITY);
            let trial = Trial {
                index,
                similarity,
                rejected_by_monotonicity: fit.rejected_by_monotonicity,
                fitted_samples: fit.samples.len(),
                samples: fit.pixels,
                candidate: None,
            };
            let fit = candidate.map(|candidate| TrialFit {
                candidate,
                samples: fit.samples,
                k,
                eta,
            });
            (trial, fit)
        })
        .unzip()
}

/// Index of the trial with the highest similarity (ties: the first; a trial whose fit failed
/// has similarity minus infinity and is never chosen).
pub fn best_trial(trials: &[Trial]) -> Option<usize> {
    trials
        .iter()
        .enumerate()
        .filter(|(_, t)| t.similarity.is_finite())
        .max_by(|a, b| {
            a.1.similarity
                .total_cmp(&b.1.similarity)
                .then(b.0.cmp(&a.0))
        })
        .map(|(i, _)| i)
}

#[cfg(test)]
mod tests {
    use super::super::prior::synthetic::{CosinePrior, Linear, phi};
    use super::*;
    use crate::brdf::ridge::RidgeError;
    use crate::reconstruct::reliable::select_reliable;

    fn pixels(truth: impl Fn(usize) -> f64, count: usize) -> Vec<Observation> {
        super::super::prior::synthetic::cap_pixels(truth, count, [1.0; 3])
    }

    #[test]
    fn similarity_is_one_for_the_truth_at_any_scale_and_lower_otherwise() {
        let truth = |bin: usize| 1.0 + 0.8 * phi(1, bin);
        let obs = pixels(truth, 300);
        let exact = Linear {
            coeffs: vec![[2.0; 3], [1.6; 3]],
        };
        assert!((cosine_similarity(&exact, &obs) - 1.0).abs() < 1e-12);
        let flat = Linear {
            coeffs: vec![[1.0; 3]],
        };
        let s = cosine_similarity(&flat, &obs);
        assert!(s < 0.999 && s > 0.5, "{s}");
    }

    #[test]
    fn selection_honours_monotonicity_and_puts_the_brightest_first() {
        // A decreasing function of theta_h: eq. 1 holds for clean pixels.
        let truth = |bin: usize| 2.0 - phi(0, bin) * 0.0 - (bin / (90 * 180)) as f64 / 90.0;
        let mut obs = pixels(truth, 300);
        // Corrupt every 10th pixel: far too bright for its n.h.
        for o in obs.iter_mut().step_by(10) {
            o.reflectance = [10.0; 3];
        }
        let settings = ReliableSettings {
            use_curvature: false,
            ..Default::default()
        };
        let reliable = select_reliable(&obs, &settings);
        let first = reliable.brightest.unwrap();
        let sel = select_pixels(
            &CosinePrior { k: 4 },
            &reliable.pixels,
            Some(&first),
            &settings,
            40,
            4,
            3,
        );
        assert_eq!(sel.pixels[0].bin, first.bin);
        assert!(sel.pixels.len() >= 30, "{}", sel.pixels.len());
        // Every pair of selected pixels respects eq. 1.
        for a in &sel.pixels {
            for b in &sel.pixels {
                if a.n_dot_h > b.n_dot_h + 1e-9 {
                    assert!(a.luminance() >= b.luminance(), "{a:?} {b:?}");
                }
            }
        }
        assert!(sel.rejected_by_monotonicity > 0);
        // Without the assumption, corrupted pixels get in.
        let none = ReliableSettings::none();
        let sel = select_pixels(
            &CosinePrior { k: 4 },
            &reliable.pixels,
            None,
            &none,
            100,
            4,
            3,
        );
        assert!(sel.pixels.iter().any(|p| p.reflectance[0] == 10.0));
    }

    #[test]
    fn dense_samples_give_each_row_the_median_of_its_pixels_and_the_anchor_its_own() {
        let truth = |bin: usize| 1.0 + 0.8 * phi(1, bin);
        let clean = pixels(truth, 300);
        // Every pixel seen three times: twice as it is, once ten times too bright (a normal far
        // off); the median keeps the truth where a mean would not.
        let mut pool = Vec::new();
        for o in &clean {
            let mut bright = *o;
            bright.reflectance = o.reflectance.map(|r| 10.0 * r);
            pool.extend([*o, bright, *o]);
        }
        let prior = CosinePrior { k: 3 };
        let rows: std::collections::HashSet<usize> = clean.iter().map(|o| o.bin).collect();
        let dense = dense_samples(&prior, &pool, None);
        assert_eq!(dense.len(), rows.len());
        for s in &dense {
            assert!((s.reflectance[0] - truth(s.bin)).abs() < 1e-12, "{s:?}");
            assert!(rows.contains(&s.bin), "{s:?}");
        }
        // The anchor comes first, and its row's pixels give no second sample.
        let mut anchor = clean[0];
        anchor.reflectance = [7.0; 3];
        let with = dense_samples(&prior, &pool, Some(&anchor));
        assert_eq!(with.len(), rows.len());
        assert_eq!(with[0].reflectance, [7.0; 3]);
        assert_eq!(with.iter().filter(|s| s.bin == anchor.bin).count(), 1);
        // A fit to them recovers the truth.
        let fit = prior.fit(&dense, 3, 1.0).unwrap();
        let probe = clean[17].bin;
        assert!((fit.eval_bin(probe)[0] - truth(probe)).abs() < 1e-6);
    }

    #[test]
    fn the_similarity_over_distinct_rows_is_the_similarity_over_pixels() {
        // A prior whose rows hold five bins each, and a fit with one value per row.
        struct Coarse;
        impl Prior for Coarse {
            fn max_components(&self) -> usize {
                1
            }
            fn row_of(&self, bin: usize) -> Option<usize> {
                (!bin.is_multiple_of(3)).then_some(bin / 5)
            }
            fn select(&self, _: &[usize], c: &[usize], _: usize, _: usize, _: u64) -> Vec<usize> {
                c.to_vec()
            }
            fn fit(
                &self,
                _: &[Sample],
                _: usize,
                _: f64,
            ) -> Result<Box<dyn Candidate>, RidgeError> {
                Err(RidgeError::Empty)
            }
        }
        struct PerRow;
        impl Candidate for PerRow {
            fn eval_bin(&self, bin: usize) -> [f64; 3] {
                let r = if bin.is_multiple_of(3) { bin } else { bin / 5 };
                [
                    0.1 + (r % 17) as f64 * 0.03,
                    0.2,
                    0.05 + (r % 5) as f64 * 0.1,
                ]
            }
        }
        let obs = pixels(|bin| 0.5 + (bin % 11) as f64 * 0.1, 500);
        let rows = DistinctRows::new(&Coarse, &obs);
        assert!(
            rows.bins.len() < obs.len(),
            "rows are shared: {}",
            rows.bins.len()
        );
        let by_rows = similarity_by_rows(&PerRow, &obs, &rows);
        assert_eq!(by_rows, cosine_similarity(&PerRow, &obs));
        assert!(by_rows > 0.5 && by_rows < 1.0, "{by_rows}");
    }

    #[test]
    fn trials_keep_the_most_similar_candidate() {
        let truth = |bin: usize| 1.0 + 0.8 * phi(1, bin) + 0.2 * phi(2, bin);
        let mut obs = pixels(truth, 400);
        // Half the pixels noisy: trials that draw fewer of them fit better.
        for (i, o) in obs.iter_mut().enumerate() {
            if i % 2 == 0 {
                let f = 1.0 + 0.3 * ((i * 7919) % 13) as f64 / 13.0;
                o.reflectance = o.reflectance.map(|r| r * f);
            }
        }
        let settings = ReliableSettings::none();
        let reliable = select_reliable(&obs, &settings);
        let ts = TrialSettings {
            trials: 6,
            subset_fraction: 0.3,
            samples: 12,
            seed: 5,
            basis_fit: BasisFit::Samples,
        };
        let (trials, fits) = run_trials(
            &CosinePrior { k: 3 },
            &reliable,
            &obs,
            &settings,
            &ts,
            3,
            1.0,
        );
        assert_eq!(trials.len(), 6);
        assert!(fits.iter().all(Option::is_some), "every trial fitted");
        let best = best_trial(&trials).unwrap();
        // the chosen fit, tabulated, is the fit the trial scored
        let table = fits[best]
            .as_ref()
            .unwrap()
            .tabulate(&CosinePrior { k: 3 })
            .unwrap();
        assert_eq!(
            cosine_similarity(table.as_ref(), &obs),
            trials[best].similarity
        );
        for t in &trials {
            assert!(t.similarity <= trials[best].similarity);
            assert_eq!(t.samples.len(), 12);
        }
        // Deterministic for a seed.
        let (again, _) = run_trials(
            &CosinePrior { k: 3 },
            &reliable,
            &obs,
            &settings,
            &ts,
            3,
            1.0,
        );
        for (a, b) in trials.iter().zip(&again) {
            assert_eq!(a.similarity, b.similarity);
        }
    }
}
