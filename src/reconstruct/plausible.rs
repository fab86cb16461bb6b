//! A physically plausible table from a fitted model: where no pixel observed a
//! (theta_h, theta_d) region the result shrinks towards a prior model instead of extrapolating
//! freely; every value is non-negative; the directional albedo is at most 1 for every incident
//! direction. Checked, enforced, and reported.
//!
//! - **Coverage**: observed pixels are counted per (theta_h bin, theta_d bin) of the MERL grid.
//!   A cell's distance `d` to the nearest observed cell is measured in bins (theta_h in MERL's
//!   square-root index, theta_d in degrees); its weight is `w = exp(-d^2 / (2 L^2))` with the
//!   shrink length `L` (bins). Every bin of the cell becomes `w f_model + (1 - w) g`, where `g`
//!   is the model clamped to within a factor `R` of the prior (`[f_prior / R, R f_prior]` per
//!   channel): the model's shape survives where it stays near the prior, a free extrapolation
//!   that runs away (the basis can put 100 times the energy in a bin no pixel saw) is pulled
//!   back; `R = 1` replaces unobserved regions by the prior. An observed cell keeps the model
//!   (`w = 1`). The prior is an analytic model fitted to the same pixels (Lambert + GGX):
//!   physically shaped where the data say nothing, and at the data's scale. With
//!   [`ThetaDShape::Prior`] or [`ThetaDShape::Basis`] the model's value at an unobserved cell is
//!   replaced, before the clamp, by the model at the nearest observed theta_d of the same
//!   theta_h column times that shape's ratio between the two cells (a study option, measured in
//!   docs/evaluation.md section 1k).
//! - **Non-negative**: negative and non-finite values become the prior's (negative entries mean
//!   "no data" in a MERL file, and a BRDF is never negative).
//! - **Albedo**: `a(theta_i) = int f(wi, wo) cos theta_o d omega_o`, by the half-vector
//!   quadrature of `render::probe` (theta_h at the 90 MERL bin centres, `phi_h` in 48 steps, `wo`
//!   the mirror of `wi` about `h`, `d omega_o = 4 (wi . h) d omega_h`), at the centres of the 90
//!   theta bins. Where `a > 1` the scale `s(theta) = 1 / a(theta)` applies, and every bin is scaled
//!   by `min(s(theta_i), s(theta_o))` at its centre (symmetric, so reciprocity holds; each
//!   incident direction's albedo drops at least to 1). Repeated while any `a > 1` remains (at most
//!   a few passes: bin-centre angles are quantised).
//!
//! Pure: no I/O.

use super::observe::Observation;
use super::prior::Candidate;
use crate::brdf::coords::{MERL_BINS, MerlBin, THETA_D_BINS, THETA_H_BINS, merl_index};
use crate::brdf::merl::MerlTable;
use nalgebra::Vector3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::f64::consts::FRAC_PI_2;
use std::sync::OnceLock;

/// Knobs of the plausibility step.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlausibleSettings {
    /// Shrink unobserved regions towards the prior.
    pub shrink: bool,
    /// The shrink length L, in bins (see the module header).
    pub shrink_length_bins: f64,
    /// R: how far (a factor) the model may stray from the prior where nothing was observed.
    pub prior_ratio_limit: f64,
    /// A cell counts as observed with at least this many pixels.
    pub min_pixels_per_cell: usize,
    /// The largest directional albedo allowed.
    pub max_albedo: f64,
    /// Where a cell is unobserved, what it starts from (see [`ThetaDShape`]).
    #[serde(default)]
    pub theta_d_shape: ThetaDShape,
}

/// Where an unobserved cell starts from before the clamp and blend towards the prior.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ThetaDShape {
    /// The model's own extrapolation.
    #[default]
    Model,
    /// The model at the nearest observed theta_d of the same theta_h column, scaled by the
    /// prior's ratio between the two cells (the data's theta_h shape, the prior's theta_d
    /// shape).
    Prior,
    /// The same, scaled by the ratio of the basis's typical material (its mean, all
    /// coefficients zero): the theta_d shape the measured materials share.
    Basis,
}

impl ThetaDShape {
    /// The name the command line takes (`--unobserved`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Model => "model",
            Self::Prior => "transfer",
            Self::Basis => "transfer-basis",
        }
    }
}

impl Default for PlausibleSettings {
    fn default() -> Self {
        Self {
            shrink: true,
            shrink_length_bins: 6.0,
            prior_ratio_limit: 10.0,
            min_pixels_per_cell: 1,
            max_albedo: 1.0,
            theta_d_shape: ThetaDShape::Model,
        }
    }
}

/// What the step found and did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plausibility {
    /// (theta_h, theta_d) cells with at least one observed pixel, of 90 x 90.
    pub observed_cells: usize,
    /// Share of the table's bins (above the horizon) whose value comes mostly from the prior
    /// (weight below one half).
    pub prior_share: f64,
    /// Bins that were negative or not finite, replaced by the prior.
    pub invalid_bins: usize,
    /// The largest directional albedo before and after enforcement.
    pub max_albedo_before: f64,
    pub max_albedo_after: f64,
    /// The incident angle of the largest albedo before enforcement, degrees.
    pub max_albedo_theta_deg: f64,
    /// Bins scaled down to keep the albedo at most `max_albedo`.
    pub scaled_bins: usize,
    /// What the prior was.
    pub prior: String,
    /// The model averaging with Lambert + GGX after this step, where it was made
    /// (`reconstruct::hedge`; absent in reports written before it existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hedge: Option<super::hedge::Hedge>,
    /// The weight of the basis + peak table averaged (geometrically) into the basis's, where
    /// the held-out images could not tell them apart (`CoreSettings::peak_average`; absent
    /// where it was not done and in reports written before it existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub peak_average: Option<f64>,
    /// How many basis rungs were averaged into the written table, the chosen one included
    /// (`CoreSettings::rung_average`; absent where it was not done and in reports written
    /// before it existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rung_average: Option<usize>,
    /// The carried value's weight in the grazing peak cells (`reconstruct::grazing`; absent
    /// where it was not done and in reports written before it existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grazing_transfer: Option<f64>,
    /// The peak's cells scaled to the images' patch sums (`reconstruct::peak_energy`, a study
    /// knob), when it ran.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub peak_energy: Option<super::peak_energy::PeakEnergy>,
    /// How each family extrapolated from the pixels below a theta_d split to those above it
    /// (`reconstruct::extrapolation`; empty where it was not run, and in reports written
    /// before it existed).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub extrapolation: Vec<super::extrapolation::Extrapolation>,
}

/// Pixels per (theta_h bin, theta_d bin), row-major in theta_h.
pub fn coverage(obs: &[&Observation]) -> Vec<usize> {
    let mut counts = vec![0usize; THETA_H_BINS * THETA_D_BINS];
    for o in obs {
        if let Some(b) = MerlBin::from_index(o.bin) {
            counts[b.theta_h * THETA_D_BINS + b.theta_d] += 1;
        }
    }
    counts
}

/// The model's weight per (theta_h, theta_d) cell (see the module header).
pub fn model_weights(counts: &[usize], settings: &PlausibleSettings) -> Vec<f64> {
    let observed: Vec<(f64, f64)> = counts
        .iter()
        .enumerate()
        .filter(|(_, c)| **c >= settings.min_pixels_per_cell.max(1))
        .map(|(i, _)| ((i / THETA_D_BINS) as f64, (i % THETA_D_BINS) as f64))
        .collect();
    let l2 = 2.0 * settings.shrink_length_bins.max(1e-9).powi(2);
    (0..THETA_H_BINS * THETA_D_BINS)
        .into_par_iter()
        .map(|i| {
            let (h, d) = ((i / THETA_D_BINS) as f64, (i % THETA_D_BINS) as f64);
            let d2 = observed
                .iter()
                .map(|(oh, od)| (oh - h).powi(2) + (od - d).powi(2))
                .fold(f64::INFINITY, f64::min);
            if d2.is_finite() {
                (-d2 / l2).exp()
            } else {
                0.0
            }
        })
        .collect()
}

/// Directional albedo of a table for an incident direction at `theta_i` (see the module
/// header). Bins without data count as zero.
pub fn directional_albedo(table: &MerlTable, theta_i: f64) -> [f64; 3] {
    albedo_sum(table, &albedo_pairs(theta_i))
}

/// The albedo quadrature at `theta_i` as `(MERL index, cos theta_o d omega_o)`: the same for
/// every table.
fn albedo_pairs(theta_i: f64) -> Vec<(usize, f64)> {
    let wi = Vector3::new(theta_i.sin(), 0.0, theta_i.cos());
    crate::render::probe::mirror_quadrature(&wi, 48)
        .into_iter()
        .map(|(wo, d_omega_o)| (merl_index(&wi, &wo), wo.z * d_omega_o))
        .collect()
}

/// `sum f w` over the quadrature `pairs`, per channel; bins without data count as zero.
fn albedo_sum(table: &MerlTable, pairs: &[(usize, f64)]) -> [f64; 3] {
    let mut a = [0.0; 3];
    for &(index, w) in pairs {
        if let Some(f) = table.get(index) {
            for c in 0..3 {
                a[c] += f[c] * w;
            }
        }
    }
    a
}

/// [`albedo_pairs`] at the centre of each of the 90 theta bins, computed once per process (the
/// half vectors' MERL indices were most of an albedo curve's cost, and a reconstruction
/// computes one or more curves per material). Made serially: no parallel work inside a
/// `OnceLock`'s initialiser (see `SphereProbe::standard_serial`).
fn albedo_quadrature() -> &'static [Vec<(usize, f64)>] {
    static QUADRATURE: OnceLock<Vec<Vec<(usize, f64)>>> = OnceLock::new();
    QUADRATURE.get_or_init(|| {
        (0..THETA_D_BINS)
            .map(|i| albedo_pairs((i as f64 + 0.5) / THETA_D_BINS as f64 * FRAC_PI_2))
            .collect()
    })
}

/// The largest channel albedo at the centre of each of the 90 theta bins.
pub fn albedo_curve(table: &MerlTable) -> Vec<f64> {
    albedo_quadrature()
        .par_iter()
        .map(|pairs| albedo_sum(table, pairs).into_iter().fold(0.0, f64::max))
        .collect()
}

fn theta_bin(theta: f64) -> usize {
    ((theta / FRAC_PI_2 * THETA_D_BINS as f64).floor().max(0.0) as usize).min(THETA_D_BINS - 1)
}

/// Makes a plausible table from a model, a prior and the pixels the model was fitted to.
pub fn make_plausible(
    model: &dyn Candidate,
    prior: Option<(&dyn Candidate, &str)>,
    used: &[&Observation],
    settings: &PlausibleSettings,
) -> (MerlTable, Plausibility) {
    make_plausible_shaped(model, prior, None, used, settings)
}

/// [`make_plausible`], with the basis's typical material for `ThetaDShape::Basis` (without
/// it that setting keeps the model's own extrapolation).
pub fn make_plausible_shaped(
    model: &dyn Candidate,
    prior: Option<(&dyn Candidate, &str)>,
    typical: Option<&dyn Candidate>,
    used: &[&Observation],
    settings: &PlausibleSettings,
) -> (MerlTable, Plausibility) {
    let counts = coverage(used);
    let weights = match prior {
        Some(_) if settings.shrink => model_weights(&counts, settings),
        _ => vec![1.0; counts.len()],
    };
    // Per theta_h column, the observed theta_d bins: an unobserved cell takes the model at the
    // nearest of them, carried to its own theta_d by the shape's ratio.
    let shape: Option<&dyn Candidate> = match settings.theta_d_shape {
        ThetaDShape::Model => None,
        ThetaDShape::Prior => prior.map(|(p, _)| p),
        ThetaDShape::Basis => typical,
    };
    let observed_d: Vec<Vec<usize>> = (0..THETA_H_BINS)
        .map(|h| {
            (0..THETA_D_BINS)
                .filter(|&d| counts[h * THETA_D_BINS + d] >= settings.min_pixels_per_cell.max(1))
                .collect()
        })
        .collect();
    // Counted as the bins are made: [above the horizon, invalid, mostly the prior's].
    let mut table = MerlTable::zeros();
    let [above, invalid_bins, from_prior] = table.update_counting(|index, _| {
        let Some(b) = MerlBin::from_index(index).filter(MerlBin::is_above_horizon) else {
            return (None, [0; 3]);
        };
        let w = weights[b.theta_h * THETA_D_BINS + b.theta_d];
        let m = model.eval_bin(index);
        let p = prior.map(|(p, _)| p.eval_bin(index));
        let valid = |v: &[f64; 3]| v.iter().all(|x| x.is_finite() && *x >= 0.0);
        let invalid = !valid(&m);
        let m = if invalid {
            match p {
                Some(p) if valid(&p) => p,
                _ => m.map(|x| if x.is_finite() { x.max(0.0) } else { 0.0 }),
            }
        } else {
            m
        };
        let r = settings.prior_ratio_limit.max(1.0);
        // The model where it was seen, carried along theta_d as the prior changes.
        let carried = match (shape, p) {
            (Some(pr), Some(_)) if w < 1.0 => observed_d[b.theta_h]
                .iter()
                .min_by_key(|&&d| d.abs_diff(b.theta_d))
                .map(|&d| MerlBin { theta_d: d, ..b })
                .filter(|s| s.is_above_horizon())
                .and_then(|s| {
                    let (ms, ps) = (model.eval_bin(s.index()), pr.eval_bin(s.index()));
                    let pc = pr.eval_bin(index);
                    let positive = |v: &[f64; 3]| v.iter().all(|x| x.is_finite() && *x > 0.0);
                    (valid(&ms) && positive(&ps) && positive(&pc))
                        .then(|| [0, 1, 2].map(|c| ms[c] * pc[c] / ps[c]))
                }),
            _ => None,
        };
        let v = match p {
            Some(p) if w < 1.0 && valid(&p) => [0, 1, 2].map(|c| {
                let g = carried.map_or(m[c], |t| t[c]).clamp(p[c] / r, p[c] * r);
                w * m[c] + (1.0 - w) * g
            }),
            _ => m,
        };
        (Some(v), [1, usize::from(invalid), usize::from(w < 0.5)])
    });

    let before = albedo_curve(&table);
    let (max_before, arg) =
        before.iter().enumerate().fold(
            (0.0f64, 0usize),
            |acc, (i, &a)| if a > acc.0 { (a, i) } else { acc },
        );
    let (curve, scaled) = cap_albedo(&mut table, before, settings.max_albedo);
    let report = Plausibility {
        observed_cells: counts.iter().filter(|&&c| c > 0).count(),
        prior_share: if above > 0 {
            from_prior as f64 / above as f64
        } else {
            0.0
        },
        invalid_bins,
        max_albedo_before: max_before,
        max_albedo_after: curve.iter().copied().fold(0.0, f64::max),
        max_albedo_theta_deg: (arg as f64 + 0.5) / THETA_D_BINS as f64 * 90.0,
        scaled_bins: scaled.iter().filter(|s| **s).count(),
        prior: prior.map_or_else(|| "none".to_string(), |(_, name)| name.to_string()),
        hedge: None,
        peak_average: None,
        rung_average: None,
        grazing_transfer: None,
        peak_energy: None,
        extrapolation: Vec::new(),
    };
    (table, report)
}

/// Scales the table down, per incident and outgoing theta, until its directional albedo is at
/// most `max_albedo` everywhere (at most four passes; `curve`: its albedo curve now). Returns
/// the final curve and, per bin, whether it was scaled.
pub fn cap_albedo(
    table: &mut MerlTable,
    curve: Vec<f64>,
    max_albedo: f64,
) -> (Vec<f64>, Vec<bool>) {
    let mut curve = curve;
    let mut scaled = vec![false; MERL_BINS];
    for _ in 0..4 {
        if curve.iter().all(|&a| a <= max_albedo) {
            break;
        }
        let s: Vec<f64> = curve
            .iter()
            .map(|&a| {
                if a > max_albedo {
                    max_albedo / a * 0.999
                } else {
                    1.0
                }
            })
            .collect();
        let now = table.scale_down(|index| {
            MerlBin::from_index(index).map_or(1.0, |b| {
                let (wi, wo) = b.centre_directions();
                s[theta_bin(wi.z.clamp(-1.0, 1.0).acos())]
                    .min(s[theta_bin(wo.z.clamp(-1.0, 1.0).acos())])
            })
        });
        for (was, now) in scaled.iter_mut().zip(now) {
            *was |= now;
        }
        curve = albedo_curve(table);
    }
    (curve, scaled)
}

#[cfg(test)]
mod tests {
    use super::super::ladder::AnalyticCandidate;
    use super::*;
    use crate::brdf::analytic::{Lambert, LambertGgx};
    use std::f64::consts::PI;

    struct Const([f64; 3]);
    impl Candidate for Const {
        fn eval_bin(&self, _: usize) -> [f64; 3] {
            self.0
        }
    }

    #[test]
    fn the_albedo_of_a_lambertian_table_is_its_albedo_at_every_angle() {
        let table = MerlTable::tabulate(&Lambert {
            albedo: [0.2, 0.5, 0.9],
        });
        for theta in [0.05, 0.5, 1.0, 1.4] {
            let a = directional_albedo(&table, theta);
            for (got, want) in a.iter().zip([0.2, 0.5, 0.9]) {
                assert!((got - want).abs() < 0.02 * want, "{theta}: {a:?}");
            }
        }
    }

    #[test]
    fn the_albedo_curve_is_the_directional_albedo_at_the_bin_centres() {
        let t = MerlTable::tabulate(&LambertGgx {
            kd: [0.3, 0.6, 0.15],
            ks: [1.0, 0.5, 0.0],
            alpha: 0.2,
            f0: 0.04,
        });
        let curve = albedo_curve(&t);
        assert_eq!(curve.len(), THETA_D_BINS);
        for (i, a) in curve.iter().enumerate() {
            let theta = (i as f64 + 0.5) / THETA_D_BINS as f64 * FRAC_PI_2;
            let d = directional_albedo(&t, theta);
            assert_eq!(*a, d.into_iter().fold(0.0, f64::max), "theta bin {i}");
        }
    }

    #[test]
    fn too_bright_tables_are_scaled_to_albedo_one_and_plausible_ones_are_untouched() {
        // 0.5 / pi per bin: albedo 0.5, nothing to do.
        let ok = Const([0.5 / PI; 3]);
        let (t, r) = make_plausible(&ok, None, &[], &PlausibleSettings::default());
        assert_eq!(r.scaled_bins, 0);
        assert!((r.max_albedo_before - 0.5).abs() < 0.02, "{r:?}");
        let some = MerlBin {
            theta_h: 20,
            theta_d: 30,
            phi_d: 40,
        };
        let v = t.get(some.index()).expect("above the horizon");
        assert!((v[0] - 0.5 / PI).abs() < 1e-12, "{v:?}");
        // A bright GGX lobe: albedo above one near grazing incidence.
        let hot = AnalyticCandidate(LambertGgx {
            kd: [0.6; 3],
            ks: [2.0; 3],
            alpha: 0.2,
            f0: 0.9,
        });
        let (t, r) = make_plausible(&hot, None, &[], &PlausibleSettings::default());
        assert!(r.max_albedo_before > 1.2, "{r:?}");
        assert!(r.max_albedo_after <= 1.0, "{r:?}");
        assert!(r.scaled_bins > 0);
        for theta in [0.1, 0.7, 1.2, 1.5] {
            let a = directional_albedo(&t, theta);
            assert!(a.iter().all(|x| *x <= 1.0 + 1e-9), "{theta}: {a:?}");
        }
        // Reciprocity: the scale of a bin depends on both angles symmetrically, so f(wi, wo)
        // and f(wo, wi) (same bin after phi_d folding) stay equal: checked on the table's
        // construction; here, nothing negative appeared.
        assert!(
            (0..MERL_BINS)
                .step_by(97)
                .all(|i| t.get(i).is_none_or(|v| v.iter().all(|x| *x >= 0.0)))
        );
    }

    #[test]
    fn unobserved_regions_shrink_to_the_prior_and_observed_ones_keep_the_model() {
        use crate::reconstruct::observation::{Observation, Seen};
        // Pixels only at theta_d ~ 10 degrees (one light near the camera).
        let l = Vector3::new(0.17, 0.0, 0.985).normalize();
        let v = Vector3::z();
        let obs: Vec<Observation> = (0..300)
            .filter_map(|i| {
                let a = i as f64 * 2.399;
                let r = 0.9 * ((i as f64 + 0.5) / 300.0).sqrt();
                let n = Vector3::new(r * a.cos(), r * a.sin(), 1.0).normalize();
                Observation::new(Seen::pixel(0, i, 0, n), l, v, [0.1; 3], [1.0; 3])
            })
            .collect();
        let used: Vec<&Observation> = obs.iter().collect();
        // A model that extrapolates wildly (100x) and a sane prior.
        let model = Const([10.0; 3]);
        let prior = Const([0.1; 3]);
        let (t, r) = make_plausible(
            &model,
            Some((&prior, "test prior")),
            &used,
            &PlausibleSettings {
                max_albedo: f64::INFINITY,
                theta_d_shape: ThetaDShape::Model,
                ..Default::default()
            },
        );
        assert!(r.prior_share > 0.5, "{r:?}");
        // An observed bin keeps the model.
        let seen = obs[10].bin;
        assert!((t.get(seen).unwrap()[0] - 10.0).abs() < 1e-9);
        // A bin at theta_d = 60 degrees, far from any observation, is held within R (10) of
        // the prior: the 100x extrapolation becomes 10x.
        let far = MerlBin {
            theta_h: 20,
            theta_d: 60,
            phi_d: 30,
        };
        assert!((t.get(far.index()).unwrap()[0] - 1.0).abs() < 1e-6);
        // R = 1 replaces it by the prior.
        let (t1, _) = make_plausible(
            &model,
            Some((&prior, "test prior")),
            &used,
            &PlausibleSettings {
                prior_ratio_limit: 1.0,
                max_albedo: f64::INFINITY,
                ..Default::default()
            },
        );
        assert!((t1.get(far.index()).unwrap()[0] - 0.1).abs() < 1e-6);
        // With shrinking off, the model stays everywhere.
        let (t2, _) = make_plausible(
            &model,
            Some((&prior, "test prior")),
            &used,
            &PlausibleSettings {
                shrink: false,
                max_albedo: f64::INFINITY,
                ..Default::default()
            },
        );
        assert!((t2.get(far.index()).unwrap()[0] - 10.0).abs() < 1e-9);
    }

    /// f = `f(theta_h bin, theta_d bin)` on every channel.
    struct ByBin(fn(usize, usize) -> f64);
    impl Candidate for ByBin {
        fn eval_bin(&self, bin: usize) -> [f64; 3] {
            let b = MerlBin::from_index(bin).expect("a MERL bin");
            [(self.0)(b.theta_h, b.theta_d); 3]
        }
    }

    #[test]
    fn unobserved_theta_d_takes_the_seen_theta_h_shape_and_the_priors_theta_d_shape() {
        use crate::reconstruct::observation::{Observation, Seen};
        // One light near the camera: every pixel at theta_d ~ 10 degrees.
        let l = Vector3::new(0.17, 0.0, 0.985).normalize();
        let v = Vector3::z();
        let obs: Vec<Observation> = (0..400)
            .filter_map(|i| {
                let a = i as f64 * 2.399;
                let r = 0.9 * ((i as f64 + 0.5) / 400.0).sqrt();
                let n = Vector3::new(r * a.cos(), r * a.sin(), 1.0).normalize();
                Observation::new(Seen::pixel(0, i, 0, n), l, v, [0.1; 3], [1.0; 3])
            })
            .collect();
        let used: Vec<&Observation> = obs.iter().collect();
        let seen_d = MerlBin::from_index(obs[0].bin).unwrap().theta_d;
        assert!(obs.iter().all(|o| {
            let b = MerlBin::from_index(o.bin).unwrap();
            b.theta_d.abs_diff(seen_d) <= 1
        }));
        // The model: a theta_h shape where it was seen, a runaway in theta_d elsewhere. The
        // prior: its own theta_h shape, and a theta_d shape (brighter towards grazing).
        let model = ByBin(|h, d| (0.2 + 0.01 * h as f64) * (1.0 + (d as f64 - 5.0).abs()));
        let prior = ByBin(|h, d| (0.3 - 0.002 * h as f64) * (1.0 + d as f64 / 30.0));
        let settings = PlausibleSettings {
            max_albedo: f64::INFINITY,
            theta_d_shape: ThetaDShape::Prior,
            ..Default::default()
        };
        let (t, _) = make_plausible(&model, Some((&prior, "test prior")), &used, &settings);
        // A cell at theta_d = 60 degrees whose theta_h column was seen: the model's value at
        // the seen theta_d, times the prior's ratio between the two theta_d.
        let h = MerlBin::from_index(obs[50].bin).unwrap().theta_h;
        let column: Vec<usize> = obs
            .iter()
            .map(|o| MerlBin::from_index(o.bin).unwrap())
            .filter(|b| b.theta_h == h)
            .map(|b| b.theta_d)
            .collect();
        let nearest = *column.iter().max().unwrap();
        let far = MerlBin {
            theta_h: h,
            theta_d: 60,
            phi_d: 30,
        };
        let m = |d: usize| (model.0)(h, d);
        let p = |d: usize| (prior.0)(h, d);
        let want = m(nearest) * p(60) / p(nearest);
        assert!(want < 10.0 * p(60), "the test wants no clamp here");
        let got = t.get(far.index()).unwrap()[0];
        assert!((got - want).abs() < 1e-9 * want, "{got} against {want}");
        // The model's own runaway (56 times its seen value) is what `model` keeps, within R.
        let (own, _) = make_plausible(
            &model,
            Some((&prior, "test prior")),
            &used,
            &PlausibleSettings {
                theta_d_shape: ThetaDShape::Model,
                ..settings
            },
        );
        let kept = own.get(far.index()).unwrap()[0];
        assert!((kept - m(60).min(10.0 * p(60))).abs() < 1e-9, "{kept}");
        assert!(kept > 2.0 * got, "{kept} {got}");
        // A theta_h column no pixel saw keeps the model's extrapolation (within R).
        let lone = (0..THETA_H_BINS)
            .rev()
            .filter(|&hh| {
                obs.iter()
                    .all(|o| MerlBin::from_index(o.bin).unwrap().theta_h != hh)
            })
            .map(|hh| MerlBin {
                theta_h: hh,
                theta_d: 20,
                phi_d: 30,
            })
            .find(|b| b.is_above_horizon())
            .expect("an unseen theta_h column above the horizon");
        let (a, b) = (
            t.get(lone.index()).unwrap()[0],
            own.get(lone.index()).unwrap()[0],
        );
        assert!((a - b).abs() < 1e-12, "{a} {b}");
        // The basis's typical material as the shape: the same carrying with its ratio (here a
        // flat one, so the seen value carries unchanged before the clamp), and without a
        // typical material the model's own extrapolation.
        let flat = ByBin(|_, _| 1.0);
        let basis_shaped = PlausibleSettings {
            theta_d_shape: ThetaDShape::Basis,
            ..settings
        };
        let (tb, _) = make_plausible_shaped(
            &model,
            Some((&prior, "test prior")),
            Some(&flat),
            &used,
            &basis_shaped,
        );
        let want_b = m(nearest).clamp(p(60) / 10.0, 10.0 * p(60));
        let got_b = tb.get(far.index()).unwrap()[0];
        assert!((got_b - want_b).abs() < 1e-9, "{got_b} {want_b}");
        let (tn, _) = make_plausible(&model, Some((&prior, "test prior")), &used, &basis_shaped);
        assert_eq!(tn.get(far.index()), own.get(far.index()));
    }
}
