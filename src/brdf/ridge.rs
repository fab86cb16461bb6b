//! Ridge reconstruction of a whole BRDF from a few observations (METHOD.md section 5).
//!
//! Per channel: `b_i = map(row_i, rho_i)` (the basis mapping, mean already subtracted),
//! `A = Q[rows, 0:n]` with `n = min(|S|, k)`, `x = (A^T A + eta I)^-1 A^T b` (eta = 40 as Nielsen
//! et al.), then every basis row is `Q[row, 0:n] x`, unmapped (which divides by the cosine map)
//! and clamped at zero. The result lives on the basis grid; [`Reconstruction::to_merl_table`]
//! spreads it to full resolution (each bin takes its block's row; blocks whose centre is below the
//! horizon get no data).
//!
//! Observations carry f_r in 1/sr (RGB, no cosine) at a basis row; several observations may
//! share a row. Pure: no files; depends on the basis only (not on sampling, images or the rig).

use super::BinValues;
use super::basis::{Basis, BasisGrid};
use super::coords::MERL_BINS;
use super::merl::MerlTable;
use nalgebra::{DMatrix, DVector};

/// Nielsen et al.'s ridge weight.
pub const DEFAULT_ETA: f64 = 40.0;

/// One measured value: f_r (1/sr, RGB) at a basis row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BasisSample {
    pub row: usize,
    pub rgb: [f64; 3],
}

impl BasisSample {
    /// An observation of f_r for the directions `(wi, wo)` (local frame), placed at the basis
    /// row of its MERL bin; `None` below the horizon or where the basis has no row.
    pub fn from_directions(
        basis: &Basis,
        wi: &nalgebra::Vector3<f64>,
        wo: &nalgebra::Vector3<f64>,
        rgb: [f64; 3],
    ) -> Option<Self> {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return None;
        }
        let row = basis.grid().row_of_bin(super::coords::merl_index(wi, wo))?;
        Some(Self { row, rgb })
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct RidgeSettings {
    /// Components at most (`k`); `min(|S|, k)` are used.
    pub k: usize,
    pub eta: f64,
}

impl Default for RidgeSettings {
    fn default() -> Self {
        Self {
            k: 20,
            eta: DEFAULT_ETA,
        }
    }
}

#[derive(Clone, Debug, thiserror::Error)]
pub enum RidgeError {
    #[error("no observations to reconstruct from")]
    Empty,
    #[error("observation row {row} is outside the basis ({rows} rows)")]
    BadRow { row: usize, rows: usize },
    #[error("observation at row {row} is not finite")]
    NonFinite { row: usize },
    #[error("the ridge system is singular (eta must be positive)")]
    Singular,
}

/// A reconstructed BRDF on the basis grid.
#[derive(Clone, Debug, PartialEq)]
pub struct Reconstruction {
    grid: BasisGrid,
    /// f_r at each basis row.
    values: Vec<[f64; 3]>,
    /// Per-channel coefficients on the first `n` components.
    coefficients: [Vec<f64>; 3],
}

/// Reconstructs per channel by ridge regression on the first `min(|S|, k)` components.
pub fn reconstruct(
    basis: &Basis,
    observations: &[BasisSample],
    settings: &RidgeSettings,
) -> Result<Reconstruction, RidgeError> {
    let coefficients = solve(basis, observations, settings)?;
    Ok(Reconstruction {
        grid: basis.grid().clone(),
        values: basis.synthesize(&coefficients),
        coefficients,
    })
}

/// The ridge coefficients alone (per channel, on the first `min(|S|, k)` components), without
/// synthesising every row: validation evaluates a fit at a few rows only
/// (`Basis::synthesize_row`).
pub fn solve(
    basis: &Basis,
    observations: &[BasisSample],
    settings: &RidgeSettings,
) -> Result<[Vec<f64>; 3], RidgeError> {
    NormalSystem::new(basis, observations, settings.k)?.solve(settings.k, settings.eta)
}

/// The normal equations of one set of observations on the first `n` components, built once:
/// a fit at any `k <= n` and any eta reads their leading block (`A^T A` restricted to the
/// first `k` components is the leading `k x k` block of the whole, and eta only adds to its
/// diagonal), so a grid of `(k, eta)` costs one product instead of one per point. The sums run
/// in another order than a column-by-column product: the coefficients agree to rounding (unit
/// test below to 1e-9; written tables to 3e-11 relative, docs/benchmarks-reconstruct.md).
pub struct NormalSystem {
    /// `A^T A` on the first `n` components.
    gram: DMatrix<f64>,
    /// `A^T b` per channel.
    rhs: [DVector<f64>; 3],
}

impl NormalSystem {
    /// The system for fits of at most `k_max` components (and at most one per observation).
    pub fn new(
        basis: &Basis,
        observations: &[BasisSample],
        k_max: usize,
    ) -> Result<Self, RidgeError> {
        if observations.is_empty() {
            return Err(RidgeError::Empty);
        }
        let rows = basis.n_rows();
        for o in observations {
            if o.row >= rows {
                return Err(RidgeError::BadRow { row: o.row, rows });
            }
            if !o.rgb.iter().all(|v| v.is_finite()) {
                return Err(RidgeError::NonFinite { row: o.row });
            }
        }
        let n = observations.len().min(k_max).min(basis.basis_components());
        // Row by row: each observation adds its row's outer product to the upper triangle
        // (contiguous, so it vectorises; a column-by-column product strides through `A`).
        let mut upper = vec![0.0; n * n];
        let mut rhs = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
        let mut q = vec![0.0; n];
        for o in observations {
            for (x, v) in q.iter_mut().zip(basis.q_row(o.row, n)) {
                *x = f64::from(*v);
            }
            for i in 0..n {
                let qi = q[i];
                for (g, qj) in upper[i * n + i..(i + 1) * n].iter_mut().zip(&q[i..]) {
                    *g += qi * qj;
                }
            }
            for (ch, r) in rhs.iter_mut().enumerate() {
                let b = basis.map(o.row, o.rgb[ch]);
                for (x, qi) in r.iter_mut().zip(&q) {
                    *x += qi * b;
                }
            }
        }
        let gram = DMatrix::from_fn(n, n, |i, j| upper[i.min(j) * n + i.max(j)]);
        Ok(Self {
            gram,
            rhs: rhs.map(DVector::from_vec),
        })
    }

    /// Per-channel coefficients on the first `min(k, n)` components with ridge weight `eta`.
    pub fn solve(&self, k: usize, eta: f64) -> Result<[Vec<f64>; 3], RidgeError> {
        let n = k.min(self.gram.nrows());
        let mut normal = self.gram.view((0, 0), (n, n)).into_owned();
        for j in 0..n {
            normal[(j, j)] += eta;
        }
        let chol = normal.cholesky().ok_or(RidgeError::Singular)?;
        Ok(std::array::from_fn(|ch| {
            chol.solve(&self.rhs[ch].rows(0, n).into_owned())
                .iter()
                .copied()
                .collect()
        }))
    }
}

impl Reconstruction {
    /// f_r at each basis row (row order of the basis grid).
    pub fn values(&self) -> &[[f64; 3]] {
        &self.values
    }

    /// Per-channel coefficients on the first components.
    pub fn coefficients(&self) -> &[Vec<f64>; 3] {
        &self.coefficients
    }

    pub fn grid(&self) -> &BasisGrid {
        &self.grid
    }

    /// f_r at a full-resolution MERL bin: the value of its block's row.
    pub fn value_at_bin(&self, bin: usize) -> Option<[f64; 3]> {
        self.grid.row_of_bin(bin).map(|r| self.values[r])
    }

    /// A full MERL table (nearest basis row per bin; no data where the block is below the
    /// horizon).
    pub fn to_merl_table(&self) -> MerlTable {
        MerlTable::from_fn(|bin| self.value_at_bin(bin.index()))
    }
}

impl super::Brdf for Reconstruction {
    /// The value of the basis row holding the bin of `(wi, wo)`; zero below the horizon and
    /// where the grid has no row. Lets trial selection render with a candidate directly.
    fn eval_local(&self, wi: &nalgebra::Vector3<f64>, wo: &nalgebra::Vector3<f64>) -> [f64; 3] {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return [0.0; 3];
        }
        self.value_at_bin(super::coords::merl_index(wi, wo))
            .unwrap_or([0.0; 3])
    }
}

impl BinValues for Reconstruction {
    fn values_at(&self, bins: &[usize]) -> Vec<[f64; 3]> {
        bins.iter()
            .map(|&b| {
                if b < MERL_BINS {
                    self.value_at_bin(b).unwrap_or([0.0; 3])
                } else {
                    [0.0; 3]
                }
            })
            .collect()
    }
}

#[cfg(test)]
// Per-channel loops compare several arrays at the same index.
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;
    use crate::brdf::nbrdf::{self, Nbrdf};

    fn nets(names: &[&str]) -> Vec<(String, Nbrdf)> {
        let dir = nbrdf::default_dir();
        names
            .iter()
            .map(|n| {
                let net = Nbrdf::load(&dir.join(format!("{n}.f32"))).expect("load");
                (n.to_string(), net)
            })
            .collect()
    }

    fn basis(nets: &[(String, Nbrdf)], k: usize) -> Basis {
        crate::brdf::basis::coarse_test_basis(nets, k)
    }

    #[test]
    fn ridge_matches_its_closed_form_with_all_rows_and_small_eta() {
        // With every row observed, A^T A = diag(sigma^2): ridge is the projection shrunk by
        // sigma^2 / (sigma^2 + eta), a closed form independent of the solver.
        let n = nets(&[
            "blue-acrylic",
            "gold-paint",
            "pink-fabric",
            "teflon",
            "chrome",
        ]);
        let b = basis(&n, 8);
        let truth = n[1].1.values_at(b.grid().bins());
        let obs: Vec<BasisSample> = truth
            .iter()
            .enumerate()
            .map(|(row, &rgb)| BasisSample { row, rgb })
            .collect();
        let settings = RidgeSettings { k: 8, eta: 40.0 };
        let rec = reconstruct(&b, &obs, &settings).expect("ridge");
        let proj = b.project(&truth, 8);
        for ch in 0..3 {
            for j in 0..8 {
                let s2 = b.singular_values()[j].powi(2);
                let want = proj[ch][j] * s2 / (s2 + 40.0);
                let got = rec.coefficients()[ch][j];
                assert!(
                    (got - want).abs() <= 1e-4 * (want.abs() + 1e-3),
                    "{ch} {j}: {got} vs {want}"
                );
            }
        }
        // A material of the basis (5 materials, 15 columns, rank <= 14) with 14 components
        // and a tiny eta is reproduced almost exactly from all rows.
        let b = basis(&n, 14);
        let settings = RidgeSettings { k: 14, eta: 1e-9 };
        let rec = reconstruct(&b, &obs, &settings).expect("ridge");
        for (t, r) in truth.iter().zip(rec.values()) {
            for ch in 0..3 {
                assert!((t[ch] - r[ch]).abs() <= 1e-3 * t[ch] + 1e-5, "{t:?} {r:?}");
            }
        }
    }

    #[test]
    fn one_normal_system_solves_every_k_and_eta_as_a_fit_built_for_it() {
        // The textbook ridge on the first k columns, built from scratch for each (k, eta),
        // against the leading blocks of one system built for the largest k.
        let n = nets(&["blue-acrylic", "gold-paint", "pink-fabric", "teflon"]);
        let b = basis(&n, 10);
        let truth = n[2].1.values_at(b.grid().bins());
        let obs: Vec<BasisSample> = (0..b.n_rows())
            .step_by(7)
            .map(|row| BasisSample {
                row,
                rgb: truth[row],
            })
            .collect();
        let system = NormalSystem::new(&b, &obs, 10).expect("system");
        for k in [1, 4, 10] {
            for eta in [1e-3, 1.0, 40.0] {
                let a = DMatrix::from_fn(obs.len(), k, |i, j| b.q(obs[i].row, j));
                let mut normal = a.tr_mul(&a);
                for j in 0..k {
                    normal[(j, j)] += eta;
                }
                let got = system.solve(k, eta).expect("solve");
                for ch in 0..3 {
                    let y = DVector::from_fn(obs.len(), |i, _| b.map(obs[i].row, obs[i].rgb[ch]));
                    let want = normal.clone().lu().solve(&a.tr_mul(&y)).expect("lu");
                    assert_eq!(got[ch].len(), k);
                    for j in 0..k {
                        assert!(
                            (got[ch][j] - want[j]).abs() <= 1e-9 * (want[j].abs() + 1.0),
                            "k {k} eta {eta} ch {ch} j {j}: {} vs {}",
                            got[ch][j],
                            want[j]
                        );
                    }
                }
            }
        }
        // At most one component per observation.
        assert_eq!(
            NormalSystem::new(&b, &obs[..3], 10)
                .unwrap()
                .solve(10, 1.0)
                .unwrap()[0]
                .len(),
            3
        );
    }

    #[test]
    fn full_table_takes_each_blocks_row() {
        let n = nets(&["blue-acrylic", "gold-paint", "pink-fabric"]);
        let b = basis(&n, 4);
        let truth = n[0].1.values_at(b.grid().bins());
        let obs: Vec<BasisSample> = (0..b.n_rows())
            .step_by(50)
            .map(|row| BasisSample {
                row,
                rgb: truth[row],
            })
            .collect();
        let rec = reconstruct(&b, &obs, &RidgeSettings::default()).expect("ridge");
        let table = rec.to_merl_table();
        for (row, &bin) in b.grid().bins().iter().enumerate().step_by(17) {
            let got = table.get(bin).expect("data");
            for ch in 0..3 {
                assert!((got[ch] - rec.values()[row][ch]).abs() <= 1e-12 * got[ch].max(1.0));
            }
        }
        assert!(matches!(
            reconstruct(&b, &[], &RidgeSettings::default()),
            Err(RidgeError::Empty)
        ));
        // Directions land on the row of their bin.
        let bin = b.grid().bins()[123];
        let (wi, wo) = crate::brdf::coords::MerlBin::from_index(bin)
            .expect("bin")
            .centre()
            .to_directions();
        let o = BasisSample::from_directions(&b, &wi, &wo, [1.0; 3]).expect("row");
        assert_eq!(o.row, 123);
        use crate::brdf::Brdf;
        assert_eq!(rec.eval_local(&wi, &wo), rec.values()[123]);
        let below = nalgebra::Vector3::new(0.0, 0.6, -0.8);
        assert!(BasisSample::from_directions(&b, &below, &wo, [1.0; 3]).is_none());
        let bad = [BasisSample {
            row: b.n_rows(),
            rgb: [0.0; 3],
        }];
        assert!(matches!(
            reconstruct(&b, &bad, &RidgeSettings::default()),
            Err(RidgeError::BadRow { .. })
        ));
    }
}
