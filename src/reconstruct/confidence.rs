//! How far a reconstruction can be trusted, judged only from what the pipeline saw (never from a
//! ground truth), so an operator gets "low confidence" instead of a confident wrong answer.
//!
//! Four indicators, each with its own reason when it fails; the renders are those of a small
//! sphere probe (`render::probe`: the standard environment, as the rendered error of
//! docs/error-metrics.md sees a BRDF):
//! - **disagreement**: the median, over the trials (basis fits to different random subsets of
//!   the pixels), of the relative difference between their environment render and the
//!   result's. Where the pixels pin the BRDF down, different fits of them render alike; where
//!   the result is extrapolated, they do not. When the ladder chose an analytic model, it
//!   measures how far a data-driven fit of the same pixels renders from it.
//! - **held-out error**: the chosen model's image-space error on held-out images or blocks
//!   (`reconstruct::ladder`): the model does not even explain what was seen. Where Lambert +
//!   GGX, fitted to the same pixels, misses the same held-out data by clearly more (the chosen
//!   error below `held_out_shared_ratio` times it), the miss is the images' or the mesh's (a
//!   highlight the normals cannot place) and every model shares it: it then lowers the verdict
//!   to medium at most, so a result that explains the images best is not called low for it.
//! - **theta_d span**: the 10th to 90th percentile range of `theta_d` over the reliable pixels.
//!   One fixed light on a turntable sees a single `theta_d` (METHOD.md section 1), so the rest of
//!   the domain is extrapolated.
//! - **unseen share**: the share of the result's environment render that comes from
//!   (theta_h, theta_d) cells of 10 x 10 MERL bins where no pixel was observed: how much of what
//!   a user will see was never measured. When it lowers the verdict, its reason also names the
//!   theta_d band that holds most of it and the light positions that would observe that band:
//!   the angle between light and view at a surface point is twice theta_d, whatever theta_h
//!   ([`UnseenBand`]).
//!
//! The thresholds are the `ConfidenceSettings` defaults, tuned on one half of the accuracy grid
//! and checked on the other (`brdf-rig bench confidence`, docs/evaluation.md section 5). Pure
//! computation: no files, no printing.

use super::observe::Observation;
use super::prior::{Candidate, CandidateValues, Prior};
use crate::brdf::BinValues;
use crate::brdf::coords::{MerlBin, THETA_D_BINS, THETA_H_BINS};
use crate::render::probe::{ProbeSettings, SphereProbe, compare};
use serde::{Deserialize, Serialize};
use std::sync::OnceLock;

/// The probe of the confidence (smaller than the evaluation's: it renders every trial).
fn probe() -> &'static SphereProbe {
    static PROBE: OnceLock<SphereProbe> = OnceLock::new();
    PROBE.get_or_init(|| {
        SphereProbe::standard_serial(ProbeSettings {
            size: 24,
            phi_h_steps: 16,
        })
    })
}

/// A candidate with its values at the confidence probe's bins computed once (in parallel):
/// the trials' fits are evaluated on demand, and the trial agreement renders each of them
/// twice (the ladder's check of the basis's trials, then the confidence). The same values as
/// the candidate's own.
pub struct AtProbe<'a> {
    candidate: &'a dyn Candidate,
    values: Vec<[f64; 3]>,
}

impl<'a> AtProbe<'a> {
    pub fn new(candidate: &'a dyn Candidate) -> Self {
        let values = candidate.values_at_bins(probe().bins());
        Self { candidate, values }
    }

    /// [`Self::new`] of each candidate, evaluated together by `prior` where it can
    /// ([`Prior::values_of_fits`]: the trials' fits of a basis read each basis row once).
    pub fn many(prior: &dyn Prior, candidates: &[&'a dyn Candidate]) -> Vec<Self> {
        prior
            .values_of_fits(candidates, probe().bins())
            .into_iter()
            .zip(candidates)
            .map(|(values, &candidate)| Self { candidate, values })
            .collect()
    }
}

impl Candidate for AtProbe<'_> {
    fn eval_bin(&self, bin: usize) -> [f64; 3] {
        self.candidate.eval_bin(bin)
    }

    fn values_at_bins(&self, bins: &[usize]) -> Vec<[f64; 3]> {
        let at = probe().bins();
        if std::ptr::eq(bins.as_ptr(), at.as_ptr()) && bins.len() == at.len() {
            self.values.clone()
        } else {
            self.candidate.values_at_bins(bins)
        }
    }
}

/// The median, over `others`, of the relative difference between their rendered sphere and
/// that of `reference` (values at the probe's bins, `probe().bins()`), in the confidence's small
/// probe under the standard environment. `None` without others.
fn render_disagreement_of(reference: &[[f64; 3]], others: &[&dyn Candidate]) -> Option<f64> {
    let probe = probe();
    let reference = probe.render_values(reference);
    let mut diffs: Vec<f64> = others
        .iter()
        .map(|c| compare(&reference, &probe.render(&CandidateValues(*c))).environment)
        .filter(|d| d.is_finite())
        .collect();
    crate::stats::median(&mut diffs)
}

/// How much fits disagree as images see them: the median relative difference of `others`'
/// rendered sphere from `reference`'s (the confidence's probe, standard environment).
pub fn render_disagreement(reference: &dyn BinValues, others: &[&dyn Candidate]) -> Option<f64> {
    render_disagreement_of(&reference.values_at(probe().bins()), others)
}

/// Overall verdict.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Level {
    Low,
    Medium,
    High,
}

impl std::fmt::Display for Level {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Level::Low => "low",
            Level::Medium => "medium",
            Level::High => "high",
        })
    }
}

/// Where each indicator turns a result to medium and to low confidence.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ConfidenceSettings {
    pub disagreement_medium: f64,
    pub disagreement_low: f64,
    pub held_out_medium: f64,
    pub held_out_low: f64,
    pub theta_d_span_medium_deg: f64,
    pub theta_d_span_low_deg: f64,
    pub unseen_energy_medium: f64,
    pub unseen_energy_low: f64,
    /// The held-out miss is shared (at most medium) when the chosen model's held-out error is
    /// below this fraction of Lambert + GGX's on the same data (0: never).
    #[serde(default)]
    pub held_out_shared_ratio: f64,
}

impl Default for ConfidenceSettings {
    fn default() -> Self {
        Self {
            disagreement_medium: 0.15,
            disagreement_low: 0.35,
            held_out_medium: 0.2,
            held_out_low: 0.33,
            theta_d_span_medium_deg: 20.0,
            theta_d_span_low_deg: 3.2,
            unseen_energy_medium: 0.35,
            unseen_energy_low: 0.55,
            held_out_shared_ratio: 0.8,
        }
    }
}

/// The verdict and the indicators behind it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Confidence {
    pub level: Level,
    /// One sentence per indicator that lowered the level.
    pub reasons: Vec<String>,
    /// Median relative difference of the trials' environment renders from the result's;
    /// `None` without a fitted trial.
    pub trial_disagreement: Option<f64>,
    /// The chosen model's held-out image error; `None` when the ladder did not run.
    pub held_out_error: Option<f64>,
    /// Lambert + GGX's held-out error on the same data; `None` when the ladder did not fit it
    /// (and in reports written before it was recorded).
    #[serde(default)]
    pub analytic_held_out_error: Option<f64>,
    /// 10th-90th percentile range of theta_d over the reliable pixels, degrees.
    pub theta_d_span_deg: f64,
    /// Share of the result's environment render from never-observed (theta_h, theta_d) cells.
    pub unseen_energy: f64,
    /// The theta_d band holding most of that share, when the share lowered the verdict
    /// (`None` otherwise, and in reports written before it was recorded).
    #[serde(default)]
    pub unseen_band: Option<UnseenBand>,
}

/// Where in theta_d the unseen share of a render lies: a run of 10-degree theta_d cells, grown
/// from the one holding most of it towards the larger neighbour, one cell at a time, until it
/// holds at least half of it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct UnseenBand {
    /// The band's theta_d range, degrees (`[low, high)`).
    pub theta_d_deg: [f64; 2],
    /// Its share of the unseen part of the render (0 to 1).
    pub share_of_unseen: f64,
}

impl UnseenBand {
    /// What a user can do about it, in words: the light-to-camera angles (as seen from the
    /// object) that observe the band, twice its theta_d.
    pub fn advice(&self) -> String {
        let [lo, hi] = self.theta_d_deg;
        let mut s = format!(
            "{:.0} % of it at theta_d {lo:.0}-{hi:.0} degrees: a light {:.0}-{:.0} degrees from \
             the camera, as seen from the object, observes those angles (light and view are \
             twice theta_d apart)",
            100.0 * self.share_of_unseen,
            2.0 * lo,
            (2.0 * hi).min(180.0)
        );
        if hi > 80.0 {
            s.push_str(
                "; near 180 degrees light and camera face each other and no surface sees both, \
                 so the most grazing angles stay extrapolated",
            );
        }
        s
    }
}

/// Cells of `CELL x CELL` (theta_h, theta_d) bins.
const CELL: usize = 10;

/// The held-out errors the verdict reads: the chosen model's and Lambert + GGX's on the same
/// held-out data.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HeldOut {
    pub chosen: Option<f64>,
    pub analytic: Option<f64>,
}

/// Judges a result: `result` is the reported BRDF (as written), `others` the trials' fits,
/// `reliable` the pixels the fit used, `held_out` the held-out errors.
pub fn assess(
    result: &dyn BinValues,
    others: &[&dyn Candidate],
    reliable: &[&Observation],
    held_out: HeldOut,
    settings: &ConfidenceSettings,
) -> Confidence {
    let probe = probe();
    let values = result.values_at(probe.bins());
    let trial_disagreement = render_disagreement_of(&values, others);

    let mut theta_d: Vec<f64> = reliable
        .iter()
        .map(|o| o.angles.theta_d.to_degrees())
        .collect();
    let theta_d_span_deg = percentile(&mut theta_d, 0.9) - percentile(&mut theta_d, 0.1);

    let unseen_energy = unseen_share(probe, &values, reliable);

    // where the unseen share lies, only when it will lower the verdict (nine more renders)
    let band = (unseen_energy > settings.unseen_energy_medium)
        .then(|| unseen_band(probe, &values, reliable))
        .flatten();

    judge(
        trial_disagreement,
        held_out,
        theta_d_span_deg,
        unseen_energy,
        band,
        settings,
    )
}

/// The verdict from the four indicators (the thresholds of `settings`); also what the
/// threshold tuning of `eval::confidence` replays on recorded indicators. `unseen_band` only
/// adds its advice to the unseen share's reason (and is recorded); it never moves the level.
pub fn judge(
    trial_disagreement: Option<f64>,
    held_out: HeldOut,
    theta_d_span_deg: f64,
    unseen_energy: f64,
    unseen_band: Option<UnseenBand>,
    settings: &ConfidenceSettings,
) -> Confidence {
    let mut level = Level::High;
    let mut reasons = Vec::new();
    let mut judge = |value: f64, medium: bool, low: bool, text: String| {
        if !value.is_finite() {
            return;
        }
        let l = if low {
            Level::Low
        } else if medium {
            Level::Medium
        } else {
            return;
        };
        level = level.min(l);
        reasons.push(format!("{l}: {text}"));
    };
    if let Some(d) = trial_disagreement {
        judge(
            d,
            d > settings.disagreement_medium,
            d > settings.disagreement_low,
            format!(
                "fits to different subsets of the pixels render {:.0} % apart (median \
                 environment-render difference from the result): the pixels do not pin the \
                 BRDF down",
                100.0 * d
            ),
        );
    }
    let held_out_error = held_out.chosen;
    if let Some(h) = held_out_error {
        match held_out.analytic {
            Some(a) if a.is_finite() && h < settings.held_out_shared_ratio * a => judge(
                h,
                h > settings.held_out_medium,
                false,
                format!(
                    "the model misses held-out images by {:.0} %, and Lambert + GGX fitted to \
                     the same pixels by {:.0} %: a miss every model shares (normals too coarse \
                     for a narrow highlight, a wrong light direction or irradiance?), and this \
                     model explains the images best",
                    100.0 * h,
                    100.0 * a
                ),
            ),
            _ => judge(
                h,
                h > settings.held_out_medium,
                h > settings.held_out_low,
                format!(
                    "the model misses held-out images by {:.0} %: no single BRDF seen through \
                     this mesh explains the images (normals too coarse for a narrow highlight, \
                     a wrong light direction or irradiance, a textured or anisotropic surface?)",
                    100.0 * h
                ),
            ),
        }
    }
    judge(
        theta_d_span_deg,
        theta_d_span_deg < settings.theta_d_span_medium_deg,
        theta_d_span_deg < settings.theta_d_span_low_deg,
        format!(
            "the pixels cover theta_d over only {theta_d_span_deg:.0} degrees: the rest of the \
             domain is extrapolated (use more light positions, METHOD.md section 1)"
        ),
    );
    judge(
        unseen_energy,
        unseen_energy > settings.unseen_energy_medium,
        unseen_energy > settings.unseen_energy_low,
        format!(
            "{:.0} % of a render of the result comes from angles no pixel observed{}",
            100.0 * unseen_energy,
            unseen_band.map_or(String::new(), |b| format!("; {}", b.advice()))
        ),
    );
    Confidence {
        level,
        reasons,
        trial_disagreement,
        held_out_error,
        analytic_held_out_error: held_out.analytic,
        theta_d_span_deg,
        unseen_energy,
        unseen_band,
    }
}

/// The (theta_h, theta_d) cells of `CELL` x `CELL` bins some reliable pixel falls in, and the
/// number of theta_d cells (row length).
fn seen_cells(reliable: &[&Observation]) -> (Vec<bool>, usize) {
    let (ch, cd) = (THETA_H_BINS.div_ceil(CELL), THETA_D_BINS.div_ceil(CELL));
    let mut seen = vec![false; ch * cd];
    for o in reliable {
        if let Some(b) = MerlBin::from_index(o.bin) {
            seen[(b.theta_h / CELL) * cd + b.theta_d / CELL] = true;
        }
    }
    (seen, cd)
}

/// `values` (at the probe's bins) kept only in never-observed cells (`seen_cells`; of theta_d
/// cell `cell` alone, when given), zero elsewhere.
fn unseen_values(
    probe: &SphereProbe,
    values: &[[f64; 3]],
    (seen, cd): &(Vec<bool>, usize),
    cell: Option<usize>,
) -> Vec<[f64; 3]> {
    probe
        .bins()
        .iter()
        .zip(values)
        .map(|(&bin, v)| match MerlBin::from_index(bin) {
            Some(b)
                if cell.is_none_or(|c| b.theta_d / CELL == c)
                    && !seen[(b.theta_h / CELL) * cd + b.theta_d / CELL] =>
            {
                *v
            }
            _ => [0.0; 3],
        })
        .collect()
}

/// The energy (sum over pixels and channels) of the probe's environment render.
fn render_energy(probe: &SphereProbe, values: &[[f64; 3]]) -> f64 {
    probe
        .render_values(values)
        .environment
        .iter()
        .flatten()
        .filter(|x| x.is_finite())
        .map(|x| x.max(0.0))
        .sum()
}

/// Where in theta_d the unseen part of the render of `values` lies ([`UnseenBand`]); `None`
/// when nothing of it is unseen. The render is linear in the values, so each theta_d cell's
/// part is the render of the unseen bins of that cell alone.
fn unseen_band(
    probe: &SphereProbe,
    values: &[[f64; 3]],
    reliable: &[&Observation],
) -> Option<UnseenBand> {
    let seen = seen_cells(reliable);
    let per_cell: Vec<f64> = (0..seen.1)
        .map(|cell| {
            let part = unseen_values(probe, values, &seen, Some(cell));
            if part.iter().flatten().any(|x| *x > 0.0) {
                render_energy(probe, &part)
            } else {
                0.0
            }
        })
        .collect();
    let total: f64 = per_cell.iter().sum();
    if !total.is_finite() || total <= 0.0 {
        return None;
    }
    let (mut lo, mut hi) = per_cell
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .map(|(i, _)| (i, i + 1))?;
    let mut held = per_cell[lo];
    while held < 0.5 * total {
        let below = lo.checked_sub(1).map(|i| per_cell[i]);
        let above = per_cell.get(hi).copied();
        match (below, above) {
            (Some(b), Some(a)) if a > b => (hi, held) = (hi + 1, held + a),
            (Some(b), _) => (lo, held) = (lo - 1, held + b),
            (None, Some(a)) => (hi, held) = (hi + 1, held + a),
            (None, None) => break,
        }
    }
    let deg = |cell: usize| (cell * CELL).min(THETA_D_BINS) as f64 * 90.0 / THETA_D_BINS as f64;
    Some(UnseenBand {
        theta_d_deg: [deg(lo), deg(hi)],
        share_of_unseen: held / total,
    })
}

/// The share of `result`'s environment render (the standard probe) that comes from
/// never-observed (theta_h, theta_d) cells of `reliable`.
pub fn unseen_render_share(result: &dyn BinValues, reliable: &[&Observation]) -> f64 {
    let probe = probe();
    unseen_share(probe, &result.values_at(probe.bins()), reliable)
}

/// The share of the environment render of `values` (at the probe's bins) that comes from
/// bins in never-observed (theta_h, theta_d) cells.
fn unseen_share(probe: &SphereProbe, values: &[[f64; 3]], reliable: &[&Observation]) -> f64 {
    let unseen_only = unseen_values(probe, values, &seen_cells(reliable), None);
    let total = render_energy(probe, values);
    let unseen = render_energy(probe, &unseen_only);
    if total > 0.0 { unseen / total } else { 1.0 }
}

/// Nearest-rank percentile (`q` in [0, 1]); NaN for no values.
fn percentile(xs: &mut [f64], q: f64) -> f64 {
    xs.sort_by(f64::total_cmp);
    crate::stats::percentile_sorted(xs, q)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_candidate_at_the_probe_gives_its_own_values_there_and_elsewhere() {
        struct Varied;
        impl Candidate for Varied {
            fn eval_bin(&self, bin: usize) -> [f64; 3] {
                [
                    bin as f64 * 1e-6,
                    (bin % 97) as f64,
                    1.0 / (1 + bin % 13) as f64,
                ]
            }
        }
        let at = AtProbe::new(&Varied);
        let bins = probe().bins();
        assert_eq!(
            CandidateValues(&at).values_at(bins),
            CandidateValues(&Varied).values_at(bins)
        );
        // another slice with the same bins is evaluated, not read from the cache
        let copy = bins.to_vec();
        assert_eq!(at.values_at_bins(&copy), Varied.values_at_bins(&copy));
        let other = [0, 5, 1_000_000];
        assert_eq!(at.values_at_bins(&other), Varied.values_at_bins(&other));
        assert_eq!(at.eval_bin(77), Varied.eval_bin(77));
    }

    struct Const(f64);
    impl Candidate for Const {
        fn eval_bin(&self, _bin: usize) -> [f64; 3] {
            [self.0; 3]
        }
    }

    fn obs(theta_h_deg: f64, theta_d_deg: f64) -> Observation {
        Observation::at_angles(theta_h_deg.to_radians(), theta_d_deg.to_radians(), [1.0; 3])
    }

    /// One pixel per (theta_h, theta_d) degree, theta_h below `h_max`, theta_d over 0-89.
    fn cells(h_max: usize) -> Vec<Observation> {
        (0..h_max)
            .flat_map(|h| (0..90).map(move |d| obs(h as f64, d as f64 * 0.99)))
            .collect()
    }

    /// A constant model's confidence on `obs`: one trial, no held-out figures.
    fn assess_const(value: f64, obs: &[Observation], settings: &ConfidenceSettings) -> Confidence {
        let refs: Vec<&Observation> = obs.iter().collect();
        assess(
            &CandidateValues(&Const(value)),
            &[],
            &refs,
            HeldOut::default(),
            settings,
        )
    }

    #[test]
    fn agreeing_trials_over_a_wide_domain_are_trusted() {
        let obs: Vec<Observation> = cells(90);
        let refs: Vec<&Observation> = obs.iter().collect();
        let (a, b) = (Const(0.3), Const(0.31));
        let c = assess(
            &CandidateValues(&a),
            &[&b],
            &refs,
            HeldOut {
                chosen: Some(0.05),
                analytic: None,
            },
            &ConfidenceSettings::default(),
        );
        assert_eq!(c.level, Level::High, "{c:?}");
        assert!(c.reasons.is_empty());
        // A constant BRDF 0.31 against 0.3 renders 1/30 apart everywhere.
        assert!((c.trial_disagreement.unwrap_or(1.0) - 1.0 / 30.0).abs() < 1e-6);
        assert!(c.unseen_energy < 0.01, "{}", c.unseen_energy);
        assert!(c.theta_d_span_deg > 60.0);
    }

    #[test]
    fn one_theta_d_and_disagreeing_trials_are_low_confidence_with_reasons() {
        let obs: Vec<Observation> = (0..40).map(|h| obs(h as f64, 30.0)).collect();
        let refs: Vec<&Observation> = obs.iter().collect();
        let (a, b, c2) = (Const(0.3), Const(0.6), Const(0.1));
        let c = assess(
            &CandidateValues(&a),
            &[&b, &c2],
            &refs,
            HeldOut {
                chosen: Some(0.7),
                analytic: None,
            },
            &ConfidenceSettings::default(),
        );
        assert_eq!(c.level, Level::Low);
        assert_eq!(c.reasons.len(), 4, "{:?}", c.reasons);
        assert!(c.theta_d_span_deg < 1.5);
        assert!(c.unseen_energy > 0.8, "{}", c.unseen_energy);
        assert!(c.reasons.iter().any(|r| r.contains("theta_d")));
    }

    #[test]
    fn the_unseen_share_names_its_theta_d_band_and_the_lights_that_would_observe_it() {
        // Every theta_h seen, theta_d only below 50 degrees: all the unseen render lies above.
        let obs: Vec<Observation> = (0..90)
            .flat_map(|h| (0..50).map(move |d| obs(h as f64, d as f64)))
            .collect();
        let settings = ConfidenceSettings {
            unseen_energy_medium: 0.0,
            ..ConfidenceSettings::default()
        };
        let c = assess_const(0.3, &obs, &settings);
        assert!(
            c.unseen_energy > 0.0 && c.unseen_energy < 0.9,
            "{}",
            c.unseen_energy
        );
        let band = c
            .unseen_band
            .expect("the share lowered the verdict, so its band is named");
        let [lo, hi] = band.theta_d_deg;
        assert!(lo >= 50.0 && hi > lo && hi <= 90.0, "{band:?}");
        assert!(
            band.share_of_unseen >= 0.5 && band.share_of_unseen <= 1.0,
            "{band:?}"
        );
        let reason = c
            .reasons
            .iter()
            .find(|r| r.contains("comes from angles no pixel observed"))
            .expect("the unseen share's reason");
        let lights = format!(
            "a light {:.0}-{:.0} degrees from the camera",
            2.0 * lo,
            (2.0 * hi).min(180.0)
        );
        assert!(reason.contains(&lights), "{reason}");

        // Seen everywhere: the share stays below the threshold and no band is named.
        let c = assess_const(0.3, &cells(90), &ConfidenceSettings::default());
        assert_eq!(c.unseen_band, None);
        assert!(
            c.reasons
                .iter()
                .all(|r| !r.contains("degrees from the camera"))
        );
    }

    #[test]
    fn a_single_trial_has_no_disagreement_figure() {
        let c = assess_const(0.2, &cells(90), &ConfidenceSettings::default());
        assert_eq!(c.trial_disagreement, None);
        assert_eq!(c.level, Level::High);
    }

    #[test]
    fn a_held_out_miss_every_model_shares_lowers_the_verdict_to_medium_at_most() {
        let obs: Vec<Observation> = cells(40);
        let reliable: Vec<&Observation> = obs.iter().collect();
        let (a, b) = (Const(0.3), Const(0.31));
        let judge_with = |analytic: Option<f64>| {
            assess(
                &CandidateValues(&a),
                &[&b],
                &reliable,
                HeldOut {
                    chosen: Some(0.6),
                    analytic,
                },
                &ConfidenceSettings::default(),
            )
        };
        // missed by 60 % and nothing else known: low
        assert_eq!(judge_with(None).level, Level::Low);
        // Lambert + GGX misses the same images by 95 %: the miss is shared, medium
        let shared = judge_with(Some(0.95));
        assert_eq!(shared.level, Level::Medium, "{:?}", shared.reasons);
        assert!(
            shared
                .reasons
                .iter()
                .any(|r| r.contains("every model shares"))
        );
        assert_eq!(shared.analytic_held_out_error, Some(0.95));
        // Lambert + GGX does about as well (70 %): not clearly better, low
        assert_eq!(judge_with(Some(0.7)).level, Level::Low);
    }
}
