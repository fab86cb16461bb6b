//! The pure heart of reconstruction: from observations to the chosen BRDF, with everything the
//! report needs (counts, choices, per-trial similarity, timings).
//!
//! Pure: no I/O; the caller supplies the observations and the prior.

use super::components::{ComponentChoice, ComponentSettings, choose_components};
use super::confidence::{Confidence, ConfidenceSettings, assess};
use super::observe::Observation;
use super::prior::{Candidate, Prior};
use super::reliable::{ReliableSettings, select_reliable};
use super::trials::{Trial, TrialSettings, best_trial, run_trials};
use serde::Serialize;
use std::time::Instant;

/// How the reported trial is chosen among the fitted ones.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum TrialChoice {
    /// The paper's eq. 3: highest cosine similarity between captured and rendered pixels
    /// (blind to the candidate's overall scale).
    Similarity,
    /// Lowest relative error of `f cos theta_i` against the observed reflectance over every
    /// observed pixel (`components::held_out_error`; scale-sensitive). Measured against eq. 3 in
    /// docs/evaluation.md section 1.
    PixelError,
}

/// Settings of the steps after observation.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CoreSettings {
    pub reliable: ReliableSettings,
    pub trials: TrialSettings,
    pub components: ComponentSettings,
    /// Use this k instead of choosing one by validation.
    pub fixed_components: Option<usize>,
    /// Ridge weight used with `fixed_components` (validation chooses its own otherwise).
    pub fixed_eta: f64,
    /// Where the result is called medium or low confidence.
    pub confidence: ConfidenceSettings,
    /// How the reported trial is chosen.
    pub choose: TrialChoice,
}

impl Default for CoreSettings {
    fn default() -> Self {
        Self {
            reliable: ReliableSettings::default(),
            trials: TrialSettings::default(),
            components: ComponentSettings::default(),
            fixed_components: None,
            fixed_eta: crate::brdf::ridge::DEFAULT_ETA,
            confidence: ConfidenceSettings::default(),
            choose: TrialChoice::Similarity,
        }
    }
}

/// Reasons the core cannot produce a BRDF.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CoreError {
    #[error("no usable pixels: every pixel was shadowed, masked out, grazing, saturated or black")]
    NoObservations,
    #[error("no reliable pixels left after the curvature filter (threshold {threshold:.4e})")]
    NoReliablePixels { threshold: f64 },
    #[error("every trial failed to fit a BRDF")]
    AllTrialsFailed,
}

/// What the core produces.
pub struct CoreOutput {
    pub brdf: Box<dyn Candidate>,
    pub trials: Vec<Trial>,
    pub chosen_trial: usize,
    pub components: ComponentChoice,
    pub reliable_pixels: usize,
    pub dropped_by_curvature: usize,
    pub curvature_threshold: Option<f64>,
    /// How far the result can be trusted (never from a ground truth).
    pub confidence: Confidence,
    /// (stage, seconds)
    pub timings: Vec<(String, f64)>,
}

/// Reliable pixels, number of components, trials, choice.
pub fn reconstruct_observations(
    observations: &[Observation],
    prior: &dyn Prior,
    settings: &CoreSettings,
    progress: &mut dyn FnMut(&str),
) -> Result<CoreOutput, CoreError> {
    if observations.is_empty() {
        return Err(CoreError::NoObservations);
    }
    let mut timings = Vec::new();
    let t = Instant::now();
    progress("reliable pixels (curvature, brightest pixel)");
    let reliable = select_reliable(observations, &settings.reliable);
    if reliable.pixels.is_empty() && reliable.brightest.is_none() {
        return Err(CoreError::NoReliablePixels {
            threshold: reliable.curvature_threshold.unwrap_or(f64::NAN),
        });
    }
    timings.push(("reliable".to_string(), t.elapsed().as_secs_f64()));

    let t = Instant::now();
    let components = match settings.fixed_components {
        Some(k) => ComponentChoice {
            k: k.min(prior.max_components()).max(1),
            eta: settings.fixed_eta,
            curve: Vec::new(),
            held_out_pixels: 0,
            samples: 0,
            note: Some("fixed by the settings".to_string()),
        },
        None => {
            progress("number of components (validation on held-back pixels)");
            choose_components(
                prior,
                &reliable,
                &settings.reliable,
                settings.trials.samples,
                &settings.components,
                settings.trials.seed,
            )
        }
    };
    timings.push(("components".to_string(), t.elapsed().as_secs_f64()));

    let t = Instant::now();
    progress(&format!(
        "{} trials ({} samples, k = {}, eta = {})",
        settings.trials.trials, settings.trials.samples, components.k, components.eta
    ));
    let mut trials = run_trials(
        prior,
        &reliable,
        observations,
        &settings.reliable,
        &settings.trials,
        components.k,
        components.eta,
    );
    let chosen = match settings.choose {
        TrialChoice::Similarity => best_trial(&trials),
        TrialChoice::PixelError => trials
            .iter()
            .enumerate()
            .filter_map(|(i, t)| {
                let c = t.candidate.as_deref()?;
                let e = super::components::held_out_error(c, observations);
                e.is_finite().then_some((i, e))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
            .map(|(i, _)| i),
    }
    .ok_or(CoreError::AllTrialsFailed)?;
    let brdf = trials[chosen]
        .candidate
        .take()
        .ok_or(CoreError::AllTrialsFailed)?;
    timings.push(("trials".to_string(), t.elapsed().as_secs_f64()));

    let t = Instant::now();
    progress("confidence (trial agreement, coverage)");
    let others: Vec<&dyn Candidate> = trials
        .iter()
        .filter_map(|tr| tr.candidate.as_deref())
        .collect();
    let used: Vec<&Observation> = reliable
        .pixels
        .iter()
        .chain(reliable.brightest.as_ref())
        .collect();
    let held_out = components
        .curve
        .iter()
        .find(|p| p.k == components.k && p.eta == components.eta)
        .and_then(|p| p.error);
    let confidence = assess(
        brdf.as_ref(),
        &others,
        &used,
        held_out,
        &settings.confidence,
    );
    timings.push(("confidence".to_string(), t.elapsed().as_secs_f64()));
    Ok(CoreOutput {
        brdf,
        trials,
        chosen_trial: chosen,
        components,
        reliable_pixels: reliable.pixels.len() + usize::from(reliable.brightest.is_some()),
        dropped_by_curvature: reliable.dropped_by_curvature,
        curvature_threshold: reliable.curvature_threshold,
        confidence,
        timings,
    })
}

#[cfg(test)]
mod tests {
    use super::super::components::held_out_error;
    use super::super::prior::synthetic::{CosinePrior, cap_pixels};
    use super::*;

    /// Noisy pixels, so the trials (different pixel subsets) differ.
    fn scene() -> Vec<Observation> {
        let mut obs = cap_pixels(|b| 0.2 + 0.05 * ((b % 7) as f64), 400, [1.0, 0.8, 0.6]);
        for (i, o) in obs.iter_mut().enumerate() {
            let wobble = 1.0 + 0.3 * ((i * 37 % 11) as f64 / 10.0 - 0.5);
            o.reflectance = o.reflectance.map(|r| r * wobble);
            o.radiance = o.reflectance.map(|r| r * o.cos_theta_i);
        }
        obs
    }

    fn run(choose: TrialChoice) -> (CoreOutput, Vec<Observation>) {
        let obs = scene();
        let mut settings = CoreSettings {
            choose,
            fixed_components: Some(3),
            ..CoreSettings::default()
        };
        settings.trials.trials = 6;
        settings.trials.samples = 6;
        let out = reconstruct_observations(&obs, &CosinePrior { k: 3 }, &settings, &mut |_| {})
            .expect("reconstructs");
        (out, obs)
    }

    #[test]
    fn pixel_error_choice_reports_the_trial_that_explains_the_pixels_best() {
        let (out, obs) = run(TrialChoice::PixelError);
        let chosen = held_out_error(out.brdf.as_ref(), &obs);
        let others: Vec<f64> = out
            .trials
            .iter()
            .filter_map(|t| t.candidate.as_deref())
            .map(|c| held_out_error(c, &obs))
            .collect();
        assert_eq!(others.len(), 5, "every other trial fitted");
        assert!(
            others.iter().all(|&e| chosen <= e),
            "{chosen} vs {others:?}"
        );
        assert!(others.iter().any(|&e| e > chosen), "the trials differ");
    }

    #[test]
    fn similarity_choice_reports_the_most_similar_trial() {
        let (out, _) = run(TrialChoice::Similarity);
        let best = out
            .trials
            .iter()
            .map(|t| t.similarity)
            .fold(f64::MIN, f64::max);
        assert_eq!(out.trials[out.chosen_trial].similarity, best);
    }
}
