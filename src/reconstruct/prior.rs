//! What reconstruction needs from a BRDF prior: choose sample bins that make the basis
//! sub-matrix well conditioned, and fit a BRDF to reflectance samples with a given number of
//! components. The real prior is the Nielsen PCA basis (`brdf::basis`, `brdf::sampling`,
//! `brdf::ridge`, adapted in [`super::nielsen`]); tests also use small synthetic priors, so the
//! trial and component logic is checked against truths it cannot know.
//!
//! Convention: a bin is a flat MERL index (`brdf::coords`), reflectance is f_r in 1/sr, RGB.

use crate::brdf::basis::Basis;
use crate::brdf::coords::MERL_BINS;
use crate::brdf::merl::MerlTable;
use crate::brdf::ridge::RidgeError;
use rayon::prelude::*;

/// One reflectance sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub bin: usize,
    pub reflectance: [f64; 3],
}

/// A reconstructed BRDF, evaluated per MERL bin.
pub trait Candidate: Send + Sync {
    /// f_r at the centre of a bin, RGB, 1/sr.
    fn eval_bin(&self, bin: usize) -> [f64; 3];

    /// The full MERL table (every bin evaluated; a prior on a coarser grid overrides this).
    fn to_merl_table(&self) -> MerlTable {
        MerlTable::from_fn(|b| Some(self.eval_bin(b.index())))
    }

    /// A fit of a basis: the basis and its per-channel coefficients (what
    /// [`Prior::values_of_fits`] can evaluate for several fits at once); `None` for any other
    /// candidate.
    fn basis_fit(&self) -> Option<(&Basis, &[Vec<f64>; 3])> {
        None
    }

    /// The values at many bins (what [`CandidateValues`] reads): `eval_bin` at each (in
    /// parallel), unless a candidate knows a cheaper way to the same values.
    fn values_at_bins(&self, bins: &[usize]) -> Vec<[f64; 3]> {
        bins.par_iter()
            .with_min_len(4096)
            .map(|&b| self.eval_bin(b))
            .collect()
    }
}

/// A candidate's values at every MERL bin, evaluated once: bit for bit its `eval_bin`, for a
/// model that several table-making steps read in turn (the analytic prior the plausibility
/// steps shrink towards is read by three of them per material).
pub struct Tabulated(Vec<[f64; 3]>);

impl Tabulated {
    /// `c.eval_bin` at every bin, in parallel.
    pub fn of(c: &dyn Candidate) -> Self {
        Self(
            (0..MERL_BINS)
                .into_par_iter()
                .map(|i| c.eval_bin(i))
                .collect(),
        )
    }
}

impl Candidate for Tabulated {
    fn eval_bin(&self, bin: usize) -> [f64; 3] {
        self.0.get(bin).copied().unwrap_or([0.0; 3])
    }
}

/// A candidate seen as values at MERL bins (what metrics and renders read).
pub struct CandidateValues<'a>(pub &'a dyn Candidate);

impl crate::brdf::BinValues for CandidateValues<'_> {
    fn values_at(&self, bins: &[usize]) -> Vec<[f64; 3]> {
        self.0.values_at_bins(bins)
    }
}

/// A basis-backed prior.
pub trait Prior: Send + Sync {
    /// Components available (the largest k a fit may use).
    fn max_components(&self) -> usize;

    /// The basis row standing for a MERL bin (a basis may live on a coarser grid, so several
    /// bins share a row); `None` when the basis has no row for it (below the horizon).
    fn row_of(&self, bin: usize) -> Option<usize>;

    /// Extends `chosen` (rows already selected, in order, kept as the prefix) to at most `n`
    /// rows drawn from `candidates`, minimising the condition number of the basis sub-matrix
    /// on its first `min(|S|, k)` columns; returns the whole ordered list. `seed` drives the
    /// random candidate draws.
    fn select(
        &self,
        chosen: &[usize],
        candidates: &[usize],
        n: usize,
        k: usize,
        seed: u64,
    ) -> Vec<usize>;

    /// Fits a BRDF to the samples with the first `min(k, samples)` components and ridge
    /// weight `eta` (a prior without regularisation may ignore it).
    fn fit(&self, samples: &[Sample], k: usize, eta: f64)
    -> Result<Box<dyn Candidate>, RidgeError>;

    /// Several candidates' values at the same bins: each one's `values_at_bins`, unless the
    /// prior knows a cheaper way to the same values (a basis evaluates its own fits together).
    fn values_of_fits(&self, fits: &[&dyn Candidate], bins: &[usize]) -> Vec<Vec<[f64; 3]>> {
        fits.iter().map(|f| f.values_at_bins(bins)).collect()
    }

    /// The prior's typical material (a basis: its mean, every coefficient zero), if it has
    /// one.
    fn typical(&self) -> Option<Box<dyn Candidate + '_>> {
        None
    }

    /// [`Prior::fit_lazy`] at each `(k, eta)` of `keys`, in order, for the same samples (a prior
    /// may share the work between them: the Nielsen prior builds its normal equations once).
    fn fit_lazy_each<'a>(
        &'a self,
        samples: &[Sample],
        keys: &[(usize, f64)],
    ) -> Vec<Result<Box<dyn Candidate + 'a>, RidgeError>> {
        keys.iter()
            .map(|&(k, eta)| self.fit_lazy(samples, k, eta))
            .collect()
    }

    /// The same fit, for validation: the result is evaluated at a few bins only, so a prior may
    /// skip tabulating it (the Nielsen prior evaluates rows on demand).
    fn fit_lazy<'a>(
        &'a self,
        samples: &[Sample],
        k: usize,
        eta: f64,
    ) -> Result<Box<dyn Candidate + 'a>, RidgeError> {
        self.fit(samples, k, eta)
            .map(|c| c as Box<dyn Candidate + 'a>)
    }

    /// The MERL bin at the centre of a basis row (the bin whose value the basis holds for the
    /// whole row), when the prior lives on a grid of rows.
    fn row_centre(&self, _row: usize) -> Option<usize> {
        None
    }

    /// The reflectance a pixel lends its basis row's sample: its own (a prior that carries
    /// pixels to their row's centre overrides this; `CarriedPrior`).
    fn row_value(&self, o: &super::observe::Observation) -> [f64; 3] {
        o.reflectance
    }
}

/// The [`Prior`] methods a wrapper around `self.inner: &dyn Prior` passes on unchanged: its
/// components, rows, selection, several fits' values, typical material and row centres (a
/// wrapper changes what its fits are given, never the basis they live on). Used inside an
/// `impl Prior for` block; the wrapper writes `fit` and whatever else it changes.
macro_rules! delegate_prior {
    () => {
        fn max_components(&self) -> usize {
            self.inner.max_components()
        }

        fn row_of(&self, bin: usize) -> Option<usize> {
            self.inner.row_of(bin)
        }

        fn select(
            &self,
            chosen: &[usize],
            candidates: &[usize],
            n: usize,
            k: usize,
            seed: u64,
        ) -> Vec<usize> {
            self.inner.select(chosen, candidates, n, k, seed)
        }

        fn values_of_fits(
            &self,
            fits: &[&dyn $crate::reconstruct::prior::Candidate],
            bins: &[usize],
        ) -> Vec<Vec<[f64; 3]>> {
            self.inner.values_of_fits(fits, bins)
        }

        fn typical(&self) -> Option<Box<dyn $crate::reconstruct::prior::Candidate + '_>> {
            self.inner.typical()
        }

        fn row_centre(&self, row: usize) -> Option<usize> {
            self.inner.row_centre(row)
        }
    };
}
pub(crate) use delegate_prior;

/// A small synthetic prior for tests: K smooth functions of the `theta_h` bin, fitted by least
/// squares, selection in a seeded random order. The truths in tests are built from it, so the
/// logic above it is checked against values it cannot see.
#[cfg(test)]
pub mod synthetic {
    use super::*;
    use nalgebra::{DMatrix, DVector};
    use rand::SeedableRng;
    use rand::seq::SliceRandom;

    /// Test scenes: `count` pixels with normals spread over a cap, light and view fixed, and
    /// reflectance `truth(bin)` scaled per colour channel by `scale`.
    pub fn cap_pixels(
        truth: impl Fn(usize) -> f64,
        count: usize,
        scale: [f64; 3],
    ) -> Vec<crate::reconstruct::observe::Observation> {
        use nalgebra::Vector3;
        let l = Vector3::new(0.5, 0.0, 1.0).normalize();
        let v = Vector3::z();
        (0..count)
            .filter_map(|i| {
                let a = i as f64 * 2.399;
                let r = 0.6 * ((i as f64 + 0.5) / count as f64).sqrt();
                let n = Vector3::new(r * a.cos(), r * a.sin(), 1.0).normalize();
                let mut o = crate::reconstruct::observation::Observation::new(
                    crate::reconstruct::observation::Seen::pixel(0, i as u32, 0, n),
                    l,
                    v,
                    [1.0; 3],
                    [1.0; 3],
                )?;
                let f = truth(o.bin);
                o.reflectance = scale.map(|c| c * f);
                o.radiance = o.reflectance.map(|r| r * o.cos_theta_i);
                Some(o)
            })
            .collect()
    }

    pub struct CosinePrior {
        pub k: usize,
    }

    /// Basis function `j` at a bin: cos(j pi t), t = theta_h bin / 90.
    pub fn phi(j: usize, bin: usize) -> f64 {
        let t = (bin / (90 * 180)) as f64 / 90.0;
        (j as f64 * std::f64::consts::PI * t).cos()
    }

    pub struct Linear {
        pub coeffs: Vec<[f64; 3]>,
    }

    impl Candidate for Linear {
        fn eval_bin(&self, bin: usize) -> [f64; 3] {
            let mut out = [0.0; 3];
            for (j, c) in self.coeffs.iter().enumerate() {
                for ch in 0..3 {
                    out[ch] += c[ch] * phi(j, bin);
                }
            }
            out
        }
    }

    impl Prior for CosinePrior {
        fn max_components(&self) -> usize {
            self.k
        }

        fn row_of(&self, bin: usize) -> Option<usize> {
            Some(bin)
        }

        fn select(
            &self,
            chosen: &[usize],
            candidates: &[usize],
            n: usize,
            _k: usize,
            seed: u64,
        ) -> Vec<usize> {
            let mut rest: Vec<usize> = candidates
                .iter()
                .copied()
                .filter(|c| !chosen.contains(c))
                .collect();
            rest.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(seed));
            chosen
                .iter()
                .copied()
                .chain(rest)
                .take(n.max(chosen.len()))
                .collect()
        }

        fn fit(
            &self,
            samples: &[Sample],
            k: usize,
            _eta: f64,
        ) -> Result<Box<dyn Candidate>, RidgeError> {
            let k = k.min(samples.len()).min(self.k);
            if k == 0 {
                return Err(RidgeError::Empty);
            }
            let a = DMatrix::from_fn(samples.len(), k, |i, j| phi(j, samples[i].bin));
            let ata = a.transpose() * &a + DMatrix::identity(k, k) * 1e-9;
            let chol = ata.cholesky().ok_or(RidgeError::Singular)?;
            let mut coeffs = vec![[0.0; 3]; k];
            for ch in 0..3 {
                let b = DVector::from_fn(samples.len(), |i, _| samples[i].reflectance[ch]);
                let x = chol.solve(&(a.transpose() * b));
                for (c, xj) in coeffs.iter_mut().zip(x.iter()) {
                    c[ch] = *xj;
                }
            }
            Ok(Box::new(Linear { coeffs }))
        }
    }
}
