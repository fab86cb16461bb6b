//! The pure heart of reconstruction: from observations to the chosen BRDF, with everything the
//! report needs (counts, choices, per-trial similarity, timings).
//!
//! Pure: no I/O; the caller supplies the observations and the prior.

use super::carry::{CarriedPrior, Carry};
use super::components::{ComponentChoice, ComponentSettings, ValidationPoint, choose_components};
use super::confidence::{
    AtProbe, Confidence, ConfidenceSettings, HeldOut, assess, render_disagreement,
    unseen_render_share,
};
use super::deblur::DeblurredPrior;
use super::extrapolation::{
    ExtrapolationInput, ExtrapolationSettings, check as check_extrapolation,
};
use super::fresnel::{F0Rule, fit_lambert_ggx_held};
use super::grazing::GrazingTransfer;
use super::hedge::{Hedge, HedgeSettings, blend_into};
use super::ladder::{
    AnalyticCandidate, Family, Ladder, LadderInput, LadderSettings, NO_PEAK, WithPeak, climb,
    fit_peak, subset,
};
use super::lambert_rung::fit_lambert_rung;
use super::observe::Observation;
use super::plausible::{
    Plausibility, PlausibleSettings, albedo_curve, make_plausible, make_plausible_shaped,
};
use super::prior::{Candidate, CandidateValues, Prior, Tabulated};
use super::reliable::{ReliableSettings, select_reliable};
use super::trials::{Trial, TrialSettings, best_trial, run_trials};
use crate::brdf::analytic::LambertGgx;
use crate::brdf::merl::MerlTable;
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use std::time::Instant;

/// Which models the reconstruction may report.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ModelSelection {
    /// The ladder chooses by held-out error (`reconstruct::ladder`).
    Auto,
    /// This family only (the basis still chooses its k by the ladder's validation).
    Only(Family),
}

/// How the reported trial is chosen among the fitted ones.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TrialChoice {
    /// The paper's eq. 3: highest cosine similarity between captured and rendered pixels
    /// (blind to the candidate's overall scale).
    Similarity,
    /// Lowest relative error of `f cos theta_i` against the observed reflectance over every
    /// observed pixel (`components::held_out_error`; scale-sensitive). Measured against eq. 3 in
    /// docs/evaluation.md section 1.
    PixelError,
    /// The mean of every trial's table (bagging): no single draw of pixels decides the
    /// extrapolation. The trial eq. 3 picks is still reported as the chosen one, and its
    /// disagreement with the others still guards the basis.
    Mean,
    /// The per-bin median of every trial's table: like `Mean`, no single draw decides the
    /// extrapolation, and a trial that extrapolates far off moves it least.
    Median,
}

/// Settings of the steps after observation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CoreSettings {
    pub reliable: ReliableSettings,
    pub trials: TrialSettings,
    pub components: ComponentSettings,
    /// Use this k (the number of basis components a fit uses) instead of choosing one by
    /// validation. Read from files written before it was renamed, too.
    #[serde(alias = "fixed_components")]
    pub fixed_k: Option<usize>,
    /// Ridge weight used with `fixed_k` (validation chooses its own otherwise).
    pub fixed_eta: f64,
    /// Where the result is called medium or low confidence.
    pub confidence: ConfidenceSettings,
    /// How the reported trial is chosen.
    pub choose: TrialChoice,
    /// The model ladder's held-out scheme and rungs.
    pub ladder: LadderSettings,
    /// Which models may be reported.
    pub model: ModelSelection,
    /// Shrinkage, non-negativity and albedo of the written table.
    pub plausible: PlausibleSettings,
    /// Model averaging with Lambert + GGX where the render is mostly unobserved
    /// (`reconstruct::hedge`). Off in reports written before it existed.
    #[serde(default = "HedgeSettings::off")]
    pub hedge: HedgeSettings,
    /// Where the ladder chose the basis and the basis + peak rung scored within noise of it
    /// (`Ladder::peak_within_noise`), the written table is the basis's and the basis + peak's,
    /// averaged geometrically with this weight on the latter (0: never). 0 in reports written
    /// before it existed.
    #[serde(default)]
    pub peak_average: f64,
    /// Where the ladder chose the basis, the basis rungs (k, eta) within noise of the chosen
    /// one both ways (`Ladder::basis_within_noise`), each fitted to the chosen trial's samples
    /// and made plausible, are averaged geometrically with it, in equal weights: the held-out
    /// images cannot rank them, and their extrapolations differ (docs/evaluation.md 1am).
    /// Off in reports written before it existed.
    #[serde(default)]
    pub rung_average: bool,
    /// Keep the final fit of every family, not only the chosen one (studies compare them with
    /// the truth; costs one more analytic peak fit).
    pub keep_alternatives: bool,
    /// Keep every trial's fit as a table in the output (`Trial::candidate`; studies score each
    /// against the truth). Off, the trials' fits are only evaluated where the trials and the
    /// confidence read them, and only the reported one is tabulated (a table of 364 000 basis
    /// rows per trial saved). Off in reports written before it existed.
    #[serde(default)]
    pub keep_trial_fits: bool,
    /// Whether the written basis fit (the trials) sees pixels carried to their basis row's
    /// centre along theta_d and phi_d (`reconstruct::carry`); the ladder always decides on the
    /// pixels as they are. `Difference` by default since session 42, with the ladder's lowest
    /// basis rung (docs/evaluation.md 1ae; measured alone in 1s); off in reports written
    /// before.
    #[serde(default)]
    pub carry: Carry,
    /// The RMS normal tilt (degrees) the written basis fit is deblurred for
    /// (`reconstruct::deblur`; 0, the default, off); the ladder always decides on the pixels
    /// as they are. Study knob: docs/evaluation.md section 1v.
    #[serde(default)]
    pub deblur_deg: f64,
    /// Where the written model is the basis's (or the basis + peak's), its grazing peak cells
    /// averaged geometrically with its value at theta_d 54 degrees carried up by Lambert +
    /// GGX's shape, with this weight on the carried value (`reconstruct::grazing`; 0, the
    /// default: off). Study knob, measured and not adopted: docs/evaluation.md section 1x.
    #[serde(default)]
    pub grazing_transfer: f64,
    /// Where the written model is the basis's (or the basis + peak's), its peak cells (theta_h
    /// below this many degrees, fading to none at twice it) scaled so that the images' patch
    /// sums match, unless the images held out one at a time refute it
    /// (`reconstruct::peak_energy`; 1 by default in session 44, 1.5 since session 46:
    /// docs/evaluation.md sections 1ag and 1ai; 0 turns it off). Reports written before read
    /// back with 0, as they were made.
    #[serde(default)]
    pub peak_energy_deg: f64,
    /// Where 2 or more, the peak's factor is fitted per band of theta_d, up to this many
    /// bands (`reconstruct::peak_bands`; 0, the default, and in reports written before: one
    /// factor). Study knob, measured and not adopted: docs/evaluation.md section 1an.
    #[serde(default)]
    pub peak_energy_bands: usize,
    /// The theta_d extrapolation check (`reconstruct::extrapolation`). Off in reports written
    /// before it existed.
    #[serde(default = "ExtrapolationSettings::off")]
    pub extrapolation: ExtrapolationSettings,
}

impl Default for CoreSettings {
    fn default() -> Self {
        Self {
            reliable: ReliableSettings::default(),
            trials: TrialSettings::default(),
            components: ComponentSettings::default(),
            fixed_k: None,
            fixed_eta: crate::brdf::ridge::DEFAULT_ETA,
            confidence: ConfidenceSettings::default(),
            choose: TrialChoice::Similarity,
            ladder: LadderSettings::default(),
            model: ModelSelection::Auto,
            plausible: PlausibleSettings::default(),
            hedge: HedgeSettings::default(),
            peak_average: 0.5,
            rung_average: false,
            keep_alternatives: false,
            keep_trial_fits: false,
            carry: Carry::Difference,
            deblur_deg: 0.0,
            grazing_transfer: 0.0,
            peak_energy_deg: 1.5,
            peak_energy_bands: 0,
            extrapolation: ExtrapolationSettings::off(),
        }
    }
}

/// The model the result comes from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModelReport {
    pub family: Family,
    /// Basis components and ridge weight (basis and hybrid).
    pub k: Option<usize>,
    pub eta: Option<f64>,
    /// The analytic model or peak, when there is one.
    pub analytic: Option<AnalyticParams>,
    /// Why this model (the ladder's reason, or the setting that forced it).
    pub reason: String,
}

/// Parameters of a Lambert (+ GGX) model or peak.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AnalyticParams {
    pub kd: [f64; 3],
    pub ks: [f64; 3],
    pub alpha: f64,
    pub f0: f64,
}

impl From<LambertGgx> for AnalyticParams {
    fn from(m: LambertGgx) -> Self {
        Self {
            kd: m.kd,
            ks: m.ks,
            alpha: m.alpha,
            f0: m.f0,
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
    /// The chosen model as fitted (before the plausibility step).
    pub brdf: Box<dyn Candidate>,
    /// The result as written: the model tabulated and made plausible (shared: the output, its
    /// material's entry and the core hold it, and a table is 35 MB).
    pub table: Arc<MerlTable>,
    pub plausibility: Plausibility,
    pub model: ModelReport,
    /// The ladder, when it ran (not with a fixed k).
    pub ladder: Option<Ladder>,
    /// With `keep_alternatives`: every other family's final fit (as fitted, not made plausible).
    pub alternatives: Vec<(Family, Box<dyn Candidate>)>,
    /// The trials; with `keep_trial_fits`, each with its fit (but the reported one, moved into
    /// `brdf`, unless the trials were averaged).
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

/// Reliable pixels, the model ladder, trials, choice, the plausible table, confidence.
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
    let used: Vec<&Observation> = reliable
        .pixels
        .iter()
        .chain(reliable.brightest.as_ref())
        .collect();
    // The analytic fits see every observed pixel (as a user's least-squares fit would), or the
    // reliable ones as observed; never eq. 2's brightest pixel with n = h: that is the
    // basis's anchor, and would pin a GGX lobe to an infinitely narrow peak.
    let analytic_pixels = subset(
        if settings.ladder.analytic_on_all_pixels {
            observations
        } else {
            &reliable.pixels
        },
        settings.ladder.analytic_max_pixels,
        settings.trials.seed ^ 0xA11A,
    );
    // Lambert + GGX of the analytic rungs' pixels, fitted once: the carry, the halves' check,
    // the prior of unobserved cells and the hedge all read it.
    let lambert_ggx = fit_lambert_ggx_held(&analytic_pixels, settings.ladder.lambert_ggx_f0);
    // The written fit (the trials) may see the pixels carried to their row's centre
    // (`reconstruct::carry`), by that Lambert + GGX.
    let carrier = lambert_ggx
        .filter(|_| settings.carry == Carry::Difference)
        .map(|model| CarriedPrior {
            inner: prior,
            model,
        });
    // The ladder decides on the pixels as they are; the written fit (the trials) sees them
    // carried when asked.
    let carried_prior: &dyn Prior = match &carrier {
        Some(c) => c,
        None => prior,
    };
    // ... and deblurred for the normals' error when asked (`reconstruct::deblur`).
    let deblurred = (settings.deblur_deg > 0.0).then(|| DeblurredPrior {
        inner: carried_prior,
        sigma: settings.deblur_deg.to_radians(),
    });
    let trial_prior: &dyn Prior = match &deblurred {
        Some(d) => d,
        None => carried_prior,
    };
    // The hybrid's peak is part of the basis method: it sees the reliable pixels.
    let peak_pixels = subset(
        &reliable.pixels,
        settings.ladder.analytic_max_pixels,
        settings.trials.seed ^ 0xBEA4,
    );
    timings.push(("reliable".to_string(), t.elapsed().as_secs_f64()));

    // The model ladder: every family scored on held-out images (or blocks).
    let t = Instant::now();
    let images = observations.iter().map(|o| o.image + 1).max().unwrap_or(0);
    let mut ladder = match settings.fixed_k {
        Some(_) => None,
        None => {
            progress("model ladder (held-out images or blocks)");
            let mut ladder_settings = settings.ladder.clone();
            if let ModelSelection::Only(f) = settings.model {
                ladder_settings.analytic = false;
                ladder_settings.hybrid = f == Family::Hybrid;
            }
            climb(&LadderInput {
                prior,
                observations,
                reliable: &reliable,
                reliable_settings: &settings.reliable,
                samples: settings.trials.samples,
                basis_fit: settings.trials.basis_fit,
                components: &settings.components,
                settings: &ladder_settings,
                images,
                seed: settings.trials.seed,
            })
        }
    };
    let components = component_choice(settings, prior, ladder.as_ref(), &reliable);
    timings.push(("ladder".to_string(), t.elapsed().as_secs_f64()));

    // The family to report.
    let (family, reason) = match (settings.model, settings.fixed_k, &ladder) {
        (ModelSelection::Only(f), _, _) => (f, format!("{f} was asked for (--model)")),
        (_, Some(k), _) => (
            Family::Basis,
            format!("the basis with k = {k} was asked for (--components)"),
        ),
        (ModelSelection::Auto, None, Some(l)) => (l.chosen().family, l.reason.clone()),
        (ModelSelection::Auto, None, None) => (
            Family::Basis,
            "too few reliable pixels to hold any out: the basis at the fallback k".to_string(),
        ),
    };
    let (k, eta) = match (&ladder, family) {
        (Some(l), Family::Hybrid) if l.chosen().family == Family::Hybrid => (
            l.chosen().k.unwrap_or(components.k),
            l.chosen().eta.unwrap_or(components.eta),
        ),
        _ => (components.k, components.eta),
    };

    // How each family extrapolates in theta_d, on the scene's own pixels (a report; it
    // changes no fit and no choice).
    let extrapolation = if ladder.is_some() && !settings.extrapolation.quantiles.is_empty() {
        let t = Instant::now();
        progress("theta_d extrapolation check");
        let checks = check_extrapolation(
            &ExtrapolationInput {
                prior,
                reliable: &reliable,
                reliable_settings: &settings.reliable,
                analytic_pixels: &analytic_pixels,
                analytic_max_pixels: settings.ladder.analytic_max_pixels,
                samples: settings.trials.samples,
                basis_fit: settings.trials.basis_fit,
                k,
                eta,
                seed: settings.trials.seed,
            },
            &settings.extrapolation,
        );
        timings.push(("extrapolation".to_string(), t.elapsed().as_secs_f64()));
        checks
    } else {
        Vec::new()
    };

    // Trials of the basis at (k, eta): the paper's fit and eq. 3, also the confidence's
    // measure of agreement whatever the family.
    let t = Instant::now();
    progress(&format!(
        "{} trials ({} samples, k = {k}, eta = {eta})",
        settings.trials.trials, settings.trials.samples
    ));
    let (mut trials, fits) = run_trials(
        trial_prior,
        &reliable,
        observations,
        &settings.reliable,
        &settings.trials,
        k,
        eta,
    );
    let chosen = match settings.choose {
        TrialChoice::Similarity | TrialChoice::Mean | TrialChoice::Median => best_trial(&trials),
        TrialChoice::PixelError => fits
            .iter()
            .enumerate()
            .filter_map(|(i, f)| {
                let c = f.as_ref()?.candidate.as_ref();
                let e = super::components::held_out_error(c, observations);
                e.is_finite().then_some((i, e))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
            .map(|(i, _)| i),
    }
    .ok_or(CoreError::AllTrialsFailed)?;
    let present: Vec<&dyn Candidate> = fits
        .iter()
        .flatten()
        .map(|f| f.candidate.as_ref())
        .collect();
    let mut probed = AtProbe::many(prior, &present).into_iter();
    let at_probe: Vec<Option<AtProbe>> = fits
        .iter()
        .map(|f| f.as_ref().and_then(|_| probed.next()))
        .collect();
    // A basis whose trials disagree cannot be trusted beyond the pixels, whatever the held-out
    // images say (`LadderSettings::max_trial_disagreement`).
    let (mut family, mut reason) = (family, reason);
    let mut basis_unstable = false;
    if matches!(settings.model, ModelSelection::Auto)
        && matches!(family, Family::Basis | Family::Hybrid)
        && let Some(l) = ladder.as_mut()
        && let Some(reference) = at_probe[chosen].as_ref()
    {
        let others: Vec<&dyn Candidate> = at_probe
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != chosen)
            .filter_map(|(_, f)| f.as_ref().map(|f| f as &dyn Candidate))
            .collect();
        if let Some(d) = render_disagreement(&CandidateValues(reference), &others)
            && d > settings.ladder.max_trial_disagreement
        {
            let why = format!(
                "the basis trials disagree by {:.0} % in a rendered sphere (more than {:.0} %): \
                 which pixels were drawn decides the basis's extrapolation",
                100.0 * d,
                100.0 * settings.ladder.max_trial_disagreement
            );
            if l.choose_analytic(&settings.ladder, &why) {
                family = l.chosen().family;
                reason = l.reason.clone();
                basis_unstable = true;
            }
        }
    }
    // The same test for a chosen Lambert + GGX: fitted to halves of the images, do its lobes
    // agree as a rendered sphere sees them? A narrow highlight seen by a few pixels lets
    // which pixels were drawn set the lobe's width and height, and the sphere then shows a
    // peak no image did; the basis (when its trials agree) or Lambert is chosen instead.
    if matches!(settings.model, ModelSelection::Auto)
        && family == Family::LambertGgx
        && let Some(l) = ladder.as_mut()
        && let Some(m) = lambert_ggx
        && let Some(d) = half_disagreement(
            &m,
            &analytic_pixels,
            settings.trials.seed,
            settings.ladder.lambert_ggx_f0,
        )
        && d > settings.ladder.max_trial_disagreement
    {
        let why = format!(
            "{}Lambert + GGX fitted to halves of the images disagrees by {:.0} % in a rendered \
             sphere (more than {:.0} %): which pixels were drawn decides its extrapolation",
            if basis_unstable {
                format!("{reason}; but ")
            } else {
                String::new()
            },
            100.0 * d,
            100.0 * settings.ladder.max_trial_disagreement
        );
        let allowed: &[Family] = if basis_unstable {
            &[Family::Lambert]
        } else {
            &[Family::Lambert, Family::Basis, Family::Hybrid]
        };
        if l.choose_among(&settings.ladder, allowed, &why, "among the others") {
            family = l.chosen().family;
            reason = l.reason.clone();
        }
    }
    // The trials' fits were evaluated on demand; what is kept is tabulated (the same values).
    let basis_fit: Box<dyn Candidate> = match settings.choose {
        TrialChoice::Mean | TrialChoice::Median => {
            let tables: Vec<Box<dyn Candidate>> = fits
                .iter()
                .flatten()
                .filter_map(|f| f.tabulate(trial_prior))
                .collect();
            let tables: Vec<&dyn Candidate> = tables.iter().map(|t| t.as_ref()).collect();
            Box::new(TableCandidate(if settings.choose == TrialChoice::Mean {
                mean_table(&tables)
            } else {
                median_table(&tables)
            }))
        }
        _ => fits[chosen]
            .as_ref()
            .and_then(|f| f.tabulate(trial_prior))
            .ok_or(CoreError::AllTrialsFailed)?,
    };
    // The confidence's trial agreement: every trial but the one reported (all with the mean).
    let others: Vec<&dyn Candidate> = at_probe
        .iter()
        .enumerate()
        .filter(|(i, _)| settings.choose.pools_trials() || *i != chosen)
        .filter_map(|(_, f)| f.as_ref().map(|f| f as &dyn Candidate))
        .collect();
    timings.push(("trials".to_string(), t.elapsed().as_secs_f64()));

    // The reported model, and the analytic prior for regions no pixel saw.
    let t = Instant::now();
    progress(&format!("{family}: the final fit and a plausible table"));
    let mut alternatives: Vec<(Family, Box<dyn Candidate>)> = Vec::new();
    if settings.keep_alternatives {
        if family != Family::Lambert
            && let Some(m) = fit_lambert_rung(&analytic_pixels, settings.ladder.lambert_fit)
        {
            alternatives.push((Family::Lambert, Box::new(AnalyticCandidate(m))));
        }
        if family != Family::LambertGgx
            && let Some(m) = lambert_ggx
        {
            alternatives.push((Family::LambertGgx, Box::new(AnalyticCandidate(m))));
        }
        if family != Family::Hybrid
            && let Some(peak) = fit_peak(basis_fit.as_ref(), &peak_pixels)
        {
            alternatives.push((
                Family::Hybrid,
                Box::new(WithPeak {
                    base: Box::new(TableCandidate(basis_fit.to_merl_table())),
                    peak,
                }),
            ));
        }
    }
    let basis_alternative = (settings.keep_alternatives && family != Family::Basis)
        .then(|| TableCandidate(basis_fit.to_merl_table()));
    let (brdf, analytic): (Box<dyn Candidate>, Option<AnalyticParams>) = match family {
        Family::Lambert => match fit_lambert_rung(&analytic_pixels, settings.ladder.lambert_fit) {
            Some(m) => (
                Box::new(AnalyticCandidate(m)),
                Some(AnalyticParams {
                    kd: m.albedo,
                    ks: [0.0; 3],
                    alpha: 0.0,
                    f0: 0.0,
                }),
            ),
            None => (basis_fit, None),
        },
        Family::LambertGgx => match lambert_ggx {
            Some(m) => (Box::new(AnalyticCandidate(m)), Some(m.into())),
            None => (basis_fit, None),
        },
        Family::Basis => (basis_fit, None),
        Family::Hybrid => match fit_peak(basis_fit.as_ref(), &peak_pixels) {
            Some(peak) => (
                Box::new(WithPeak {
                    base: basis_fit,
                    peak,
                }),
                Some(peak.into()),
            ),
            None => (basis_fit, None),
        },
    };
    if let Some(b) = basis_alternative {
        alternatives.push((Family::Basis, Box::new(b)));
    }
    // Tabulated once: the plausibility step, the peak average's and the hedge's all read it.
    let prior_model = match (family, lambert_ggx) {
        (Family::Basis | Family::Hybrid, Some(m)) => Some(Tabulated::of(&AnalyticCandidate(m))),
        _ => None,
    };
    // Where the held-out images cannot tell whether a peak sits on the basis, both are kept:
    // the basis + peak's table is averaged in after the plausibility step.
    let averaged_peak = (family == Family::Basis
        && settings.peak_average > 0.0
        && ladder
            .as_ref()
            .is_some_and(|l| l.peak_within_noise(&settings.ladder)))
    .then(|| fit_peak(brdf.as_ref(), &peak_pixels))
    .flatten();
    let typical = prior.typical();
    let plausible_of = |c: &dyn Candidate| {
        // The grazing peak carried by Lambert + GGX's theta_d shape (reconstruct::grazing).
        let carried = prior_model
            .as_ref()
            .filter(|_| settings.grazing_transfer > 0.0)
            .map(|p| GrazingTransfer {
                model: c,
                shape: p,
                weight: settings.grazing_transfer,
            });
        let c = carried.as_ref().map_or(c, |g| g as &dyn Candidate);
        make_plausible_shaped(
            c,
            prior_model.as_ref().map(|p| {
                (
                    p as &dyn Candidate,
                    "Lambert + GGX fitted to the same pixels",
                )
            }),
            typical.as_deref(),
            &used,
            &settings.plausible,
        )
    };
    let (mut table, mut plausibility) = plausible_of(brdf.as_ref());
    // The basis rungs the held-out images cannot tell from the chosen one, averaged in
    // (equal weights, geometric: the running mean's weight on the n-th is 1 / n).
    if family == Family::Basis
        && settings.rung_average
        && eta > 0.0
        && let Some(l) = ladder.as_ref()
        && let Some(f) = fits[chosen].as_ref()
    {
        let mut n = 1usize;
        for (k2, eta2) in l.basis_within_noise(&settings.ladder) {
            if let Some(c) = f.tabulate_at(trial_prior, k2, eta2 / eta) {
                let (other, _) = plausible_of(c.as_ref());
                n += 1;
                blend_into(&mut table, &other, 1.0 / n as f64);
            }
        }
        plausibility.max_albedo_after = albedo_curve(&table).into_iter().fold(0.0, f64::max);
        plausibility.rung_average = Some(n);
        if n > 1 {
            reason = format!(
                "{reason}; {} other basis rung(s) within noise of it both ways averaged in \
                 (geometrically, equal weights)",
                n - 1
            );
        }
    }
    if prior_model.is_some() && settings.grazing_transfer > 0.0 {
        plausibility.grazing_transfer = Some(settings.grazing_transfer.min(1.0));
    }
    if let Some(peak) = averaged_peak {
        let with_peak = WithPeak {
            base: Box::new(Borrowed(brdf.as_ref())),
            peak,
        };
        let (peaked, _) = plausible_of(&with_peak);
        let w = settings.peak_average.clamp(0.0, 1.0);
        blend_into(&mut table, &peaked, w);
        plausibility.max_albedo_after = albedo_curve(&table).into_iter().fold(0.0, f64::max);
        plausibility.peak_average = Some(w);
        let said = format!(
            "a GGX peak on top neither lowers nor raises the held-out error beyond noise, so \
             the written table is the basis averaged (geometrically, weight {w}) with the \
             basis + that peak"
        );
        reason = if reason.contains(NO_PEAK) {
            reason.replace(NO_PEAK, &said)
        } else {
            format!("{reason}; {said}")
        };
    }
    // The peak's energy from the images' patch sums (reconstruct::peak_energy).
    if matches!(family, Family::Basis | Family::Hybrid) && settings.peak_energy_deg > 0.0 {
        // every observed pixel: a patch's sum integrates the table only over all of its pixels
        let all: Vec<&Observation> = observations.iter().collect();
        let patch_px = super::ladder::patch_size(observations.iter(), &settings.ladder);
        if let Some(mut fit) =
            super::peak_energy::fit_scale(&table, &all, patch_px, settings.peak_energy_deg)
        {
            let weights = super::peak_energy::theta_d_weights(&all);
            // per theta_d band where asked for (reconstruct::peak_bands, a study knob)
            fit.bands = (settings.peak_energy_bands >= 2)
                .then(|| {
                    super::peak_bands::fit_bands(
                        &table,
                        &all,
                        patch_px,
                        settings.peak_energy_deg,
                        settings.peak_energy_bands,
                        &fit,
                    )
                })
                .flatten();
            match &fit.bands {
                Some(b) if b.applied => {
                    super::peak_bands::apply(&mut table, b, settings.peak_energy_deg, &weights)
                }
                _ => super::peak_energy::apply(&mut table, &fit, &weights),
            }
            let curve = albedo_curve(&table);
            let (curve, _) =
                super::plausible::cap_albedo(&mut table, curve, settings.plausible.max_albedo);
            plausibility.max_albedo_after = curve.into_iter().fold(0.0, f64::max);
            plausibility.peak_energy = Some(fit);
        }
    }
    // Where held-out images cannot judge the extrapolation, average it with Lambert + GGX's.
    if let Some(p) = &prior_model
        && settings.hedge.strength > 0.0
    {
        let unseen_share = unseen_render_share(&table, &used);
        let unresolved = lambert_ggx.is_some_and(|m| super::hedge::unresolved_lobe(&m));
        let analytic_weight = if unresolved {
            0.0
        } else {
            settings.hedge.analytic_weight(unseen_share)
        };
        if analytic_weight > 0.0 {
            let (analytic, _) = make_plausible(p, None, &used, &settings.plausible);
            blend_into(&mut table, &analytic, analytic_weight);
            plausibility.max_albedo_after = albedo_curve(&table).into_iter().fold(0.0, f64::max);
        }
        plausibility.hedge = Some(Hedge {
            unseen_share,
            analytic_weight,
            f0: lambert_ggx.map(|m| m.f0),
            f0_held: settings.ladder.lambert_ggx_f0 == F0Rule::Physical
                && !super::fresnel::fresnel_identifiable(&analytic_pixels),
            unresolved_lobe: unresolved,
        });
    }
    plausibility.extrapolation = extrapolation;
    timings.push(("plausible".to_string(), t.elapsed().as_secs_f64()));

    let t = Instant::now();
    progress("confidence (trial agreement, coverage)");
    let held_out = ladder.as_ref().and_then(|l| l.chosen().error).or_else(|| {
        components
            .curve
            .iter()
            .find(|p| p.k == components.k && p.eta == components.eta)
            .and_then(|p| p.error)
    });
    let analytic_held_out = ladder.as_ref().and_then(|l| {
        l.rungs
            .iter()
            .find(|r| r.family == Family::LambertGgx)
            .and_then(|r| r.error)
    });
    let confidence = assess(
        &table,
        &others,
        &used,
        HeldOut {
            chosen: held_out,
            analytic: analytic_held_out,
        },
        &settings.confidence,
    );
    timings.push(("confidence".to_string(), t.elapsed().as_secs_f64()));
    if settings.keep_trial_fits {
        for (i, (trial, fit)) in trials.iter_mut().zip(&fits).enumerate() {
            if settings.choose.pools_trials() || i != chosen {
                trial.candidate = fit.as_ref().and_then(|f| f.tabulate(trial_prior));
            }
        }
    }
    let model = ModelReport {
        family,
        k: matches!(family, Family::Basis | Family::Hybrid).then_some(k),
        eta: matches!(family, Family::Basis | Family::Hybrid).then_some(eta),
        analytic,
        reason,
    };
    Ok(CoreOutput {
        brdf,
        table: Arc::new(table),
        plausibility,
        model,
        ladder,
        alternatives,
        trials,
        chosen_trial: chosen,
        components,
        reliable_pixels: used.len(),
        dropped_by_curvature: reliable.dropped_by_curvature,
        curvature_threshold: reliable.curvature_threshold,
        confidence,
        timings,
    })
}

/// A tabulated BRDF as a candidate.
struct TableCandidate(MerlTable);

/// The per-bin, per-channel median of the tables (the mean of the middle two for an even count).
fn median_table(fits: &[&dyn Candidate]) -> MerlTable {
    MerlTable::from_fn(|b| {
        let mut out = [0.0; 3];
        let mut v: Vec<f64> = Vec::with_capacity(fits.len());
        for (c, o) in out.iter_mut().enumerate() {
            v.clear();
            v.extend(fits.iter().map(|f| f.eval_bin(b.index())[c]));
            v.sort_by(f64::total_cmp);
            let n = v.len();
            *o = match n {
                0 => 0.0,
                _ if n % 2 == 1 => v[n / 2],
                _ => 0.5 * (v[n / 2 - 1] + v[n / 2]),
            };
        }
        Some(out)
    })
}

/// The bin-by-bin mean of several fits, as a table.
fn mean_table(fits: &[&dyn Candidate]) -> MerlTable {
    let n = fits.len().max(1) as f64;
    MerlTable::from_fn(|b| {
        let mut sum = [0.0; 3];
        for f in fits {
            let v = f.eval_bin(b.index());
            for c in 0..3 {
                sum[c] += v[c];
            }
        }
        Some(sum.map(|x| x / n))
    })
}

impl TrialChoice {
    /// Whether the written basis fit pools every trial (`Mean`, `Median`) instead of one.
    pub fn pools_trials(self) -> bool {
        matches!(self, Self::Mean | Self::Median)
    }
}

impl Candidate for TableCandidate {
    fn eval_bin(&self, bin: usize) -> [f64; 3] {
        self.0.get(bin).unwrap_or([0.0; 3])
    }

    fn to_merl_table(&self) -> MerlTable {
        self.0.clone()
    }
}

/// The basis's k and eta: fixed by the settings, the ladder's best basis rung (its curve is the
/// basis rungs' held-out errors), or the old single-split validation when the ladder could not
/// run.
fn component_choice(
    settings: &CoreSettings,
    prior: &dyn Prior,
    ladder: Option<&Ladder>,
    reliable: &super::reliable::Reliable,
) -> ComponentChoice {
    if let Some(k) = settings.fixed_k {
        return ComponentChoice {
            k: k.min(prior.max_components()).max(1),
            eta: settings.fixed_eta,
            curve: Vec::new(),
            held_out_pixels: 0,
            samples: 0,
            note: Some("fixed by the settings".to_string()),
        };
    }
    let Some(ladder) = ladder else {
        return choose_components(
            prior,
            reliable,
            &settings.reliable,
            settings.trials.samples,
            &settings.components,
            settings.trials.seed,
        );
    };
    let basis: Vec<&super::ladder::Rung> = ladder
        .rungs
        .iter()
        .filter(|r| r.family == Family::Basis)
        .collect();
    let curve: Vec<ValidationPoint> = basis
        .iter()
        .filter_map(|r| {
            Some(ValidationPoint {
                k: r.k?,
                eta: r.eta?,
                error: r.error,
            })
        })
        .collect();
    // The chosen rung's own (k, eta) when it is a basis rung; else the simplest basis rung
    // within one standard error of the best basis rung.
    let pick = if matches!(ladder.chosen().family, Family::Basis | Family::Hybrid) {
        Some(ladder.chosen())
    } else {
        let best = basis
            .iter()
            .filter_map(|r| Some((r, r.error?, r.standard_error.unwrap_or(0.0))))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        best.and_then(|(_, e, se)| {
            basis
                .iter()
                .filter(|r| r.error.is_some_and(|x| x <= e + se))
                .min_by(|a, b| {
                    a.parameters
                        .cmp(&b.parameters)
                        .then(b.eta.unwrap_or(0.0).total_cmp(&a.eta.unwrap_or(0.0)))
                })
                .copied()
        })
    };
    let fallback = settings
        .components
        .fallback
        .min(prior.max_components())
        .max(1);
    ComponentChoice {
        k: pick.and_then(|r| r.k).unwrap_or(fallback),
        eta: pick
            .and_then(|r| r.eta)
            .unwrap_or(settings.components.fallback_eta),
        note: pick
            .is_none()
            .then(|| format!("every basis rung failed on some fold: k = {fallback}")),
        curve,
        held_out_pixels: ladder.held_out_pixels,
        samples: settings.trials.samples,
    }
}

/// How much Lambert + GGX fits to halves of the pixels' images differ from `full` (fitted to
/// them all) as a rendered sphere sees them (`confidence::render_disagreement`): two seeded
/// splits of the images in two halves each, whole images apart (neighbouring pixels of one
/// image would agree for nothing). `None` with fewer than two images or no fit.
pub fn half_disagreement(
    full: &LambertGgx,
    pixels: &[Observation],
    seed: u64,
    f0: F0Rule,
) -> Option<f64> {
    use rand::SeedableRng;
    use rand::seq::SliceRandom;
    let mut images: Vec<usize> = pixels.iter().map(|o| o.image).collect();
    images.sort_unstable();
    images.dedup();
    if images.len() < 2 {
        return None;
    }
    let mut fits = Vec::new();
    for split in 0..2u64 {
        let mut order = images.clone();
        order.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(
            seed ^ 0x4A1F ^ split,
        ));
        let first: std::collections::HashSet<usize> =
            order[..order.len() / 2].iter().copied().collect();
        for side in [true, false] {
            let half: Vec<Observation> = pixels
                .iter()
                .filter(|o| first.contains(&o.image) == side)
                .copied()
                .collect();
            if let Some(m) = fit_lambert_ggx_held(&half, f0) {
                fits.push(AnalyticCandidate(m));
            }
        }
    }
    let others: Vec<&dyn Candidate> = fits.iter().map(|f| f as &dyn Candidate).collect();
    render_disagreement(&CandidateValues(&AnalyticCandidate(*full)), &others)
}

/// A borrowed candidate as a boxed one (the averaged peak sits on the basis fit in place).
struct Borrowed<'a>(&'a dyn Candidate);

impl Candidate for Borrowed<'_> {
    fn eval_bin(&self, bin: usize) -> [f64; 3] {
        self.0.eval_bin(bin)
    }
}

#[cfg(test)]
mod tests {
    use super::super::baselines::fit_lambert_ggx;
    use super::super::components::held_out_error;
    use super::super::prior::synthetic::{CosinePrior, cap_pixels};
    use super::*;

    #[test]
    fn settings_written_before_the_hedge_and_peak_average_read_back_with_them_off() {
        let mut json = serde_json::to_value(CoreSettings::default()).unwrap();
        let old = json.as_object_mut().unwrap();
        assert!(old.remove("hedge").is_some());
        assert!(old.remove("peak_average").is_some());
        assert!(old.remove("extrapolation").is_some());
        let read: CoreSettings = serde_json::from_value(json).unwrap();
        assert!(read.extrapolation.quantiles.is_empty());
        assert_eq!(read.hedge.strength, 0.0);
        assert_eq!(read.peak_average, 0.0);
        assert_eq!(
            CoreSettings {
                hedge: HedgeSettings::default(),
                peak_average: CoreSettings::default().peak_average,
                ..read
            },
            CoreSettings::default()
        );
    }

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

    /// Pixels over a cap from six images: a dark Lambertian surface with a narrow peak
    /// (theta_h under 4 degrees) that no GGX tail announces, the peak's pixels in the images
    /// `peak_image(i)` says and the others spread over all six.
    fn peak_scene(peak_image: impl Fn(usize) -> usize) -> Vec<Observation> {
        let mut obs = cap_pixels(|_| 0.05, 900, [1.0; 3]);
        for (i, o) in obs.iter_mut().enumerate() {
            let h = (o.light + o.view).normalize();
            let theta_h = o.normal.dot(&h).clamp(-1.0, 1.0).acos().to_degrees();
            o.image = i % 6;
            if theta_h < 4.0 {
                o.image = peak_image(i);
                o.reflectance = [0.05 + 30.0 * (1.0 - theta_h / 4.0); 3];
                o.radiance = o.reflectance.map(|r| r * o.cos_theta_i);
            }
        }
        obs
    }

    #[test]
    fn a_peak_every_image_sees_fits_alike_from_either_half_of_the_images() {
        let obs = peak_scene(|i| i % 6);
        let full = fit_lambert_ggx(&obs).expect("fits");
        let d = half_disagreement(&full, &obs, 1, F0Rule::Free).expect("six images");
        assert!(d < 0.1, "{d}");
    }

    #[test]
    fn a_peak_only_one_image_sees_makes_the_halves_disagree() {
        let obs = peak_scene(|_| 0);
        let full = fit_lambert_ggx(&obs).expect("fits");
        let d = half_disagreement(&full, &obs, 1, F0Rule::Free).expect("six images");
        assert!(d > 0.3, "{d}");
        // one image: nothing to split
        let one: Vec<Observation> = obs.iter().map(|o| Observation { image: 0, ..*o }).collect();
        assert_eq!(half_disagreement(&full, &one, 1, F0Rule::Free), None);
    }

    fn run(choose: TrialChoice) -> (CoreOutput, Vec<Observation>) {
        let obs = scene();
        let mut settings = CoreSettings {
            choose,
            fixed_k: Some(3),
            keep_trial_fits: true,
            ..CoreSettings::default()
        };
        settings.trials.trials = 6;
        settings.trials.samples = 6;
        let out = reconstruct_observations(&obs, &CosinePrior { k: 3 }, &settings, &mut |_| {})
            .expect("reconstructs");
        (out, obs)
    }

    /// A dark cap of one image (no bin scaled for the albedo) reconstructed with 3 components
    /// and 3 trials of 6 samples, the hedge off (its weight reads the whole render, which the
    /// steps under test change), after `change` to the settings.
    fn dark_cap(change: impl Fn(&mut CoreSettings)) -> CoreOutput {
        let obs = cap_pixels(|b| 0.04 + 0.01 * ((b % 5) as f64), 400, [1.0, 0.8, 0.6]);
        let mut settings = CoreSettings {
            fixed_k: Some(3),
            hedge: HedgeSettings::off(),
            ..CoreSettings::default()
        };
        settings.trials.trials = 3;
        settings.trials.samples = 6;
        change(&mut settings);
        reconstruct_observations(&obs, &CosinePrior { k: 3 }, &settings, &mut |_| {})
            .expect("reconstructs")
    }

    /// The grazing transfer (`reconstruct::grazing`) changes the written table in the grazing
    /// peak cells only, and the report gives its weight where it was applied. The
    /// scene is dark enough that no bin is scaled for the albedo and the hedge is off (its
    /// weight reads the whole render), so every other bin is the same number.
    #[test]
    fn the_grazing_transfer_moves_only_the_grazing_peak_cells_and_is_reported() {
        use super::super::grazing::carried;
        use crate::brdf::coords::MerlBin;
        let run = |w: f64| dark_cap(|s| s.grazing_transfer = w);
        let (off, on) = (run(0.0), run(0.5));
        assert_eq!(off.model.family, Family::Basis);
        assert_eq!(off.plausibility.grazing_transfer, None);
        assert_eq!(on.plausibility.grazing_transfer, Some(0.5));
        assert_eq!(
            (off.plausibility.scaled_bins, on.plausibility.scaled_bins),
            (0, 0)
        );
        let (mut moved, mut kept) = (0, 0);
        for index in (0..crate::brdf::coords::MERL_BINS).step_by(7) {
            let Some(b) = MerlBin::from_index(index).filter(MerlBin::is_above_horizon) else {
                continue;
            };
            if carried(&b) {
                moved += usize::from(on.table.get(index) != off.table.get(index));
            } else {
                assert_eq!(on.table.get(index), off.table.get(index), "{b:?}");
                kept += 1;
            }
        }
        assert!(moved > 100 && kept > 10_000, "{moved} moved, {kept} kept");
    }

    /// The peak's energy step (`reconstruct::peak_energy`) runs unless turned off and is
    /// reported; on a single image no image can be held out to check the factor it
    /// fits, so the factor is reported and not applied: the table is the same, bin for bin.
    /// (The module's tests cover the factor applied.)
    #[test]
    fn the_peak_energy_step_is_reported_and_needs_images_to_hold_out() {
        let run = |deg: f64| dark_cap(|s| s.peak_energy_deg = deg);
        let (off, on) = (run(0.0), run(CoreSettings::default().peak_energy_deg));
        assert_eq!(off.plausibility.peak_energy, None);
        let e = on.plausibility.peak_energy.expect("reported");
        assert!(e.patches > 0 && e.fitted != 1.0, "{e:?}");
        assert_eq!((e.images, e.scale), (0, 1.0), "{e:?}");
        for index in (0..crate::brdf::coords::MERL_BINS).step_by(7) {
            assert_eq!(off.table.get(index), on.table.get(index));
        }
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

    /// A trial that extrapolates far off moves the median by nothing and the mean by a third
    /// of its excess; with an even count the median is the middle pair's mean.
    #[test]
    fn the_median_of_the_trials_tables_ignores_one_far_off_trial() {
        let constant = |v: f64| TableCandidate(MerlTable::from_fn(|_| Some([v, 2.0 * v, 0.5 * v])));
        let (a, b, far) = (constant(1.0), constant(2.0), constant(100.0));
        let three: Vec<&dyn Candidate> = vec![&a, &far, &b];
        let median = median_table(&three);
        let mean = mean_table(&three);
        let close = |t: &MerlTable, index: usize, want: [f64; 3]| {
            let got = t.get(index).expect("a bin");
            assert!(
                got.iter().zip(want).all(|(g, w)| (g - w).abs() < 1e-9 * w),
                "bin {index}: {got:?} against {want:?}"
            );
        };
        for index in [0, 12_345, crate::brdf::coords::MERL_BINS - 1] {
            close(&median, index, [2.0, 4.0, 1.0]);
            close(&mean, index, [103.0 / 3.0, 206.0 / 3.0, 103.0 / 6.0]);
        }
        let c = constant(4.0);
        let four: Vec<&dyn Candidate> = vec![&a, &b, &c, &far];
        close(&median_table(&four), 7, [3.0, 6.0, 1.5]);
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

    /// Where the basis is chosen, the rungs within noise of it are averaged in, as many as
    /// the ladder says, and the table moves exactly when there were some; off, nothing is.
    #[test]
    fn the_basis_rungs_within_noise_are_averaged_in_and_reported() {
        let obs = scene();
        let with = |rung_average: bool| {
            let mut settings = CoreSettings {
                model: ModelSelection::Only(Family::Basis),
                rung_average,
                ..CoreSettings::default()
            };
            settings.trials.trials = 3;
            settings.trials.samples = 12;
            let out = reconstruct_observations(&obs, &CosinePrior { k: 3 }, &settings, &mut |_| {})
                .expect("reconstructs");
            (out, settings)
        };
        let (off, _) = with(false);
        let (on, settings) = with(true);
        assert_eq!(off.plausibility.rung_average, None);
        let ladder = on.ladder.as_ref().expect("the ladder ran");
        assert_eq!(ladder.chosen().family, Family::Basis);
        let within = ladder.basis_within_noise(&settings.ladder);
        assert_eq!(on.plausibility.rung_average, Some(within.len() + 1));
        assert!(
            !within.is_empty(),
            "this scene's rungs fit it alike: {:?}",
            ladder.rungs
        );
        let moved = (0..crate::brdf::coords::MERL_BINS)
            .step_by(7)
            .any(|i| on.table.get(i) != off.table.get(i));
        assert!(moved, "the average moved the table");
        assert!(
            on.model.reason.contains("averaged in (geometrically"),
            "{}",
            on.model.reason
        );
    }

    #[test]
    fn keeping_the_trials_fits_changes_nothing_but_what_the_output_holds() {
        for choose in [
            TrialChoice::Similarity,
            TrialChoice::Mean,
            TrialChoice::Median,
        ] {
            let (kept, obs) = run(choose);
            let mut settings = CoreSettings {
                choose,
                fixed_k: Some(3),
                ..CoreSettings::default()
            };
            settings.trials.trials = 6;
            settings.trials.samples = 6;
            let lean =
                reconstruct_observations(&obs, &CosinePrior { k: 3 }, &settings, &mut |_| {})
                    .expect("reconstructs");
            assert_eq!(lean.chosen_trial, kept.chosen_trial, "{choose:?}");
            assert_eq!(lean.confidence, kept.confidence, "{choose:?}");
            for index in (0..crate::brdf::coords::MERL_BINS).step_by(101) {
                assert_eq!(
                    lean.table.get(index),
                    kept.table.get(index),
                    "{choose:?} {index}"
                );
            }
            assert!(lean.trials.iter().all(|t| t.candidate.is_none()));
            let with_fits = kept.trials.iter().filter(|t| t.candidate.is_some()).count();
            // the mean and the median report every trial; otherwise the reported one's fit is
            // `brdf`
            let expected = if choose.pools_trials() { 6 } else { 5 };
            assert_eq!(with_fits, expected, "{choose:?}");
            for (a, b) in lean.trials.iter().zip(&kept.trials) {
                assert_eq!(a.similarity, b.similarity);
            }
        }
    }
}
