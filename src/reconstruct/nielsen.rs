//! The Nielsen prior: the PCA basis of measured BRDFs (`brdf::basis`), sample selection by
//! condition number (`brdf::sampling`) restricted to the rows the reliable pixels observe, and
//! ridge reconstruction (`brdf::ridge`). An adapter only: the mathematics lives in `brdf`.
//!
//! Convention: the basis lives on a subsampled grid; a MERL bin stands for the row of its block
//! (`BasisGrid::row_of_bin`), so several pixels may share a row; the fit uses one sample per row
//! chosen by the trial logic.

use super::prior::{Candidate, Prior, Sample};
use crate::brdf::basis::Basis;
use crate::brdf::merl::MerlTable;
use crate::brdf::ridge::{self, Reconstruction, RidgeSettings};
use crate::brdf::sampling::{self, SamplingSettings};
use serde::{Deserialize, Serialize};

/// Knobs of selection and fit (speed against conditioning).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct NielsenSettings {
    /// Random candidates tried per added sample.
    pub n_random: usize,
    /// Coordinate-descent passes after each addition.
    pub descent_passes: usize,
}

impl Default for NielsenSettings {
    fn default() -> Self {
        Self {
            n_random: 32,
            descent_passes: 0,
        }
    }
}

pub struct NielsenPrior<'a> {
    pub basis: &'a Basis,
    pub settings: NielsenSettings,
}

struct Fitted(Reconstruction);

impl Candidate for Fitted {
    fn eval_bin(&self, bin: usize) -> [f64; 3] {
        self.0.value_at_bin(bin).unwrap_or([0.0; 3])
    }

    fn to_merl_table(&self) -> MerlTable {
        self.0.to_merl_table()
    }
}

impl Prior for NielsenPrior<'_> {
    fn max_components(&self) -> usize {
        self.basis.basis_components()
    }

    fn row_of(&self, bin: usize) -> Option<usize> {
        self.basis.grid().row_of_bin(bin)
    }

    fn row_centre(&self, row: usize) -> Option<usize> {
        self.basis.grid().bins().get(row).copied()
    }

    /// This basis's own fits together ([`Basis::synthesize_rows_many`]: each basis row read
    /// once for all of them); the same values as each fit's `values_at_bins`, bit for bit.
    fn values_of_fits(&self, fits: &[&dyn Candidate], bins: &[usize]) -> Vec<Vec<[f64; 3]>> {
        let own: Option<Vec<&[Vec<f64>; 3]>> = fits
            .iter()
            .map(|f| {
                f.basis_fit()
                    .filter(|(b, _)| std::ptr::eq(*b, self.basis))
                    .map(|(_, c)| c)
            })
            .collect();
        let rows: Vec<Option<usize>> = bins.iter().map(|&b| self.row_of(b)).collect();
        let present: Vec<usize> = rows.iter().flatten().copied().collect();
        let batch = own
            .filter(|own| !own.is_empty())
            .and_then(|own| self.basis.synthesize_rows_many(&own, &present));
        let Some(batch) = batch else {
            return fits.iter().map(|f| f.values_at_bins(bins)).collect();
        };
        batch
            .into_iter()
            .map(|values| {
                let mut values = values.into_iter();
                rows.iter()
                    .map(|r| match r {
                        Some(_) => values.next().unwrap_or([0.0; 3]),
                        None => [0.0; 3],
                    })
                    .collect()
            })
            .collect()
    }

    fn select(
        &self,
        chosen: &[usize],
        candidates: &[usize],
        n: usize,
        k: usize,
        seed: u64,
    ) -> Vec<usize> {
        let mut pool: Vec<usize> = chosen.iter().chain(candidates).copied().collect();
        pool.sort_unstable();
        pool.dedup();
        let settings = SamplingSettings {
            k: k.max(1),
            n_random: self.settings.n_random,
            descent_passes: self.settings.descent_passes,
            seed,
        };
        let rows = sampling::select_samples(self.basis, n.min(pool.len()), Some(&pool), &settings)
            .unwrap_or_default();
        // The accepted pixels stay; the selection's other rows follow in its order.
        let mut out: Vec<usize> = chosen.to_vec();
        out.extend(rows.into_iter().filter(|r| !chosen.contains(r)));
        out.truncate(n.max(chosen.len()));
        out
    }

    fn fit(
        &self,
        samples: &[Sample],
        k: usize,
        eta: f64,
    ) -> Result<Box<dyn Candidate>, ridge::RidgeError> {
        let (obs, settings) = self.ridge_input(samples, k, eta);
        ridge::reconstruct(self.basis, &obs, &settings)
            .map(|r| Box::new(Fitted(r)) as Box<dyn Candidate>)
    }

    fn typical(&self) -> Option<Box<dyn Candidate + '_>> {
        Some(Box::new(Lazy {
            basis: self.basis,
            coefficients: [Vec::new(), Vec::new(), Vec::new()],
        }))
    }

    fn fit_lazy_each<'a>(
        &'a self,
        samples: &[Sample],
        keys: &[(usize, f64)],
    ) -> Vec<Result<Box<dyn Candidate + 'a>, ridge::RidgeError>> {
        let k_max = keys.iter().map(|&(k, _)| k).max().unwrap_or(0);
        let (obs, _) = self.ridge_input(samples, k_max, 0.0);
        match ridge::NormalSystem::new(self.basis, &obs, k_max) {
            Ok(system) => keys
                .iter()
                .map(|&(k, eta)| {
                    system.solve(k, eta).map(|coefficients| {
                        Box::new(Lazy {
                            basis: self.basis,
                            coefficients,
                        }) as Box<dyn Candidate + 'a>
                    })
                })
                .collect(),
            Err(e) => keys.iter().map(|_| Err(e.clone())).collect(),
        }
    }

    fn fit_lazy<'a>(
        &'a self,
        samples: &[Sample],
        k: usize,
        eta: f64,
    ) -> Result<Box<dyn Candidate + 'a>, ridge::RidgeError> {
        let (obs, settings) = self.ridge_input(samples, k, eta);
        let coefficients = ridge::solve(self.basis, &obs, &settings)?;
        Ok(Box::new(Lazy {
            basis: self.basis,
            coefficients,
        }))
    }
}

impl NielsenPrior<'_> {
    fn ridge_input(
        &self,
        samples: &[Sample],
        k: usize,
        eta: f64,
    ) -> (Vec<ridge::BasisSample>, RidgeSettings) {
        let obs = samples
            .iter()
            .filter_map(|s| {
                self.row_of(s.bin).map(|row| ridge::BasisSample {
                    row,
                    rgb: s.reflectance,
                })
            })
            .collect();
        (obs, RidgeSettings { k, eta })
    }
}

/// A fit evaluated row by row on demand (validation reads a few hundred bins of it; the trials
/// read it at their pixels' rows and the confidence probe's bins).
struct Lazy<'a> {
    basis: &'a Basis,
    coefficients: [Vec<f64>; 3],
}

impl Candidate for Lazy<'_> {
    fn eval_bin(&self, bin: usize) -> [f64; 3] {
        self.basis.grid().row_of_bin(bin).map_or([0.0; 3], |row| {
            self.basis.synthesize_row(&self.coefficients, row)
        })
    }

    fn basis_fit(&self) -> Option<(&Basis, &[Vec<f64>; 3])> {
        Some((self.basis, &self.coefficients))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::BinValues;
    use crate::brdf::coords::{MERL_BINS, MerlBin};
    use crate::reconstruct::prior::Tabulated;

    struct Lobe(f64);
    impl BinValues for Lobe {
        fn values_at(&self, bins: &[usize]) -> Vec<[f64; 3]> {
            bins.iter()
                .map(|&b| {
                    let c = MerlBin::from_index(b).expect("bin").centre();
                    let s = self.0 * (-(c.theta_h / 0.1).powi(2)).exp();
                    [0.1 + s, 0.08 + s, 0.05 + s]
                })
                .collect()
        }
    }

    #[test]
    fn a_basis_evaluates_its_fits_together_as_each_alone() {
        let lobes: Vec<(String, Lobe)> = (0..5)
            .map(|i| (format!("m{i}"), Lobe(0.5 + i as f64)))
            .collect();
        let basis = crate::brdf::basis::coarse_test_basis(&lobes, 4);
        let prior = NielsenPrior {
            basis: &basis,
            settings: NielsenSettings::default(),
        };
        let rows = basis.grid().bins();
        let sample = |i: usize, v: f64| Sample {
            bin: rows[i * 7 % rows.len()],
            reflectance: [v, 0.8 * v, 0.6 * v],
        };
        let a: Vec<Sample> = (0..12).map(|i| sample(i, 0.2 + 0.1 * i as f64)).collect();
        let b: Vec<Sample> = (0..12)
            .map(|i| sample(i + 5, 1.0 / (1.0 + i as f64)))
            .collect();
        let fa = prior.fit_lazy(&a, 4, 1.0).expect("fit a");
        let fb = prior.fit_lazy(&b, 3, 10.0).expect("fit b");
        let fc = prior.fit_lazy(&b, 4, 0.0).expect("fit c");
        // bins with a row, without one (below the horizon) and past the table
        let mut bins: Vec<usize> = (0..MERL_BINS).step_by(1013).collect();
        bins.push(MERL_BINS + 3);
        assert!(bins.iter().any(|&b| basis.grid().row_of_bin(b).is_none()));
        let check = |fits: &[&dyn Candidate]| {
            let together = prior.values_of_fits(fits, &bins);
            assert_eq!(together.len(), fits.len());
            for (f, values) in fits.iter().zip(&together) {
                let alone: Vec<[u64; 3]> = bins
                    .iter()
                    .map(|&b| f.eval_bin(b).map(f64::to_bits))
                    .collect();
                let got: Vec<[u64; 3]> = values.iter().map(|v| v.map(f64::to_bits)).collect();
                assert_eq!(got, alone);
            }
        };
        // the same k: evaluated together
        check(&[fa.as_ref(), fc.as_ref()]);
        // different k, or a candidate that is not this basis's fit: each alone, same values
        check(&[fa.as_ref(), fb.as_ref()]);
        let tabulated = Tabulated::of(fa.as_ref());
        check(&[&tabulated, fc.as_ref()]);
        for &bin in &bins {
            assert_eq!(tabulated.eval_bin(bin), fa.eval_bin(bin));
        }
    }
}
