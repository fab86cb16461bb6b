//! The PCA basis of measured BRDFs, built the way Nielsen, Jensen and Ramamoorthi (2015) build
//! it (METHOD.md section 5): the prior that optimal sampling and ridge reconstruction rely on.
//!
//! Conventions:
//! - Rows are a subsampled set of MERL bins (a [`BasisGrid`]): every `stride`-th bin along each
//!   axis, the middle bin of each block, kept only when both centre directions are above the
//!   horizon. Any full-resolution bin maps to the row of its block.
//! - Columns: one per (material, channel), materials sorted by name, channels R, G, B.
//! - Cosine map `c = clip(cos theta_i cos theta_o, 0.01, 1)` at the bin centre; mapped value
//!   `m = ln((rho c + eps) / (med + eps))`, eps = 0.001, `med` the per-row median of `rho c` over
//!   all columns; then the per-row mean of `m` is subtracted.
//! - `Q = M V` for the centred matrix `M` (rows x columns) and the eigenvectors `V` of the Gram
//!   matrix `M^T M`, sorted by decreasing eigenvalue: column `j` of `Q` is `sigma_j u_j`, the
//!   left singular vector scaled by its singular value. Entries of `Q` do not depend on how many
//!   rows the grid keeps, so the ridge weight (eta = 40) means the same at any resolution.
//!
//! Memory: `M` is rows x columns f32. At full resolution (1.10 M bins above the horizon x 300
//! columns) that is 1.25 GiB before the Gram products; the default stride (1, 2, 2) keeps every
//! `theta_h` bin (the specular peak lives in the first few) and halves `theta_d` and `phi_d`,
//! 272 k rows, 311 MiB for `M` and about 0.5 GiB at peak: well under 4 GiB, and a build of a few
//! seconds per core.
//!
//! Pure: materials come in as [`BinValues`]; the disk cache lives in `basis_cache.rs`. Must not
//! depend on sampling, reconstruction or any file.

use super::BinValues;
use super::coords::{MerlBin, PHI_D_BINS, THETA_D_BINS, THETA_H_BINS};
use nalgebra::{DMatrix, SymmetricEigen};
use rayon::prelude::*;

/// The epsilon of the log mapping (Nielsen et al.).
pub const MAP_EPS: f64 = 0.001;
/// The floor of the cosine map.
pub const COS_MAP_MIN: f64 = 0.01;

/// Keep every `n`-th bin along each axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct GridStride {
    pub theta_h: usize,
    pub theta_d: usize,
    pub phi_d: usize,
}

impl Default for GridStride {
    /// (1, 2, 2): see the module header for why.
    fn default() -> Self {
        Self {
            theta_h: 1,
            theta_d: 2,
            phi_d: 2,
        }
    }
}

/// How to build a basis.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct BasisSettings {
    pub stride: GridStride,
    /// Components kept (at most the number of columns).
    pub basis_components: usize,
    /// Materials left out: always the material being evaluated (leave-one-out).
    pub exclude: Vec<String>,
}

impl Default for BasisSettings {
    /// 64 components: reconstructions use k <= |S| components, and |S| stays well under 64 on
    /// the rig.
    fn default() -> Self {
        Self {
            stride: GridStride::default(),
            basis_components: 64,
            exclude: Vec::new(),
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum BasisError {
    #[error("stride {0:?} has a zero or exceeds the MERL grid")]
    BadStride(GridStride),
    #[error("material {0:?} is to be excluded but is not among the materials given (typo?)")]
    UnknownExcluded(String),
    #[error("a basis needs at least 2 materials, {0} left after exclusion")]
    TooFewMaterials(usize),
    #[error("material {name}: {got} values for {expected} basis bins")]
    WrongValueCount {
        name: String,
        got: usize,
        expected: usize,
    },
    #[error("a basis needs at least one component")]
    NoComponents,
    #[error("inconsistent basis parts: {0}")]
    Inconsistent(String),
}

/// The subsampled bins a basis lives on, and the map from full-resolution bins to rows.
#[derive(Clone, Debug, PartialEq)]
pub struct BasisGrid {
    stride: GridStride,
    dims: [usize; 3],
    /// MERL flat index of each row.
    bins: Vec<usize>,
    /// Per block (theta_h, theta_d, phi_d row-major): its row, or `u32::MAX` when the block's
    /// centre is below the horizon.
    block_rows: Vec<u32>,
}

impl BasisGrid {
    pub fn new(stride: GridStride) -> Result<Self, BasisError> {
        let ok = |s: usize, n: usize| s >= 1 && s <= n;
        if !(ok(stride.theta_h, THETA_H_BINS)
            && ok(stride.theta_d, THETA_D_BINS)
            && ok(stride.phi_d, PHI_D_BINS))
        {
            return Err(BasisError::BadStride(stride));
        }
        let dims = [
            THETA_H_BINS.div_ceil(stride.theta_h),
            THETA_D_BINS.div_ceil(stride.theta_d),
            PHI_D_BINS.div_ceil(stride.phi_d),
        ];
        let mut bins = Vec::new();
        let mut block_rows = vec![u32::MAX; dims[0] * dims[1] * dims[2]];
        for a in 0..dims[0] {
            for b in 0..dims[1] {
                for p in 0..dims[2] {
                    let bin = MerlBin {
                        theta_h: (a * stride.theta_h + stride.theta_h / 2).min(THETA_H_BINS - 1),
                        theta_d: (b * stride.theta_d + stride.theta_d / 2).min(THETA_D_BINS - 1),
                        phi_d: (p * stride.phi_d + stride.phi_d / 2).min(PHI_D_BINS - 1),
                    };
                    if bin.is_above_horizon() {
                        block_rows[(a * dims[1] + b) * dims[2] + p] = bins.len() as u32;
                        bins.push(bin.index());
                    }
                }
            }
        }
        Ok(Self {
            stride,
            dims,
            bins,
            block_rows,
        })
    }

    pub fn stride(&self) -> GridStride {
        self.stride
    }

    /// MERL flat index of each row.
    pub fn bins(&self) -> &[usize] {
        &self.bins
    }

    pub fn n_rows(&self) -> usize {
        self.bins.len()
    }

    fn block_of(&self, bin: MerlBin) -> [usize; 3] {
        [
            bin.theta_h / self.stride.theta_h,
            bin.theta_d / self.stride.theta_d,
            bin.phi_d / self.stride.phi_d,
        ]
    }

    /// The row standing for a full-resolution MERL bin (`None` when its block is below the
    /// horizon or the index is out of range).
    pub fn row_of_bin(&self, index: usize) -> Option<usize> {
        let bin = MerlBin::from_index(index)?;
        let [a, b, p] = self.block_of(bin);
        let r = self.block_rows[(a * self.dims[1] + b) * self.dims[2] + p];
        (r != u32::MAX).then_some(r as usize)
    }

    /// Rows of the blocks next to `row`'s block along each axis (up to 6; used by coordinate
    /// descent in sample selection).
    pub fn neighbours(&self, row: usize) -> Vec<usize> {
        let Some(bin) = self.bins.get(row).and_then(|&b| MerlBin::from_index(b)) else {
            return Vec::new();
        };
        let [a, b, p] = self.block_of(bin);
        let mut out = Vec::with_capacity(6);
        let mut push = |a: Option<usize>, b: Option<usize>, p: Option<usize>| {
            if let (Some(a), Some(b), Some(p)) = (a, b, p)
                && a < self.dims[0]
                && b < self.dims[1]
                && p < self.dims[2]
            {
                let r = self.block_rows[(a * self.dims[1] + b) * self.dims[2] + p];
                if r != u32::MAX {
                    out.push(r as usize);
                }
            }
        };
        push(a.checked_sub(1), Some(b), Some(p));
        push(Some(a + 1), Some(b), Some(p));
        push(Some(a), b.checked_sub(1), Some(p));
        push(Some(a), Some(b + 1), Some(p));
        // phi_d is periodic with period pi (reciprocity).
        let np = self.dims[2];
        push(Some(a), Some(b), Some((p + np - 1) % np));
        push(Some(a), Some(b), Some((p + 1) % np));
        out
    }
}

/// The cosine map at a bin: `clip(cos theta_i cos theta_o, 0.01, 1)` at its centre.
pub fn cos_map(bin: usize) -> f64 {
    match MerlBin::from_index(bin) {
        Some(b) => {
            let (ci, co) = b.centre_cosines();
            (ci * co).clamp(COS_MAP_MIN, 1.0)
        }
        None => COS_MAP_MIN,
    }
}

/// The PCA basis (see the module header).
#[derive(Clone, Debug, PartialEq)]
pub struct Basis {
    pub(super) settings: BasisSettings,
    /// Materials used, in column order (column = 3 * material + channel).
    pub(super) materials: Vec<String>,
    pub(super) grid: BasisGrid,
    pub(super) cos_map: Vec<f64>,
    /// Per-row median of `rho c` over the columns.
    pub(super) median: Vec<f64>,
    /// Per-row mean of the mapped values.
    pub(super) mean: Vec<f64>,
    /// Singular values, all of them (one per column), decreasing.
    pub(super) singular_values: Vec<f64>,
    /// Rows x k, row-major.
    pub(super) q: Vec<f32>,
    pub(super) k: usize,
}

impl Basis {
    /// Builds the basis from named materials, leaving out `settings.exclude`.
    pub fn build(
        settings: &BasisSettings,
        materials: &[(&str, &dyn BinValues)],
    ) -> Result<Self, BasisError> {
        if settings.basis_components == 0 {
            return Err(BasisError::NoComponents);
        }
        for name in &settings.exclude {
            if !materials.iter().any(|(n, _)| n == name) {
                return Err(BasisError::UnknownExcluded(name.clone()));
            }
        }
        let mut used: Vec<(&str, &dyn BinValues)> = materials
            .iter()
            .filter(|(n, _)| !settings.exclude.iter().any(|e| e == n))
            .copied()
            .collect();
        used.sort_by(|a, b| a.0.cmp(b.0));
        if used.len() < 2 {
            return Err(BasisError::TooFewMaterials(used.len()));
        }
        let grid = BasisGrid::new(settings.stride)?;
        let rows = grid.n_rows();
        let cols = 3 * used.len();
        let cos: Vec<f64> = grid.bins().par_iter().map(|&b| cos_map(b)).collect();

        // rho c, row-major rows x cols, f32 to halve the memory.
        let mut m = vec![0.0f32; rows * cols];
        for (mi, (name, src)) in used.iter().enumerate() {
            let v = src.values_at(grid.bins());
            if v.len() != rows {
                return Err(BasisError::WrongValueCount {
                    name: name.to_string(),
                    got: v.len(),
                    expected: rows,
                });
            }
            m.par_chunks_mut(cols)
                .zip(v.par_iter())
                .zip(cos.par_iter())
                .for_each(|((row, rgb), c)| {
                    for ch in 0..3 {
                        row[3 * mi + ch] = (rgb[ch].max(0.0) * c) as f32;
                    }
                });
        }

        // Log-relative mapping against the per-row median, then centre each row.
        let (median, mean): (Vec<f64>, Vec<f64>) = m
            .par_chunks_mut(cols)
            .map(|row| {
                let mut tmp: Vec<f64> = row.iter().map(|&x| f64::from(x)).collect();
                let med = crate::stats::median(&mut tmp).unwrap_or(f64::NAN);
                let mut sum = 0.0;
                for x in row.iter_mut() {
                    let mapped = ((f64::from(*x) + MAP_EPS) / (med + MAP_EPS)).ln();
                    *x = mapped as f32;
                    sum += mapped;
                }
                let mean = sum / cols as f64;
                for x in row.iter_mut() {
                    *x = (f64::from(*x) - mean) as f32;
                }
                (med, mean)
            })
            .unzip();

        // Gram matrix M^T M in f64, summed over blocks of rows.
        const BLOCK: usize = 4096;
        let gram = m
            .par_chunks(BLOCK * cols)
            .map(|chunk| {
                let n = chunk.len() / cols;
                let a = DMatrix::from_fn(n, cols, |i, j| f64::from(chunk[i * cols + j]));
                a.tr_mul(&a)
            })
            .reduce(|| DMatrix::zeros(cols, cols), |a, b| a + b);
        let eig = SymmetricEigen::new(gram);
        let mut order: Vec<usize> = (0..cols).collect();
        order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
        let singular_values: Vec<f64> = order
            .iter()
            .map(|&j| eig.eigenvalues[j].max(0.0).sqrt())
            .collect();
        let k = settings.basis_components.min(cols);
        let v_k = DMatrix::from_fn(cols, k, |i, j| eig.eigenvectors[(i, order[j])]);

        // Q = M V_k, by blocks of rows.
        let q: Vec<f32> = m
            .par_chunks(BLOCK * cols)
            .flat_map_iter(|chunk| {
                let n = chunk.len() / cols;
                let a = DMatrix::from_fn(n, cols, |i, j| f64::from(chunk[i * cols + j]));
                let p = a * &v_k;
                let mut out = Vec::with_capacity(n * k);
                for i in 0..n {
                    for j in 0..k {
                        out.push(p[(i, j)] as f32);
                    }
                }
                out.into_iter()
            })
            .collect();

        Ok(Self {
            settings: settings.clone(),
            materials: used.iter().map(|(n, _)| n.to_string()).collect(),
            grid,
            cos_map: cos,
            median,
            mean,
            singular_values,
            q,
            k,
        })
    }

    /// Checks that parts read back (from the cache) fit together.
    pub(super) fn validate(&self) -> Result<(), BasisError> {
        let rows = self.grid.n_rows();
        let bad = |what: &str| Err(BasisError::Inconsistent(what.to_string()));
        if self.cos_map.len() != rows || self.median.len() != rows || self.mean.len() != rows {
            return bad("per-row vectors do not match the grid");
        }
        if self.singular_values.len() != 3 * self.materials.len() {
            return bad("singular values do not match the materials");
        }
        if self.k > self.singular_values.len() || self.q.len() != rows * self.k {
            return bad("component matrix does not match the grid and k");
        }
        let finite = self
            .cos_map
            .iter()
            .chain(&self.median)
            .chain(&self.mean)
            .chain(&self.singular_values)
            .all(|x| x.is_finite())
            && self.q.iter().all(|x| x.is_finite());
        if !finite {
            return bad("non-finite values");
        }
        Ok(())
    }

    pub fn settings(&self) -> &BasisSettings {
        &self.settings
    }

    /// Materials in the basis, in column order.
    pub fn materials(&self) -> &[String] {
        &self.materials
    }

    pub fn grid(&self) -> &BasisGrid {
        &self.grid
    }

    pub fn n_rows(&self) -> usize {
        self.grid.n_rows()
    }

    /// Components stored.
    pub fn basis_components(&self) -> usize {
        self.k
    }

    /// Singular values of the centred mapped matrix, decreasing (one per column).
    pub fn singular_values(&self) -> &[f64] {
        &self.singular_values
    }

    /// `Q[row, comp]`.
    pub fn q(&self, row: usize, comp: usize) -> f64 {
        f64::from(self.q[row * self.k + comp])
    }

    /// The first `n` entries of a row of `Q`.
    pub fn q_row(&self, row: usize, n: usize) -> &[f32] {
        &self.q[row * self.k..row * self.k + n.min(self.k)]
    }

    pub fn cos_map(&self, row: usize) -> f64 {
        self.cos_map[row]
    }

    /// The centred mapped value of f_r `rho` at `row`: `ln((rho c + eps)/(med + eps)) - mean`.
    pub fn map(&self, row: usize, rho: f64) -> f64 {
        let c = self.cos_map[row];
        ((rho.max(0.0) * c + MAP_EPS) / (self.median[row] + MAP_EPS)).ln() - self.mean[row]
    }

    /// Inverse of [`Self::map`]: f_r from a centred mapped value, clamped at zero.
    pub fn unmap(&self, row: usize, mapped: f64) -> f64 {
        let c = self.cos_map[row];
        let x = (mapped + self.mean[row]).exp() * (self.median[row] + MAP_EPS) - MAP_EPS;
        (x / c).max(0.0)
    }

    /// Least-squares coefficients of a BRDF known at every row on the first `k` components,
    /// per channel: `x_j = (Q_j . m) / sigma_j^2` (the columns of `Q` are orthogonal).
    pub fn project(&self, rho: &[[f64; 3]], k: usize) -> [Vec<f64>; 3] {
        let k = k.min(self.k);
        let mut out = [vec![0.0; k], vec![0.0; k], vec![0.0; k]];
        for (row, v) in rho.iter().enumerate().take(self.n_rows()) {
            let qr = self.q_row(row, k);
            for ch in 0..3 {
                let m = self.map(row, v[ch]);
                for (o, q) in out[ch].iter_mut().zip(qr) {
                    *o += f64::from(*q) * m;
                }
            }
        }
        for ch in &mut out {
            for (j, x) in ch.iter_mut().enumerate() {
                let s2 = self.singular_values[j] * self.singular_values[j];
                *x = if s2 > 0.0 { *x / s2 } else { 0.0 };
            }
        }
        out
    }

    /// f_r at every row from per-channel coefficients (the inverse of [`Self::project`]).
    pub fn synthesize(&self, coeffs: &[Vec<f64>; 3]) -> Vec<[f64; 3]> {
        (0..self.n_rows())
            .into_par_iter()
            .map(|row| self.synthesize_row(coeffs, row))
            .collect()
    }

    /// Several fits' values at many rows: `synthesize_row` of each fit at each row, bit for
    /// bit, with each row of the basis read once for all the fits and the fits' sums run side
    /// by side (each still in the order of `synthesize_row`'s, so the processor can do several
    /// at once). Every fit must have the same number of coefficients in every channel; `None`
    /// otherwise. Returns, per fit, its values in the order of `rows`.
    pub fn synthesize_rows_many(
        &self,
        fits: &[&[Vec<f64>; 3]],
        rows: &[usize],
    ) -> Option<Vec<Vec<[f64; 3]>>> {
        let n = fits.first().map_or(0, |f| f[0].len());
        if fits.iter().any(|f| f.iter().any(|x| x.len() != n)) {
            return None;
        }
        let n = n.min(self.k);
        let cols = 3 * fits.len();
        // x[j * cols + 3 t + c]: coefficient j of fit t, channel c
        let mut x = vec![0.0; n * cols];
        for (t, f) in fits.iter().enumerate() {
            for (c, xc) in f.iter().enumerate() {
                for (j, v) in xc.iter().take(n).enumerate() {
                    x[j * cols + 3 * t + c] = *v;
                }
            }
        }
        let per_row: Vec<Vec<f64>> = rows
            .par_iter()
            .with_min_len(256)
            .map(|&row| {
                let mut m = vec![-0.0; cols];
                for (j, q) in self.q_row(row, n).iter().enumerate() {
                    let q = f64::from(*q);
                    for (acc, xj) in m.iter_mut().zip(&x[j * cols..(j + 1) * cols]) {
                        *acc += q * xj;
                    }
                }
                m.into_iter().map(|v| self.unmap(row, v)).collect()
            })
            .collect();
        Some(
            (0..fits.len())
                .map(|t| {
                    per_row
                        .iter()
                        .map(|m| [m[3 * t], m[3 * t + 1], m[3 * t + 2]])
                        .collect()
                })
                .collect(),
        )
    }

    /// f_r at one row from per-channel coefficients (what [`Self::synthesize`] gives there).
    pub fn synthesize_row(&self, coeffs: &[Vec<f64>; 3], row: usize) -> [f64; 3] {
        let [x0, x1, x2] = coeffs;
        if x0.len() == x1.len() && x1.len() == x2.len() {
            // One pass over the row for the three channels: three independent sums, each in the
            // order of the per-channel loop below (the same values, bit for bit), which the
            // processor overlaps instead of waiting on one chain of additions at a time.
            let qr = self.q_row(row, x0.len());
            let (mut m0, mut m1, mut m2) = (-0.0, -0.0, -0.0);
            for (j, q) in qr.iter().enumerate() {
                let q = f64::from(*q);
                m0 += q * x0[j];
                m1 += q * x1[j];
                m2 += q * x2[j];
            }
            return [
                self.unmap(row, m0),
                self.unmap(row, m1),
                self.unmap(row, m2),
            ];
        }
        let mut rgb = [0.0; 3];
        for (ch, x) in coeffs.iter().enumerate() {
            let qr = self.q_row(row, x.len());
            let m: f64 = qr.iter().zip(x).map(|(q, c)| f64::from(*q) * c).sum();
            rgb[ch] = self.unmap(row, m);
        }
        rgb
    }
}

/// For tests: a basis of `k` components on a coarse grid (every 3rd theta_h, 6th theta_d,
/// 12th phi_d bin) from named materials, built in a fraction of a second.
#[cfg(test)]
pub(crate) fn coarse_test_basis<T: BinValues>(materials: &[(String, T)], k: usize) -> Basis {
    let refs: Vec<(&str, &dyn BinValues)> = materials
        .iter()
        .map(|(n, m)| (n.as_str(), m as &dyn BinValues))
        .collect();
    let settings = BasisSettings {
        stride: GridStride {
            theta_h: 3,
            theta_d: 6,
            phi_d: 12,
        },
        basis_components: k,
        exclude: vec![],
    };
    Basis::build(&settings, &refs).expect("build a test basis")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::coords::MERL_BINS;

    /// A synthetic family of BRDFs: a Lambert term plus a Gaussian lobe in theta_h whose width
    /// and strength vary with the material.
    pub(crate) struct Toy {
        pub kd: f64,
        pub ks: f64,
        pub width: f64,
    }
    impl BinValues for Toy {
        fn values_at(&self, bins: &[usize]) -> Vec<[f64; 3]> {
            bins.iter()
                .map(|&b| {
                    let c = MerlBin::from_index(b).expect("bin").centre();
                    let s = self.ks * (-(c.theta_h / self.width).powi(2)).exp();
                    [self.kd + s, 0.8 * self.kd + s, 0.5 * self.kd + s]
                })
                .collect()
        }
    }

    fn toys() -> Vec<(String, Toy)> {
        (0..6)
            .map(|i| {
                let t = i as f64;
                (
                    format!("toy{i}"),
                    Toy {
                        kd: 0.05 + 0.03 * t,
                        ks: 0.5 + 2.0 * t,
                        width: 0.05 + 0.04 * t,
                    },
                )
            })
            .collect()
    }

    fn coarse() -> BasisSettings {
        BasisSettings {
            stride: GridStride {
                theta_h: 3,
                theta_d: 6,
                phi_d: 12,
            },
            basis_components: 12,
            exclude: vec![],
        }
    }

    fn refs(v: &[(String, Toy)]) -> Vec<(&str, &dyn BinValues)> {
        v.iter()
            .map(|(n, t)| (n.as_str(), t as &dyn BinValues))
            .collect()
    }

    #[test]
    fn grid_maps_every_bin_to_its_block_row() {
        let grid = BasisGrid::new(coarse().stride).expect("grid");
        for (row, &bin) in grid.bins().iter().enumerate() {
            assert_eq!(grid.row_of_bin(bin), Some(row));
            assert!(MerlBin::from_index(bin).expect("bin").is_above_horizon());
        }
        // A bin next to a kept one (same block) maps to the same row.
        let b = MerlBin::from_index(grid.bins()[10]).expect("bin");
        let nb = MerlBin {
            phi_d: b.phi_d + 1,
            ..b
        };
        assert_eq!(grid.row_of_bin(nb.index()), Some(10));
        assert_eq!(grid.row_of_bin(MERL_BINS), None);
        assert!(GridStride::default().theta_h == 1);
        assert!(
            BasisGrid::new(GridStride {
                theta_h: 0,
                theta_d: 1,
                phi_d: 1
            })
            .is_err()
        );
        // Neighbours are symmetric.
        for r in (0..grid.n_rows()).step_by(37) {
            for n in grid.neighbours(r) {
                assert!(grid.neighbours(n).contains(&r));
            }
        }
    }

    #[test]
    fn several_fits_synthesized_together_are_each_fit_alone_bit_for_bit() {
        let t = toys();
        let basis = coarse_test_basis(&t, 12);
        let fit = |seed: f64| -> [Vec<f64>; 3] {
            std::array::from_fn(|c| {
                (0..7)
                    .map(|j| ((seed + j as f64 * 1.7 + c as f64 * 0.3).sin()) * 0.8)
                    .collect()
            })
        };
        let fits: Vec<[Vec<f64>; 3]> = (0..4).map(|i| fit(i as f64)).collect();
        let refs: Vec<&[Vec<f64>; 3]> = fits.iter().collect();
        let rows: Vec<usize> = (0..basis.n_rows()).rev().step_by(3).collect();
        let together = basis
            .synthesize_rows_many(&refs, &rows)
            .expect("same lengths");
        assert_eq!(together.len(), fits.len());
        for (f, values) in fits.iter().zip(&together) {
            assert_eq!(values.len(), rows.len());
            for (&row, v) in rows.iter().zip(values) {
                let alone = basis.synthesize_row(f, row);
                assert_eq!(v.map(f64::to_bits), alone.map(f64::to_bits), "row {row}");
            }
        }
        // Fits of different lengths are not batched (the caller evaluates each alone).
        let mut short = fit(9.0);
        short[1].pop();
        assert!(
            basis
                .synthesize_rows_many(&[&fits[0], &short], &rows)
                .is_none()
        );
    }

    #[test]
    fn map_and_unmap_are_inverse() {
        let t = toys();
        let basis = coarse_test_basis(&t, 12);
        for row in (0..basis.n_rows()).step_by(101) {
            for rho in [0.0, 0.01, 0.3, 5.0, 400.0] {
                let back = basis.unmap(row, basis.map(row, rho));
                assert!((back - rho).abs() <= 1e-9 * (1.0 + rho), "{rho} {back}");
            }
        }
    }

    #[test]
    fn basis_matches_a_direct_svd_and_reproduces_its_materials() {
        let t = toys();
        let basis = coarse_test_basis(&t, 12);
        assert_eq!(basis.materials().len(), 6);
        // Second implementation: the singular values of M from nalgebra's SVD directly.
        let rows = basis.n_rows();
        let mut m = DMatrix::zeros(rows, 18);
        for (mi, (_, toy)) in t.iter().enumerate() {
            let v = toy.values_at(basis.grid().bins());
            for r in 0..rows {
                for ch in 0..3 {
                    m[(r, 3 * mi + ch)] = basis.map(r, v[r][ch]);
                }
            }
        }
        let svd = m.clone().svd(false, false);
        let mut sv: Vec<f64> = svd.singular_values.iter().copied().collect();
        sv.sort_by(|a, b| b.total_cmp(a));
        for (a, b) in sv.iter().zip(basis.singular_values()).take(8) {
            assert!((a - b).abs() <= 1e-4 * sv[0], "{a} vs {b}");
        }
        // The centred columns sum to zero in every row.
        for r in (0..rows).step_by(53) {
            let s: f64 = (0..18).map(|j| m[(r, j)]).sum();
            assert!(s.abs() < 1e-4, "{s}");
        }
        // With every component, a material of the basis is in the span: reproduced up to the
        // f32 storage of Q.
        let mut all = coarse();
        all.basis_components = 64;
        let basis = Basis::build(&all, &refs(&t)).expect("build");
        assert_eq!(basis.basis_components(), 18);
        let (_, toy) = &t[2];
        let truth = toy.values_at(basis.grid().bins());
        let rec = basis.synthesize(&basis.project(&truth, 18));
        let (mut num, mut den) = (0.0, 0.0);
        for (a, b) in truth.iter().zip(&rec) {
            for ch in 0..3 {
                num += (a[ch] - b[ch]).powi(2);
                den += a[ch] * a[ch];
            }
        }
        assert!((num / den).sqrt() < 1e-4, "{}", (num / den).sqrt());
    }

    #[test]
    fn exclusion_is_enforced() {
        let t = toys();
        let mut s = coarse();
        s.exclude = vec!["toy3".into()];
        let basis = Basis::build(&s, &refs(&t)).expect("build");
        assert!(!basis.materials().iter().any(|m| m == "toy3"));
        assert_eq!(basis.materials().len(), 5);
        s.basis_components = 0;
        assert!(matches!(
            Basis::build(&s, &refs(&t)),
            Err(BasisError::NoComponents)
        ));
        s.basis_components = 12;
        s.exclude = vec!["nope".into()];
        assert!(matches!(
            Basis::build(&s, &refs(&t)),
            Err(BasisError::UnknownExcluded(_))
        ));
    }
}
