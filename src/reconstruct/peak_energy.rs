//! The specular peak's energy set from patch sums of the images (on by default since session
//! 44; `reconstruct --peak-energy 0` turns it off; docs/evaluation.md section 1ag).
//!
//! Why: with normals off by about a degree (the refinement's floor at 640x480), a narrow peak's
//! pixels land at the wrong theta_h, and a per-pixel fit (the basis's, in log space) writes a
//! peak a third of the truth's height at theta_h below 1 degree (blue-acrylic:
//! docs/evaluation.md 1ag). An environment render integrates the peak over directions and sees
//! its missing energy, where a bright window lies behind the object. Summed over a patch of the
//! image, the pixels' rendered values integrate the table over the patch's range of normals
//! much as the truth's do, wherever each pixel's own normal points: the sum does not ask which
//! pixel the highlight fell on. So the peak's cells and the rest are given a factor each,
//! fitted in linear least squares to the patch sums of every observed pixel (all images):
//! `sum_patch (a (R - Q) + s Q - I)^2` minimal, `R` the table's rendered sum, `Q` the part of
//! it from the peak's cells, `I` the observed sum; the peak's cells are then multiplied by
//! `s / a` (the rest keeps its fit: `a` only takes up the whole table's level, which a small
//! misfit of a broad part would otherwise push onto a peak that holds little of the energy).
//! A peak cell at theta_h below `theta_deg` (1.5 degrees by default since session 46, 1 before)
//! takes the full factor, fading linearly (in theta_h) to none at twice that. The factor is
//! applied unless the images refute it: each image in turn is held out, the factor fitted to
//! the others' patches, and the held-out image's relative patch error must not rise, on
//! average over the images, by one standard error or more (where a peak is narrower than a
//! pixel's step in normal, which pixel hits it is luck, and the images disagree). Session 46 loosened the rule from "must fall by more
//! than one standard error": the held-out patch error is noisy where one image's highlight
//! lands on a wrong normal, and asking it to confirm the factor refused factors that rendered
//! better (docs/evaluation.md 1ai). The factor is at least 1 and fades along theta_d over
//! [`THETA_D_SHRINK_BINS`] degrees away from every theta_d a pixel reached, so a peak that no
//! image saw (grazing theta_d with one light by the camera) is not multiplied.
//!
//! Pure: no I/O. Must not refit the model: it only rescales the written table's peak cells.

use super::observe::Observation;
use crate::brdf::coords::{MerlBin, THETA_D_BINS};
use crate::brdf::merl::MerlTable;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// What the step did, for `report.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PeakEnergy {
    /// The peak's cells: full factor below this theta_h (degrees), none beyond twice it.
    pub theta_deg: f64,
    /// The factor applied: `fitted` unless the images held out one at a time refute it
    /// (`held_out_change` at least `held_out_standard_error`), else 1.
    pub scale: f64,
    /// The fitted factor of the peak relative to the rest of the table (every image), clamped
    /// to `[MIN_SCALE, MAX_SCALE]`.
    pub fitted: f64,
    /// The rest's own factor in the same fit (not applied: the rest is fitted to the pixels
    /// themselves; it takes up what the patch sums say of the whole table's level, so that a
    /// broad part's small misfit is not read as the peak's).
    pub rest_gain: f64,
    /// Patches with some of the peak's rendered energy in them.
    pub patches: usize,
    /// Mean, over the images held out one at a time, of the change in their relative patch
    /// error when the peak takes the factor fitted to the other images (negative: better).
    pub held_out_change: f64,
    pub held_out_standard_error: f64,
    /// Images held out.
    pub images: usize,
    /// The factors per band of theta_d, where asked for (`reconstruct::peak_bands`, a study
    /// knob); where applied they replace `scale`. Absent in reports written before session 53.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bands: Option<PeakBands>,
}

impl PeakEnergy {
    /// What the step did, in words (the command line and the HTML report).
    pub fn describe(&self) -> String {
        let one = format!(
            "fitted to the images' patch sums {:.2}, held out one image at a time their patch \
             error {:+.4} +- {:.4}",
            self.fitted, self.held_out_change, self.held_out_standard_error
        );
        match &self.bands {
            Some(b) if b.applied => format!(
                "peak cells below theta_h {:.1} deg scaled {} (one factor {one}, not applied)",
                self.theta_deg,
                b.describe()
            ),
            _ => format!(
                "peak cells below theta_h {:.1} deg {}; {one}{}",
                self.theta_deg,
                if self.scale == 1.0 {
                    "left as fitted".to_string()
                } else {
                    format!("scaled by {:.2}", self.scale)
                },
                self.bands
                    .as_ref()
                    .map_or(String::new(), |b| format!("; {}", b.describe()))
            ),
        }
    }
}

/// One band's factor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PeakBand {
    /// The peak energy's mean theta_d in the band (degrees), where its factor is exact.
    pub theta_d_deg: f64,
    /// The band's fitted factor, clamped to `[MIN_SCALE, MAX_SCALE]`.
    pub fitted: f64,
}

/// The band factors of `reconstruct::peak_bands` (a study knob) and their check, for
/// `report.json` (inside `plausibility.peak_energy`): the report's type lives here, the fit
/// there.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PeakBands {
    pub bands: Vec<PeakBand>,
    /// Applied: the images held out one at a time confirmed the band factors, and beyond what
    /// the one factor achieved (`reconstruct::peak_bands::accepted`).
    pub applied: bool,
    /// Mean over the held-out images of the change in their relative patch error with the
    /// band factors fitted to the others (negative: better), and its standard error.
    pub held_out_change: f64,
    pub held_out_standard_error: f64,
}

impl PeakBands {
    /// In words, for the command line and the HTML report.
    pub fn describe(&self) -> String {
        let list: Vec<String> = self
            .bands
            .iter()
            .map(|b| format!("{:.2} at theta_d {:.0}", b.fitted, b.theta_d_deg))
            .collect();
        format!(
            "per theta_d band {} ({}; held out one image at a time {:+.4} +- {:.4})",
            if self.applied {
                "applied"
            } else {
                "not applied (not confirmed by the held-out images beyond the one factor)"
            },
            list.join(", "),
            self.held_out_change,
            self.held_out_standard_error
        )
    }

    /// The factor at theta_d bin `j`: interpolated in log between the bands' centres, held
    /// beyond the outer ones; 1 when not applied.
    pub fn factor_at(&self, j: usize) -> f64 {
        if !self.applied || self.bands.is_empty() {
            return 1.0;
        }
        let t = j as f64 + 0.5;
        let first = &self.bands[0];
        let last = &self.bands[self.bands.len() - 1];
        if t <= first.theta_d_deg {
            return first.fitted;
        }
        if t >= last.theta_d_deg {
            return last.fitted;
        }
        self.bands
            .windows(2)
            .find(|w| t >= w[0].theta_d_deg && t <= w[1].theta_d_deg)
            .map_or(last.fitted, |w| {
                let span = (w[1].theta_d_deg - w[0].theta_d_deg).max(1e-9);
                let u = (t - w[0].theta_d_deg) / span;
                (w[0].fitted.ln() * (1.0 - u) + w[1].fitted.ln() * u).exp()
            })
    }
}

/// The smallest and largest factor the step applies. Never below 1: the normals' error only
/// spreads a peak's energy over the shoulder, where a per-pixel fit loses it; patch sums that
/// want less peak read something else (measured: docs/evaluation.md 1ag).
pub const MIN_SCALE: f64 = 1.0;
pub const MAX_SCALE: f64 = 10.0;

/// Shrink length of the factor along theta_d away from every theta_d the pixels saw (bins of
/// one degree, as the plausibility step's `L`): the patch sums speak for the peak where the
/// images saw it; at a theta_d no image reached (one light by the camera) the peak is an
/// extrapolation the step must not multiply.
pub const THETA_D_SHRINK_BINS: f64 = 6.0;

/// Per theta_d bin, `exp(-d^2 / (2 L^2))` with `d` the distance in bins to the nearest theta_d
/// bin any of `obs` falls in (`L` = [`THETA_D_SHRINK_BINS`]); all zero without observations.
pub fn theta_d_weights(obs: &[&Observation]) -> Vec<f64> {
    let mut seen = [false; THETA_D_BINS];
    for o in obs {
        if let Some(b) = MerlBin::from_index(o.bin) {
            seen[b.theta_d] = true;
        }
    }
    let seen: Vec<usize> = (0..THETA_D_BINS).filter(|&j| seen[j]).collect();
    (0..THETA_D_BINS)
        .map(|j| {
            seen.iter()
                .map(|&k| j.abs_diff(k) as f64)
                .fold(None, |m: Option<f64>, d| Some(m.map_or(d, |m| m.min(d))))
                .map_or(0.0, |d| {
                    (-d * d / (2.0 * THETA_D_SHRINK_BINS * THETA_D_SHRINK_BINS)).exp()
                })
        })
        .collect()
}

/// The weight of a bin in the peak (1 below `theta_deg`, 0 from twice it).
pub(super) fn peak_weight(bin: usize, theta_deg: f64) -> f64 {
    let Some(b) = MerlBin::from_index(bin) else {
        return 0.0;
    };
    let t = b.centre().theta_h.to_degrees();
    if t <= theta_deg {
        1.0
    } else {
        (2.0 - t / theta_deg).clamp(0.0, 1.0)
    }
}

/// (R, Q, I) per channel of one patch: the table's rendered sum, the part of it from the
/// peak's cells, the observed sum.
type PatchSums = [[f64; 3]; 3];

/// The patch sums of every image, keyed by (image, patch column, patch row).
fn patch_sums(
    table: &MerlTable,
    obs: &[&Observation],
    patch_px: usize,
    theta_deg: f64,
) -> BTreeMap<(usize, u32, u32), PatchSums> {
    let patch_px = patch_px.max(1) as u32;
    let mut sums: BTreeMap<(usize, u32, u32), PatchSums> = BTreeMap::new();
    for o in obs {
        let Some(f) = table.get(o.bin) else { continue };
        let w = peak_weight(o.bin, theta_deg);
        let e = sums
            .entry((o.image, o.x / patch_px, o.y / patch_px))
            .or_insert([[0.0; 3]; 3]);
        for c in 0..3 {
            let r = f[c] * o.irradiance[c] * o.cos_theta_i;
            if !(r.is_finite() && o.radiance[c].is_finite()) {
                continue;
            }
            e[0][c] += r;
            e[1][c] += w * r;
            e[2][c] += o.radiance[c];
        }
    }
    sums
}

/// `(a, s)` minimising `sum (a (R - Q) + s Q - I)^2` over `patches`, or `None` when the peak
/// holds no rendered energy there or the two are not separable.
fn solve<'a>(patches: impl Iterator<Item = &'a PatchSums>) -> Option<(f64, f64)> {
    let (mut pp, mut pq, mut qq, mut pi, mut qi) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for [r, q, i] in patches {
        for c in 0..3 {
            let rest = r[c] - q[c];
            pp += rest * rest;
            pq += rest * q[c];
            qq += q[c] * q[c];
            pi += rest * i[c];
            qi += q[c] * i[c];
        }
    }
    let det = pp * qq - pq * pq;
    if !(qq > 0.0 && det > 1e-12 * pp * qq && det.is_finite()) {
        return None;
    }
    let a = (qq * pi - pq * qi) / det;
    let s = (pp * qi - pq * pi) / det;
    (a > 0.0).then_some((a, s))
}

/// `sum (pred - I)^2` and `sum I^2` of patches with the peak's cells times `m`, the rest as
/// it is.
fn residual<'a>(patches: impl Iterator<Item = &'a PatchSums>, m: f64) -> (f64, f64) {
    let (mut num, mut den) = (0.0, 0.0);
    for [r, q, i] in patches {
        for c in 0..3 {
            let d = r[c] - q[c] + m * q[c] - i[c];
            num += d * d;
            den += i[c] * i[c];
        }
    }
    (num, den)
}

/// The factor of the peak's cells that best matches the patch sums, checked image by image
/// (each image's patches scored with the factor fitted to the other images'), or `None` when
/// no patch holds any of the peak's rendered energy.
pub fn fit_scale(
    table: &MerlTable,
    obs: &[&Observation],
    patch_px: usize,
    theta_deg: f64,
) -> Option<PeakEnergy> {
    let sums = patch_sums(table, obs, patch_px, theta_deg);
    let patches = sums
        .values()
        .filter(|[_, q, _]| q.iter().any(|&x| x > 0.0))
        .count();
    if patches == 0 {
        return None;
    }
    let (a, s) = solve(sums.values())?;
    let clamp = |m: f64| m.clamp(MIN_SCALE, MAX_SCALE);
    // leave one image out: the relative held-out patch error with the factor against without
    let mut images: Vec<usize> = sums.keys().map(|k| k.0).collect();
    images.dedup();
    let mut diffs = Vec::new();
    for &m in &images {
        let held = || sums.iter().filter(move |(k, _)| k.0 == m).map(|(_, v)| v);
        let Some((a_m, s_m)) = solve(sums.iter().filter(|(k, _)| k.0 != m).map(|(_, v)| v)) else {
            continue;
        };
        let (with, den) = residual(held(), clamp(s_m / a_m));
        let (without, _) = residual(held(), 1.0);
        if den > 0.0 {
            diffs.push((with.sqrt() - without.sqrt()) / den.sqrt());
        }
    }
    let (mean, standard_error) = crate::stats::mean_and_standard_error(&diffs);
    let accepted = diffs.len() >= 2 && mean < standard_error;
    Some(PeakEnergy {
        theta_deg,
        fitted: clamp(s / a),
        scale: if accepted { clamp(s / a) } else { 1.0 },
        rest_gain: a,
        patches,
        held_out_change: mean,
        held_out_standard_error: standard_error,
        images: diffs.len(),
        bands: None,
    })
}

/// Multiplies the peak's cells by the fitted factor (fading as [`fit_scale`] weighs them, and
/// along theta_d by `theta_d_weight`, from [`theta_d_weights`]).
pub fn apply(table: &mut MerlTable, fit: &PeakEnergy, theta_d_weight: &[f64]) {
    table.update(|bin, v| {
        v.map(|v| {
            let d = MerlBin::from_index(bin)
                .and_then(|b| theta_d_weight.get(b.theta_d).copied())
                .unwrap_or(0.0);
            let m = 1.0 + (fit.scale - 1.0) * peak_weight(bin, fit.theta_deg) * d;
            v.map(|x| x * m)
        })
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(peak: f64) -> MerlTable {
        MerlTable::from_fn(|b| {
            let t = b.centre().theta_h.to_degrees();
            Some(if t < 1.0 { [peak; 3] } else { [0.1; 3] })
        })
    }

    fn pixel(image: usize, x: u32, theta_h_deg: f64, radiance: f64) -> Observation {
        let mut o = Observation::at_angles(theta_h_deg.to_radians(), 0.3, [radiance; 3]);
        o.image = image;
        o.x = x;
        o
    }

    /// Images 0..n, each with a patch holding the table's peak bin (seen dark) and the
    /// highlight read at theta_h 3 degrees (its normal wrong) of value `highlight(image)`, and
    /// a patch of the body alone.
    fn scene(n: usize, highlight: impl Fn(usize) -> f64) -> Vec<Observation> {
        (0..n)
            .flat_map(|m| {
                [
                    pixel(m, 0, 0.5, 0.1),
                    pixel(m, 1, 3.0, highlight(m)),
                    pixel(m, 9, 5.0, 0.1),
                ]
            })
            .collect()
    }

    /// The truth's peak is 30 where the table says 10: no pixel agrees alone, but every
    /// image's patch sum holds the highlight, so the factor is 3 and it is applied; the body's
    /// cells keep their values, the fade's half way gets half the factor's excess.
    #[test]
    fn a_peak_short_of_the_patch_sums_is_scaled_up_to_them() {
        let t = table(10.0);
        let obs = scene(4, |_| 30.0);
        let refs: Vec<&Observation> = obs.iter().collect();
        let fit = fit_scale(&t, &refs, 8, 1.0).expect("a patch with peak energy");
        assert_eq!((fit.patches, fit.images), (4, 4));
        assert!((fit.fitted - 3.0).abs() < 1e-9, "{fit:?}");
        assert_eq!(fit.scale, fit.fitted);
        assert!(fit.held_out_change < 0.0, "{fit:?}");
        let mut t = t;
        apply(&mut t, &fit, &[1.0; THETA_D_BINS]);
        assert!((t.get(obs[0].bin).unwrap_or([0.0; 3])[0] - 30.0).abs() < 1e-6);
        assert!((t.get(obs[2].bin).unwrap_or([0.0; 3])[0] - 0.1).abs() < 1e-9);
        // theta_h 1.5 degrees: half way along the fade, the factor 2
        let fading = pixel(0, 0, 1.5, 0.0).bin;
        assert!((t.get(fading).unwrap_or([0.0; 3])[0] - 0.2).abs() < 0.03);
    }

    /// Half the images show the highlight and half do not (a peak narrower than a pixel's
    /// step: which pixel hits it is luck): the factor fitted to all is not applied, since the
    /// images held out refute the others' factor (their patch error rises by more than a
    /// standard error).
    #[test]
    fn a_factor_the_held_out_images_disagree_with_is_not_applied() {
        let t = table(10.0);
        let obs = scene(4, |m| if m < 2 { 30.0 } else { 0.1 });
        let refs: Vec<&Observation> = obs.iter().collect();
        let fit = fit_scale(&t, &refs, 8, 1.0).expect("fit");
        assert!(fit.fitted > 1.2, "{fit:?}");
        assert!(fit.held_out_change > fit.held_out_standard_error, "{fit:?}");
        assert_eq!(fit.scale, 1.0);
    }

    /// Three images of four show the highlight and one caught less of it (its normals' luck):
    /// held out, that image's patch error rises with the factor and the others' falls, so the
    /// mean change is positive but within a standard error: the images do not refute the
    /// factor, and it is applied (a rule asking them to confirm it refused such factors where
    /// they rendered better; docs/evaluation.md 1ai).
    #[test]
    fn one_image_that_missed_the_highlight_does_not_veto_the_factor() {
        let t = table(10.0);
        let obs = scene(4, |m| if m == 3 { 6.0 } else { 30.0 });
        let refs: Vec<&Observation> = obs.iter().collect();
        let fit = fit_scale(&t, &refs, 8, 1.0).expect("fit");
        assert!(fit.held_out_change > 0.0, "{fit:?}");
        assert!(fit.held_out_change < fit.held_out_standard_error, "{fit:?}");
        assert!(fit.fitted > 2.0, "{fit:?}");
        assert_eq!(fit.scale, fit.fitted);
    }

    /// A table whose peak already matches the patches keeps it; no peak pixel, no fit.
    #[test]
    fn a_matching_peak_keeps_its_scale_and_no_peak_pixel_gives_no_fit() {
        let t = table(10.0);
        let obs = scene(3, |_| 10.0);
        let refs: Vec<&Observation> = obs.iter().collect();
        let fit = fit_scale(&t, &refs, 8, 1.0).expect("fit");
        assert!((fit.fitted - 1.0).abs() < 1e-9, "{fit:?}");
        assert!((fit.rest_gain - 1.0).abs() < 1e-9, "{fit:?}");
        assert_eq!(fit.scale, 1.0);
        let none = [pixel(0, 1, 3.0, 0.1), pixel(1, 0, 5.0, 0.1)];
        let refs: Vec<&Observation> = none.iter().collect();
        assert!(fit_scale(&t, &refs, 8, 1.0).is_none());
    }

    /// A nearly diffuse table (peak 0.2 on a body of 0.1) whose body the images show 2 %
    /// brighter: a peak scale alone would double the peak to take up that 2 % (one peak pixel
    /// among a hundred body pixels); the rest's own factor takes it, and the peak keeps its
    /// level relative to the body.
    #[test]
    fn a_broad_parts_small_misfit_is_not_read_as_the_peaks() {
        let t = table(0.2);
        let mut obs = Vec::new();
        for m in 0..3 {
            obs.push(pixel(m, 0, 0.5, 0.2 * 1.02));
            for x in 0..100 {
                obs.push(pixel(m, 1 + x % 7, 3.0, 0.102));
                obs.push(pixel(m, 8 + x % 8, 5.0, 0.102));
            }
        }
        let refs: Vec<&Observation> = obs.iter().collect();
        let fit = fit_scale(&t, &refs, 8, 1.0).expect("fit");
        assert!((fit.rest_gain - 1.02).abs() < 1e-9, "{fit:?}");
        assert!((fit.fitted - 1.0).abs() < 1e-9, "{fit:?}");
    }

    /// With one light by the camera every pixel sits near one theta_d: the factor applies
    /// there and fades over six degrees; the grazing peak, which no image saw, keeps its value.
    #[test]
    fn the_factor_stays_where_the_pixels_theta_d_was() {
        let at = |theta_d_deg: f64| {
            let mut o = pixel(0, 0, 0.5, 1.0);
            o.angles.theta_d = theta_d_deg.to_radians();
            o.bin = o.angles.merl_bin().index();
            o
        };
        let obs = [at(10.5)];
        let refs: Vec<&Observation> = obs.iter().collect();
        let w = theta_d_weights(&refs);
        assert!((w[10] - 1.0).abs() < 1e-12);
        assert!((w[16] - (-0.5f64).exp()).abs() < 1e-12);
        assert!(w[70] < 1e-12);
        let fit = PeakEnergy {
            theta_deg: 1.0,
            scale: 3.0,
            fitted: 3.0,
            rest_gain: 1.0,
            patches: 1,
            held_out_change: -0.1,
            held_out_standard_error: 0.01,
            images: 3,
            bands: None,
        };
        let mut t = table(10.0);
        apply(&mut t, &fit, &w);
        assert!((t.get(at(10.5).bin).unwrap_or([0.0; 3])[0] - 30.0).abs() < 1e-6);
        assert!((t.get(at(70.5).bin).unwrap_or([0.0; 3])[0] - 10.0).abs() < 1e-6);
        assert!(theta_d_weights(&[]).iter().all(|&x| x == 0.0));
    }
}
