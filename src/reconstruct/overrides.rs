//! Study overrides of the core's settings that the benches share: what a basis fit is given,
//! where an unobserved cell starts from, the ladder's smallest gain, its ridge weights and the
//! hedge's strength, the peak average's weight and whether pixels are carried to their row's
//! centre, the grazing peak's transfer, how the written basis fit comes from the trials, and
//! which basis rung the ladder writes. Each `None` keeps the library's default. Pure data; no I/O, no parsing (the command line's words
//! live in `cli`).

use super::carry::Carry;
use super::core::{CoreSettings, TrialChoice};
use super::fresnel::F0Rule;
use super::ladder::BasisRung;
use super::lambert_rung::LambertFit;
use super::plausible::ThetaDShape;
use super::reliable::CurvatureThreshold;
use super::trials::BasisFit;

#[derive(Clone, Debug, Default, PartialEq)]
pub struct CoreOverrides {
    pub basis_fit: Option<BasisFit>,
    pub theta_d_shape: Option<ThetaDShape>,
    pub min_gain: Option<f64>,
    pub etas: Option<Vec<f64>>,
    pub hedge: Option<f64>,
    pub peak_average: Option<f64>,
    pub rung_average: Option<bool>,
    pub carry: Option<Carry>,
    /// The RMS normal tilt (degrees) the written basis fit is deblurred for.
    pub deblur_deg: Option<f64>,
    /// Quantiles of theta_d for the extrapolation check (empty: off).
    pub extrapolation: Option<Vec<f64>>,
    /// The margin a basis must beat Lambert + GGX's held-out error by.
    pub analytic_margin: Option<f64>,
    /// The carried value's weight in the grazing peak cells (`reconstruct::grazing`).
    pub grazing_transfer: Option<f64>,
    /// The peak's theta_h extent (degrees) scaled to the patch sums (`reconstruct::peak_energy`).
    pub peak_energy: Option<f64>,
    /// Up to this many theta_d bands of the peak's factor (`reconstruct::peak_bands`).
    pub peak_energy_bands: Option<usize>,
    /// How the reported trial is chosen and the written basis fit made (`CoreSettings::choose`).
    pub choose: Option<TrialChoice>,
    /// Which basis rung the ladder writes once it took the basis family.
    pub basis_rung: Option<BasisRung>,
    /// How the reconstruction's Lambert + GGX sets F0 where the pixels cannot tell it.
    pub lambert_ggx_f0: Option<F0Rule>,
    /// How the reconstruction's Lambert fits its albedo.
    pub lambert_fit: Option<LambertFit>,
    /// The curvature filter's quantile of |H| (`ReliableSettings::curvature_threshold`; 1
    /// keeps every pixel).
    pub curvature_quantile: Option<f64>,
}

impl CoreOverrides {
    /// Sets what was given; the rest keeps what `core` had.
    pub fn apply(&self, core: &mut CoreSettings) {
        if let Some(f) = self.basis_fit {
            core.trials.basis_fit = f;
        }
        if let Some(u) = self.theta_d_shape {
            core.plausible.theta_d_shape = u;
        }
        if let Some(g) = self.min_gain {
            core.ladder.min_gain = g;
        }
        if let Some(e) = &self.etas {
            core.components.etas = e.clone();
        }
        if let Some(h) = self.hedge {
            core.hedge.strength = h;
        }
        if let Some(w) = self.peak_average {
            core.peak_average = w;
        }
        if let Some(r) = self.rung_average {
            core.rung_average = r;
        }
        if let Some(c) = self.carry {
            core.carry = c;
        }
        if let Some(d) = self.deblur_deg {
            core.deblur_deg = d;
        }
        if let Some(q) = &self.extrapolation {
            core.extrapolation.quantiles = q.clone();
        }
        if let Some(m) = self.analytic_margin {
            core.ladder.analytic_margin = m;
        }
        if let Some(w) = self.grazing_transfer {
            core.grazing_transfer = w;
        }
        if let Some(d) = self.peak_energy {
            core.peak_energy_deg = d;
        }
        if let Some(n) = self.peak_energy_bands {
            core.peak_energy_bands = n;
        }
        if let Some(c) = self.choose {
            core.choose = c;
        }
        if let Some(b) = self.basis_rung {
            core.ladder.basis_rung = b;
        }
        if let Some(f) = self.lambert_ggx_f0 {
            core.ladder.lambert_ggx_f0 = f;
        }
        if let Some(f) = self.lambert_fit {
            core.ladder.lambert_fit = f;
        }
        if let Some(q) = self.curvature_quantile {
            core.reliable.curvature_threshold = CurvatureThreshold::Quantile(q);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_set_what_they_name_and_keep_the_rest() {
        let mut core = CoreSettings::default();
        CoreOverrides::default().apply(&mut core);
        assert_eq!(core, CoreSettings::default());
        CoreOverrides {
            basis_fit: Some(BasisFit::Samples),
            theta_d_shape: Some(ThetaDShape::Basis),
            min_gain: Some(0.05),
            etas: Some(vec![0.01, 1.0]),
            hedge: Some(0.0),
            peak_average: Some(0.25),
            rung_average: Some(!CoreSettings::default().rung_average),
            carry: Some(Carry::Off),
            deblur_deg: Some(3.0),
            extrapolation: Some(vec![0.8]),
            analytic_margin: Some(0.25),
            grazing_transfer: Some(0.75),
            peak_energy: Some(2.0),
            peak_energy_bands: Some(3),
            choose: Some(TrialChoice::Median),
            basis_rung: Some(BasisRung::Simplest),
            lambert_ggx_f0: Some(F0Rule::Free),
            lambert_fit: Some(LambertFit::LeastSquares),
            curvature_quantile: Some(0.9),
        }
        .apply(&mut core);
        assert_eq!(core.trials.basis_fit, BasisFit::Samples);
        assert_eq!(core.plausible.theta_d_shape, ThetaDShape::Basis);
        assert_eq!(core.ladder.min_gain, 0.05);
        assert_eq!(core.components.etas, vec![0.01, 1.0]);
        assert_eq!(core.hedge.strength, 0.0);
        assert_eq!(core.peak_average, 0.25);
        assert_eq!(core.rung_average, !CoreSettings::default().rung_average);
        assert_eq!(core.carry, Carry::Off);
        assert_eq!(core.deblur_deg, 3.0);
        assert_eq!(core.extrapolation.quantiles, vec![0.8]);
        assert_eq!(core.ladder.analytic_margin, 0.25);
        assert_eq!(core.grazing_transfer, 0.75);
        assert_eq!(core.peak_energy_deg, 2.0);
        assert_eq!(core.peak_energy_bands, 3);
        assert_eq!(core.choose, TrialChoice::Median);
        assert_eq!(core.ladder.basis_rung, BasisRung::Simplest);
        assert_eq!(
            core.reliable.curvature_threshold,
            CurvatureThreshold::Quantile(0.9)
        );
        assert_eq!(core.ladder.lambert_ggx_f0, F0Rule::Free);
        assert_eq!(core.ladder.lambert_fit, LambertFit::LeastSquares);
        assert_eq!(core.trials.samples, CoreSettings::default().trials.samples);
    }
}
