//! The reconstruction study knobs that `bench accuracy` and `bench external` share: what a
//! basis fit is given, where an unobserved cell starts from, the ladder's smallest gain,
//! ridge weights, the hedge's strength, the peak average's weight, the carry of pixels to
//! their row's centre, the grazing peak's transfer, how the trials make the written fit and
//! which basis rung is written. Their parsing, the library's overrides they make
//! (`reconstruct::overrides`), and the words that type them again for a page's "command"
//! line.
//! No I/O.

use brdf_rig::reconstruct::carry::Carry;
use brdf_rig::reconstruct::core::TrialChoice;
use brdf_rig::reconstruct::fresnel::F0Rule;
use brdf_rig::reconstruct::ladder::BasisRung;
use brdf_rig::reconstruct::lambert_rung::LambertFit;
use brdf_rig::reconstruct::overrides::CoreOverrides;
use brdf_rig::reconstruct::plausible::ThetaDShape;
use brdf_rig::reconstruct::trials::BasisFit;
use clap::Args;

#[derive(Args, Clone, Debug, Default)]
pub struct FitKnobs {
    /// What each basis fit is given: `rows` (the default) or `samples` (the paper's), as
    /// `reconstruct --basis-fit`.
    #[arg(long, value_parser = super::reconstruct::parse_basis_fit)]
    pub basis_fit: Option<BasisFit>,
    /// Where an unobserved cell starts from: `model` (the default), `transfer` or
    /// `transfer-basis`, as `reconstruct --unobserved`.
    #[arg(long, value_parser = super::reconstruct::parse_unobserved)]
    pub unobserved: Option<ThetaDShape>,
    /// A simpler rung within this fraction of the best rung's mean held-out error counts as
    /// within noise too (`LadderSettings::min_gain`; default: the library's 0.01; 0: the
    /// paired standard error alone).
    #[arg(long, value_parser = super::ranges::real_in(super::ranges::Closed(0.0), super::ranges::Closed(1.0)))]
    pub min_gain: Option<f64>,
    /// Study knob: the ridge weights the ladder tries for each k, before the scaling of a fit
    /// to every row (`ComponentSettings::etas`; default: the library's 1, 10, 40).
    #[arg(long, value_delimiter = ',', value_parser = super::ranges::real_in(super::ranges::Open(0.0), super::ranges::Closed(1e6)))]
    pub etas: Option<Vec<f64>>,
    /// The weight of Lambert + GGX per unit share of the render from unobserved cells, as
    /// `reconstruct --hedge` (default: the library's 1; 0 turns the averaging off).
    #[arg(long, value_parser = super::ranges::real_in(super::ranges::Closed(0.0), super::ranges::Closed(1.0)))]
    pub hedge: Option<f64>,
    /// The weight of the basis + peak averaged into a basis result the held-out images cannot
    /// tell from it, as `reconstruct --peak-average` (default: the library's 0.5; 0: never).
    #[arg(long, value_parser = super::ranges::real_in(super::ranges::Closed(0.0), super::ranges::Closed(1.0)))]
    pub peak_average: Option<f64>,
    /// Whether the basis rungs within noise of the chosen one are averaged into a basis
    /// result, as `reconstruct --rung-average` (default: the library's).
    #[arg(long, action = clap::ArgAction::Set)]
    pub rung_average: Option<bool>,
    /// Whether the written basis fit sees pixels carried to their row's centre, as
    /// `reconstruct --carry` (`difference`, the default, or `off`).
    #[arg(long, value_parser = super::reconstruct::parse_carry)]
    pub carry: Option<Carry>,
    /// Study knob: deblur the written basis fit for normals off by this RMS tilt in degrees,
    /// as `reconstruct --deblur` (default 0, off).
    #[arg(long, value_parser = super::ranges::real_in(super::ranges::Closed(0.0), super::ranges::Closed(20.0)))]
    pub deblur: Option<f64>,
    /// Study knob: run the theta_d extrapolation check at these quantiles of the reliable
    /// pixels' theta_d (`reconstruct::extrapolation`; reported in `plausibility.extrapolation`).
    #[arg(long, value_delimiter = ',', value_parser = super::ranges::real_in(super::ranges::Open(0.0), super::ranges::Open(1.0)))]
    pub extrapolation: Option<Vec<f64>>,
    /// Study knob: a chosen basis rung must beat Lambert + GGX's held-out error by this
    /// fraction, or Lambert + GGX is chosen (`LadderSettings::analytic_margin`; default 0, off).
    #[arg(long, value_parser = super::ranges::real_in(super::ranges::Closed(0.0), super::ranges::Open(1.0)))]
    pub analytic_margin: Option<f64>,
    /// Study knob: the carried value's weight in the grazing peak cells, as `reconstruct
    /// --grazing-transfer` (default 0, off).
    #[arg(long, value_parser = super::ranges::real_in(super::ranges::Closed(0.0), super::ranges::Closed(1.0)))]
    pub grazing_transfer: Option<f64>,
    /// The written basis's peak cells (theta_h below this many degrees) scaled to the images'
    /// patch sums, as `reconstruct --peak-energy` (default 1.5; 0 turns it off).
    #[arg(long, value_parser = super::ranges::real_in(super::ranges::Closed(0.0), super::ranges::Closed(10.0)))]
    pub peak_energy: Option<f64>,
    /// Study knob: the peak's factor per band of theta_d, up to this many bands, as
    /// `reconstruct --peak-energy-bands` (default 0: one factor; measured, not adopted).
    #[arg(long, value_parser = super::ranges::int_in(0usize, 8))]
    pub peak_energy_bands: Option<usize>,
    /// How the reported trial is chosen and the written basis fit made, as `reconstruct
    /// --choose`: `similarity` (the default), `pixel-error`, `mean` or `median`.
    #[arg(long, value_parser = super::reconstruct::parse_choice)]
    pub choose: Option<TrialChoice>,
    /// Which basis rung is written once the ladder took the basis family, as `reconstruct
    /// --basis-rung`: `lowest` (held-out error, the default), `simplest` (within noise of the
    /// best) or `extrapolates` (of those within noise of the lowest, the best at the largest
    /// theta_d; a study knob).
    #[arg(long, value_parser = super::reconstruct::parse_basis_rung)]
    pub basis_rung: Option<BasisRung>,
    /// How the reconstruction's Lambert + GGX sets F0 where the pixels cannot tell it, as
    /// `reconstruct --lambert-ggx-f0`: `physical` (the default) or `free`. The baselines the
    /// bench compares against are the plain least-squares fits either way.
    #[arg(long = "lambert-ggx-f0", value_parser = super::reconstruct::parse_f0_rule)]
    pub lambert_ggx_f0: Option<F0Rule>,
    /// How the reconstruction's Lambert (its ladder rung, a written Lambert) fits its
    /// albedo, as `reconstruct --lambert-fit`: `median` (the default) or `least-squares`. The
    /// bench's Lambert baseline is least squares either way.
    #[arg(long = "lambert-fit", value_parser = super::reconstruct::parse_lambert_fit)]
    pub lambert_fit: Option<LambertFit>,
    /// The curvature filter keeps the pixels whose |mean curvature| is at or below this
    /// quantile, as `reconstruct --curvature-quantile` (default: the library's 0.5; 1 keeps
    /// every pixel).
    #[arg(long, value_parser = super::ranges::real_in(super::ranges::Open(0.0), super::ranges::Closed(1.0)))]
    pub curvature_quantile: Option<f64>,
}

impl FitKnobs {
    /// The knobs as the library's overrides.
    pub fn overrides(&self) -> CoreOverrides {
        CoreOverrides {
            basis_fit: self.basis_fit,
            theta_d_shape: self.unobserved,
            min_gain: self.min_gain,
            etas: self.etas.clone(),
            hedge: self.hedge,
            peak_average: self.peak_average,
            rung_average: self.rung_average,
            carry: self.carry,
            deblur_deg: self.deblur,
            extrapolation: self.extrapolation.clone(),
            analytic_margin: self.analytic_margin,
            grazing_transfer: self.grazing_transfer,
            peak_energy: self.peak_energy,
            peak_energy_bands: self.peak_energy_bands,
            choose: self.choose,
            basis_rung: self.basis_rung,
            lambert_ggx_f0: self.lambert_ggx_f0,
            lambert_fit: self.lambert_fit,
            curvature_quantile: self.curvature_quantile,
        }
    }

    /// The knobs as typed (each with a leading space), empty when none was given.
    pub fn args(&self) -> String {
        let mut s = String::new();
        if let Some(f) = self.basis_fit {
            s += &format!(" --basis-fit {}", f.name());
        }
        if let Some(u) = self.unobserved {
            s += &format!(" --unobserved {}", u.name());
        }
        if let Some(g) = self.min_gain {
            s += &format!(" --min-gain {g}");
        }
        if let Some(e) = &self.etas {
            let e: Vec<String> = e.iter().map(|x| x.to_string()).collect();
            s += &format!(" --etas {}", e.join(","));
        }
        if let Some(h) = self.hedge {
            s += &format!(" --hedge {h}");
        }
        if let Some(w) = self.peak_average {
            s += &format!(" --peak-average {w}");
        }
        if let Some(r) = self.rung_average {
            s += &format!(" --rung-average {r}");
        }
        if let Some(c) = self.carry {
            s += &format!(" --carry {}", c.name());
        }
        if let Some(d) = self.deblur {
            s += &format!(" --deblur {d}");
        }
        if let Some(q) = &self.extrapolation {
            let q: Vec<String> = q.iter().map(|x| x.to_string()).collect();
            s += &format!(" --extrapolation {}", q.join(","));
        }
        if let Some(m) = self.analytic_margin {
            s += &format!(" --analytic-margin {m}");
        }
        if let Some(w) = self.grazing_transfer {
            s += &format!(" --grazing-transfer {w}");
        }
        if let Some(d) = self.peak_energy {
            s += &format!(" --peak-energy {d}");
        }
        if let Some(n) = self.peak_energy_bands {
            s += &format!(" --peak-energy-bands {n}");
        }
        if let Some(c) = self.choose {
            s += &format!(" --choose {}", super::reconstruct::choice_name(c));
        }
        if let Some(b) = self.basis_rung {
            s += &format!(" --basis-rung {}", b.name());
        }
        if let Some(f) = self.lambert_ggx_f0 {
            s += &format!(" --lambert-ggx-f0 {}", f.name());
        }
        if let Some(f) = self.lambert_fit {
            s += &format!(" --lambert-fit {}", f.name());
        }
        if let Some(q) = self.curvature_quantile {
            s += &format!(" --curvature-quantile {q}");
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn knobs_become_the_overrides_and_type_themselves_again() {
        let none = FitKnobs::default();
        assert_eq!(none.overrides(), CoreOverrides::default());
        assert_eq!(none.args(), "");
        let k = FitKnobs {
            basis_fit: Some(BasisFit::Samples),
            unobserved: Some(ThetaDShape::Basis),
            min_gain: Some(0.05),
            etas: Some(vec![0.01, 1.0]),
            hedge: Some(0.25),
            peak_average: Some(0.75),
            rung_average: Some(false),
            carry: Some(Carry::Difference),
            deblur: Some(3.0),
            extrapolation: Some(vec![0.7, 0.8]),
            analytic_margin: Some(0.25),
            grazing_transfer: Some(0.75),
            peak_energy: Some(1.0),
            peak_energy_bands: Some(4),
            choose: Some(TrialChoice::Median),
            basis_rung: Some(BasisRung::Simplest),
            lambert_ggx_f0: Some(F0Rule::Free),
            lambert_fit: Some(LambertFit::LeastSquares),
            curvature_quantile: Some(0.9),
        };
        let o = k.overrides();
        assert_eq!(o.basis_fit, Some(BasisFit::Samples));
        assert_eq!(o.theta_d_shape, Some(ThetaDShape::Basis));
        assert_eq!(o.min_gain, Some(0.05));
        assert_eq!(o.etas, Some(vec![0.01, 1.0]));
        assert_eq!(o.hedge, Some(0.25));
        assert_eq!(o.peak_average, Some(0.75));
        assert_eq!(o.rung_average, Some(false));
        assert_eq!(o.carry, Some(Carry::Difference));
        assert_eq!(o.deblur_deg, Some(3.0));
        assert_eq!(o.extrapolation, Some(vec![0.7, 0.8]));
        assert_eq!(o.analytic_margin, Some(0.25));
        assert_eq!(o.grazing_transfer, Some(0.75));
        assert_eq!(o.peak_energy, Some(1.0));
        assert_eq!(o.peak_energy_bands, Some(4));
        assert_eq!(o.choose, Some(TrialChoice::Median));
        assert_eq!(o.basis_rung, Some(BasisRung::Simplest));
        assert_eq!(o.lambert_ggx_f0, Some(F0Rule::Free));
        assert_eq!(o.lambert_fit, Some(LambertFit::LeastSquares));
        assert_eq!(o.curvature_quantile, Some(0.9));
        assert_eq!(
            k.args(),
            " --basis-fit samples --unobserved transfer-basis --min-gain 0.05 --etas 0.01,1 --hedge 0.25 --peak-average 0.75 --rung-average false --carry difference --deblur 3 --extrapolation 0.7,0.8 --analytic-margin 0.25 --grazing-transfer 0.75 --peak-energy 1 --peak-energy-bands 4 --choose median --basis-rung simplest --lambert-ggx-f0 free --lambert-fit least-squares --curvature-quantile 0.9"
        );
    }
}
