//! The condition number of a matrix with one more row, for many candidate rows at once: the
//! optimal sampling (`sampling`) scores every candidate row by `cond([A; r])`, and a full
//! singular value decomposition per candidate was two thirds of a reconstruction's time
//! (docs/benchmarks-reconstruct.md, "Sample selection").
//!
//! `[A; r]^T [A; r] = A^T A + r r^T`. With `A^T A = V diag(lambda) V^T` (one SVD of `A` per
//! step, shared by every candidate), the eigenvalues of the update are those of
//! `diag(lambda) + z z^T`, `z = V^T r`: the roots of the secular equation
//! `1 + sum_i z_i^2 / (lambda_i - mu) = 0` (Golub 1973), which interlace the `lambda_i`. Only the
//! smallest and the largest are needed; each is found by bisection in O(n) per step, so a
//! candidate costs O(n^2) (the product `V^T r`) instead of an SVD's O(m n^2).
//!
//! Pure: no I/O; knows nothing of BRDFs or bases (rows are plain slices).

use nalgebra::DMatrix;

/// The spectrum of `A^T A` for a fixed `A` (m x n), ready to score `[A; r]` for any row `r`.
pub struct RowUpdate {
    /// Eigenvalues of `A^T A`, ascending, never negative.
    lambda: Vec<f64>,
    /// Eigenvectors as rows (`vt[i]` belongs to `lambda[i]`), each of length n.
    vt: Vec<Vec<f64>>,
}

impl RowUpdate {
    /// From the rows of `A` (each at least `n` long; only the first `n` entries are read).
    pub fn new(rows: &[&[f64]], n: usize) -> Self {
        // Padded with zero rows to at least n x n so the SVD returns every right singular
        // vector, the null space of A included (a candidate row may fill it).
        let m = rows.len().max(n);
        let a = DMatrix::from_fn(m, n, |i, j| rows.get(i).map_or(0.0, |r| r[j]));
        let svd = a.svd(false, true);
        let mut pairs: Vec<(f64, Vec<f64>)> = match svd.v_t {
            Some(vt) => (0..n)
                .map(|i| {
                    let s = svd.singular_values[i];
                    (s * s, (0..n).map(|j| vt[(i, j)]).collect())
                })
                .collect(),
            None => Vec::new(),
        };
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (lambda, vt) = pairs.into_iter().unzip();
        Self { lambda, vt }
    }

    /// `cond([A; r])` in the 2-norm (the square root of the extreme eigenvalues' ratio);
    /// infinite when `[A; r]` is rank deficient or the decomposition failed.
    pub fn condition_with(&self, row: &[f64]) -> f64 {
        let n = self.lambda.len();
        if n == 0 {
            return f64::INFINITY;
        }
        let w: Vec<f64> = self
            .vt
            .iter()
            .map(|v| {
                let z: f64 = v.iter().zip(row).map(|(a, b)| a * b).sum();
                z * z
            })
            .collect();
        let total: f64 = w.iter().sum();
        let secular = Secular {
            lambda: &self.lambda,
            w: &w,
        };
        let lambda = &self.lambda;
        // Smallest eigenvalue: the first root above lambda_1, or lambda_2 when the root lies
        // beyond it (a deflated lambda_2 stays an eigenvalue), never above lambda_1 + |z|^2.
        let upper = if n >= 2 {
            lambda[1].min(lambda[0] + total)
        } else {
            lambda[0] + total
        };
        let min = if w[0] > 0.0 {
            secular.lowest_nonnegative(0, upper)
        } else {
            lambda[0]
        };
        // Largest: the root above lambda_n, at most lambda_n + |z|^2 (where the equation is
        // already non-negative).
        let max = match (0..n).rev().find(|&i| w[i] > 0.0) {
            // No weight: the row is zero and A's spectrum stands.
            None => lambda[n - 1],
            // Above the top eigenvalue with weight, the last root; above lambda_n if f is
            // already non-negative there (w_n = 0: lambda_n stays the largest).
            Some(p) => secular
                .lowest_nonnegative(p, lambda[n - 1] + total)
                .max(lambda[n - 1]),
        };
        if min > 0.0 && max.is_finite() {
            (max / min).sqrt()
        } else {
            f64::INFINITY
        }
    }
}

/// `f(mu) = 1 + sum_i w_i / (lambda_i - mu)`, increasing between its poles.
struct Secular<'a> {
    lambda: &'a [f64],
    w: &'a [f64],
}

impl Secular<'_> {
    /// `F(mu) = (mu - lambda_p) f(mu)` with the pole `p` removed, and `F'(mu)`: the same sign as
    /// `f` above `lambda_p`, and smooth there, so Newton's method converges on it where it
    /// crawls on `f` (Bunch, Nielsen and Sorensen 1978 use the same idea).
    fn eval(&self, mu: f64, p: usize) -> (f64, f64) {
        let (mut phi, mut dphi) = (1.0, 0.0);
        for (i, (l, w)) in self.lambda.iter().zip(self.w).enumerate() {
            if i != p && *w > 0.0 {
                let d = 1.0 / (l - mu);
                phi += w * d;
                dphi += w * d * d;
            }
        }
        let t = mu - self.lambda[p];
        (t * phi - self.w[p], phi + t * dphi)
    }

    /// The smallest `mu` in `[lambda_p, hi]` where `f` is non-negative (`hi` when none is
    /// below it), `w_p > 0`: Newton's method on `F` kept inside the bracket, bisecting (in
    /// ratio once the bracket is positive, so a root orders of magnitude below `hi` is found to
    /// relative precision) when a step would leave the bracket or did not halve the step
    /// before the last (as in Numerical Recipes' `rtsafe`).
    fn lowest_nonnegative(&self, p: usize, mut hi: f64) -> f64 {
        let mut lo = self.lambda[p];
        let mut x = hi;
        let (mut f, mut df) = self.eval(x, p);
        if f < 0.0 {
            return hi;
        }
        let mut step_before = hi - lo;
        let mut step = step_before;
        for _ in 0..200 {
            if hi - lo <= 4.0 * f64::EPSILON * hi.abs() {
                break;
            }
            let newton = x - f / df;
            // Converged: Newton's step no longer moves the estimate (it would sit on a side of
            // the bracket, which the test below refuses).
            if f == 0.0 || (f / df).abs() <= 4.0 * f64::EPSILON * x.abs() {
                return x;
            }
            let next = if newton.is_finite()
                && newton > lo
                && newton < hi
                && (f / df).abs() <= 0.5 * step_before.abs()
            {
                newton
            } else if lo > 0.0 && hi > 4.0 * lo {
                (lo * hi).sqrt()
            } else {
                0.5 * (lo + hi)
            };
            if next <= lo || next >= hi {
                break;
            }
            step_before = step;
            step = next - x;
            (f, df) = self.eval(next, p);
            x = next;
            if f < 0.0 {
                lo = next;
            } else {
                hi = next;
            }
            if step.abs() <= 4.0 * f64::EPSILON * x.abs() {
                break;
            }
        }
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The reference: the SVD of the whole stacked matrix.
    fn reference(rows: &[Vec<f64>], extra: &[f64], n: usize) -> f64 {
        let m = rows.len() + 1;
        let a = DMatrix::from_fn(
            m,
            n,
            |i, j| if i < rows.len() { rows[i][j] } else { extra[j] },
        );
        let sv = a.singular_values();
        let (max, min) = (sv.max(), sv.min());
        if min > 0.0 { max / min } else { f64::INFINITY }
    }

    fn random_rows(rng: &mut ChaCha8Rng, m: usize, n: usize) -> Vec<Vec<f64>> {
        (0..m)
            .map(|_| (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect())
            .collect()
    }

    #[test]
    fn matches_the_svd_of_the_stacked_matrix() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        // Tall, square-after-the-row (the sampling's growing phase: s rows, s + 1 columns),
        // and a single row.
        for &(m, n) in &[(30, 12), (11, 12), (1, 2), (0, 1), (79, 40)] {
            let rows = random_rows(&mut rng, m, n);
            let refs: Vec<&[f64]> = rows.iter().map(Vec::as_slice).collect();
            let update = RowUpdate::new(&refs, n);
            for _ in 0..20 {
                let r: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
                let fast = update.condition_with(&r);
                let exact = reference(&rows, &r, n);
                assert!(
                    (fast - exact).abs() <= 1e-8 * exact,
                    "{m}x{n}: {fast} against {exact}"
                );
            }
        }
    }

    #[test]
    fn ill_conditioned_rows_keep_relative_precision() {
        // Columns scaled over eight orders of magnitude: condition numbers near 1e8.
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let n = 6;
        let scale = |j: usize| 10f64.powi(-(j as i32) * 3 / 2);
        let rows: Vec<Vec<f64>> = (0..20)
            .map(|_| {
                (0..n)
                    .map(|j| rng.gen_range(-1.0..1.0) * scale(j))
                    .collect()
            })
            .collect();
        let refs: Vec<&[f64]> = rows.iter().map(Vec::as_slice).collect();
        let update = RowUpdate::new(&refs, n);
        for _ in 0..10 {
            let r: Vec<f64> = (0..n)
                .map(|j| rng.gen_range(-1.0..1.0) * scale(j))
                .collect();
            let (fast, exact) = (update.condition_with(&r), reference(&rows, &r, n));
            assert!(exact > 1e5, "the case is ill conditioned: {exact}");
            assert!(
                (fast - exact).abs() <= 1e-6 * exact,
                "{fast} against {exact}"
            );
        }
    }

    #[test]
    fn rank_deficiency_is_infinite_and_a_filling_row_is_not() {
        // Two rows in three columns: the third direction is empty.
        let rows = [vec![1.0, 0.0, 0.0], vec![0.0, 2.0, 0.0]];
        let refs: Vec<&[f64]> = rows.iter().map(Vec::as_slice).collect();
        let update = RowUpdate::new(&refs, 3);
        assert!(update.condition_with(&[1.0, 1.0, 0.0]).is_infinite());
        // A row along the empty direction: singular values 1, 2, 4.
        let c = update.condition_with(&[0.0, 0.0, 4.0]);
        assert!((c - 4.0).abs() < 1e-12, "{c}");
        // The row repeats an existing direction: singular values sqrt(2), 2 and 0.
        let one = RowUpdate::new(&[&[1.0, 0.0][..]], 2);
        assert!(one.condition_with(&[1.0, 0.0]).is_infinite());
    }
}
