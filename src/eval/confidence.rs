//! Tuning the confidence verdict's thresholds on one half of an accuracy grid and checking it on
//! the other (issue #11, item 4): the verdict is replayed (`reconstruct::confidence::judge`) on
//! the indicators each run recorded, against the level its true rendered error deserves.
//!
//! The level a result deserves, from its environment error `e` (docs/error-metrics.md) and the
//! better analytic baseline's `b` on the same scene: **high** when `e <= 0.10`, or when it beats
//! the baseline by 2x with `e <= 0.20`; **low** when `e > 0.25` and it does not beat the baseline
//! by 2x, or when `e > 0.5`; **medium** otherwise. So a shiny material recovered clearly better
//! than any analytic fit is not "low" merely because its peak was never observed.
//!
//! The search: coordinate descent over the eight thresholds, each tried at the recorded values
//! of its indicator (midpoints between them), minimising a cost that punishes over-confidence
//! twice as much as caution: for each run, `2 x (levels too high)` + `1 x (levels too low)`.
//! Ties keep the current value. Pure: data in, settings and tables out.

use crate::reconstruct::confidence::{ConfidenceSettings, HeldOut, Level, judge};
use serde::Serialize;

/// One run's recorded indicators and its true error.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Run {
    pub label: String,
    /// The group used to split tuning from checking (the mesh).
    pub group: String,
    pub environment: f64,
    /// The better analytic baseline's environment error on the same scene, when known.
    pub baseline: Option<f64>,
    pub trial_disagreement: Option<f64>,
    pub held_out_error: Option<f64>,
    /// Lambert + GGX's held-out error on the same data (from the ladder's rungs when the run
    /// did not record it).
    pub analytic_held_out_error: Option<f64>,
    pub theta_d_span_deg: f64,
    pub unseen_energy: f64,
}

/// The level a run's true error deserves (see the module header).
pub fn deserved(run: &Run) -> Level {
    let e = run.environment;
    let twice_better = run.baseline.is_some_and(|b| b >= 2.0 * e);
    if e <= 0.10 || (twice_better && e <= 0.20) {
        Level::High
    } else if e > 0.5 || (e > 0.25 && !twice_better) {
        Level::Low
    } else {
        Level::Medium
    }
}

/// The verdict the settings give a run.
pub fn verdict(run: &Run, s: &ConfidenceSettings) -> Level {
    judge(
        run.trial_disagreement,
        HeldOut {
            chosen: run.held_out_error,
            analytic: run.analytic_held_out_error,
        },
        run.theta_d_span_deg,
        run.unseen_energy,
        None,
        s,
    )
    .level
}

fn rank(l: Level) -> i32 {
    match l {
        Level::Low => 0,
        Level::Medium => 1,
        Level::High => 2,
    }
}

/// The tuning cost of the settings over runs (see the module header).
pub fn cost(runs: &[Run], s: &ConfidenceSettings) -> f64 {
    runs.iter()
        .map(|r| {
            let d = rank(verdict(r, s)) - rank(deserved(r));
            if d > 0 { 2.0 * d as f64 } else { -d as f64 }
        })
        .sum()
}

/// Sets the i-th of the eight thresholds (medium, low per indicator).
fn set(s: &mut ConfidenceSettings, i: usize, v: f64) {
    match i {
        0 => s.disagreement_medium = v,
        1 => s.disagreement_low = v,
        2 => s.held_out_medium = v,
        3 => s.held_out_low = v,
        4 => s.theta_d_span_medium_deg = v,
        5 => s.theta_d_span_low_deg = v,
        6 => s.unseen_energy_medium = v,
        _ => s.unseen_energy_low = v,
    }
}

/// The recorded values of the indicator a threshold reads.
fn values(runs: &[Run], i: usize) -> Vec<f64> {
    let mut v: Vec<f64> = runs
        .iter()
        .filter_map(|r| match i / 2 {
            0 => r.trial_disagreement,
            1 => r.held_out_error,
            2 => Some(r.theta_d_span_deg),
            _ => Some(r.unseen_energy),
        })
        .filter(|x| x.is_finite())
        .collect();
    v.sort_by(f64::total_cmp);
    v.dedup();
    v
}

/// Whether the medium and low thresholds of an indicator are in order (low is the stricter
/// one: larger for the "above" indicators, smaller for the theta_d span).
fn ordered(s: &ConfidenceSettings) -> bool {
    s.disagreement_low >= s.disagreement_medium
        && s.held_out_low >= s.held_out_medium
        && s.theta_d_span_low_deg <= s.theta_d_span_medium_deg
        && s.unseen_energy_low >= s.unseen_energy_medium
}

/// Tunes the thresholds on `runs`, from `start`.
pub fn tune(runs: &[Run], start: &ConfidenceSettings) -> ConfidenceSettings {
    let mut best = *start;
    let mut best_cost = cost(runs, &best);
    for _pass in 0..6 {
        let before = best_cost;
        for i in 0..8 {
            let v = values(runs, i);
            // Candidates: between consecutive recorded values, and beyond both ends (an
            // indicator that never fires).
            let mut cands: Vec<f64> = v.windows(2).map(|w| 0.5 * (w[0] + w[1])).collect();
            if let (Some(lo), Some(hi)) = (v.first(), v.last()) {
                cands.push(lo * 0.5 - 1e-9);
                cands.push(hi * 2.0 + 1.0);
            }
            for c in cands {
                let mut s = best;
                set(&mut s, i, c);
                if !ordered(&s) {
                    continue;
                }
                let k = cost(runs, &s);
                if k < best_cost {
                    best = s;
                    best_cost = k;
                }
            }
        }
        if best_cost >= before {
            break;
        }
    }
    best
}

/// What is missing from an accuracy grid's JSON.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GridJsonError {
    #[error("no \"scenes\" array")]
    NoScenes,
    #[error("scenes[{scene}]: no {field}")]
    Missing { scene: usize, field: &'static str },
}

/// The runs of an accuracy grid's JSON (`bench accuracy`, `accuracy.json`): the full pipeline
/// ("all three assumptions") of every scene that produced a result. Errors name the scene and
/// the field.
pub fn runs_from_accuracy_json(v: &serde_json::Value) -> Result<Vec<Run>, GridJsonError> {
    let scenes = v
        .get("scenes")
        .and_then(|s| s.as_array())
        .ok_or(GridJsonError::NoScenes)?;
    let f = |x: &serde_json::Value, k: &str| x.get(k).and_then(serde_json::Value::as_f64);
    let mut out = Vec::new();
    for (i, sc) in scenes.iter().enumerate() {
        let name = |k: &str| {
            sc.get(k)
                .map(|x| x.as_str().map_or_else(|| x.to_string(), str::to_string))
                .unwrap_or_default()
        };
        let label = format!(
            "{} {} {} seed {}",
            name("mesh"),
            name("material"),
            sc.get("rig").map(|r| r.to_string()).unwrap_or_default(),
            name("seed")
        );
        let variants =
            sc.get("variants")
                .and_then(|x| x.as_array())
                .ok_or(GridJsonError::Missing {
                    scene: i,
                    field: "\"variants\"",
                })?;
        // The full pipeline: the variant with all three assumptions on.
        let all = variants.iter().find(|p| {
            p.get(0).is_some_and(|v| {
                ["curvature", "monotonicity", "brightest"]
                    .iter()
                    .all(|k| v.get(k).and_then(serde_json::Value::as_bool) == Some(true))
            })
        });
        let Some(ok) = all.and_then(|p| p.get(1)).and_then(|r| r.get("Ok")) else {
            continue;
        };
        let environment =
            ok.get("chosen")
                .and_then(|c| f(c, "environment"))
                .ok_or(GridJsonError::Missing {
                    scene: i,
                    field: "chosen.environment",
                })?;
        let c = ok.get("confidence").ok_or(GridJsonError::Missing {
            scene: i,
            field: "confidence",
        })?;
        let baseline = ["lambert", "lambert_ggx"]
            .iter()
            .filter_map(|k| sc.get(*k).and_then(|e| f(e, "environment")))
            .fold(None, |acc: Option<f64>, x| {
                Some(acc.map_or(x, |a| a.min(x)))
            });
        // Lambert + GGX's held-out error: recorded by the confidence since session 25, else
        // the ladder's rung of that family.
        let analytic_held_out_error = f(c, "analytic_held_out_error").or_else(|| {
            ok.get("ladder")
                .and_then(|l| l.get("rungs"))
                .and_then(|r| r.as_array())
                .and_then(|rungs| {
                    rungs
                        .iter()
                        .find(|r| r.get("family").and_then(|x| x.as_str()) == Some("lambert-ggx"))
                })
                .and_then(|r| f(r, "error"))
        });
        out.push(Run {
            label,
            group: name("mesh"),
            environment,
            baseline,
            trial_disagreement: f(c, "trial_disagreement"),
            held_out_error: f(c, "held_out_error"),
            analytic_held_out_error,
            theta_d_span_deg: f(c, "theta_d_span_deg").ok_or(GridJsonError::Missing {
                scene: i,
                field: "confidence.theta_d_span_deg",
            })?,
            unseen_energy: f(c, "unseen_energy").ok_or(GridJsonError::Missing {
                scene: i,
                field: "confidence.unseen_energy",
            })?,
        });
    }
    Ok(out)
}

/// Per verdict level: runs, and the mean / median / max true environment error.
pub fn table(runs: &[Run], s: &ConfidenceSettings) -> String {
    let mut out = "| verdict | runs | env mean | env median | env max | deserved high / medium / low |\n|---|---|---|---|---|---|\n".to_string();
    for level in [Level::High, Level::Medium, Level::Low] {
        let mut e: Vec<f64> = runs
            .iter()
            .filter(|r| verdict(r, s) == level)
            .map(|r| r.environment)
            .collect();
        if e.is_empty() {
            out += &format!("| {level} | 0 | - | - | - | - |\n");
            continue;
        }
        let deserved_counts = [Level::High, Level::Medium, Level::Low].map(|d| {
            runs.iter()
                .filter(|r| verdict(r, s) == level && deserved(r) == d)
                .count()
        });
        e.sort_by(f64::total_cmp);
        out += &format!(
            "| {level} | {} | {:.3} | {:.3} | {:.3} | {} / {} / {} |\n",
            e.len(),
            e.iter().sum::<f64>() / e.len() as f64,
            e[e.len() / 2],
            e[e.len() - 1],
            deserved_counts[0],
            deserved_counts[1],
            deserved_counts[2]
        );
    }
    out
}

/// The thresholds as a markdown table.
pub fn settings_table(s: &ConfidenceSettings) -> String {
    format!(
        "| indicator | medium when | low when |\n|---|---|---|\n\
         | trial disagreement (rendered) | > {:.3} | > {:.3} |\n\
         | held-out image error | > {:.3} | > {:.3}, unless below {:.2} x Lambert + GGX's (then medium at most) |\n\
         | theta_d span, degrees | < {:.1} | < {:.1} |\n\
         | unseen share of the render | > {:.3} | > {:.3} |\n",
        s.disagreement_medium,
        s.disagreement_low,
        s.held_out_medium,
        s.held_out_low,
        s.held_out_shared_ratio,
        s.theta_d_span_medium_deg,
        s.theta_d_span_low_deg,
        s.unseen_energy_medium,
        s.unseen_energy_low
    )
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_grid_file_without_a_field_names_the_scene_and_the_field() {
        assert_eq!(
            super::runs_from_accuracy_json(&serde_json::json!({})).unwrap_err(),
            super::GridJsonError::NoScenes
        );
        let e =
            super::runs_from_accuracy_json(&serde_json::json!({"scenes": [{}, {}]})).unwrap_err();
        assert_eq!(e.to_string(), "scenes[0]: no \"variants\"");
    }

    use super::*;

    fn run(env: f64, disagreement: f64) -> Run {
        Run {
            label: String::new(),
            group: String::new(),
            environment: env,
            baseline: None,
            trial_disagreement: Some(disagreement),
            held_out_error: Some(0.01),
            analytic_held_out_error: None,
            theta_d_span_deg: 60.0,
            unseen_energy: 0.0,
        }
    }

    #[test]
    fn the_deserved_level_follows_the_error_and_the_margin_over_the_baseline() {
        assert_eq!(deserved(&run(0.05, 0.0)), Level::High);
        assert_eq!(deserved(&run(0.2, 0.0)), Level::Medium);
        assert_eq!(deserved(&run(0.4, 0.0)), Level::Low);
        let mut shiny = run(0.18, 0.0);
        shiny.baseline = Some(0.5);
        assert_eq!(deserved(&shiny), Level::High);
        // Beating the baseline by 2x lifts a 0.3 error from low to medium, not further.
        shiny.environment = 0.3;
        assert_eq!(deserved(&shiny), Level::Low);
        shiny.baseline = Some(0.7);
        assert_eq!(deserved(&shiny), Level::Medium);
    }

    #[test]
    fn tuning_finds_the_thresholds_that_separate_an_indicator_that_tracks_the_error() {
        // The disagreement is the error divided by two: perfectly informative.
        let runs: Vec<Run> = (1..60)
            .map(|i| {
                let e = i as f64 / 60.0;
                run(e, e / 2.0)
            })
            .collect();
        let start = ConfidenceSettings {
            disagreement_medium: 10.0,
            disagreement_low: 10.0,
            ..Default::default()
        };
        assert!(cost(&runs, &start) > 0.0);
        let tuned = tune(&runs, &start);
        assert_eq!(cost(&runs, &tuned), 0.0, "{tuned:?}");
        assert!((tuned.disagreement_medium - 0.05).abs() < 0.01, "{tuned:?}");
        assert!((tuned.disagreement_low - 0.125).abs() < 0.01, "{tuned:?}");
        let t = table(&runs, &tuned);
        assert!(t.contains("| high |"), "{t}");
    }
}
