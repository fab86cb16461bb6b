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
}
