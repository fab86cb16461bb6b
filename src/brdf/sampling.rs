//! Optimal sample selection (Nielsen, Jensen, Ramamoorthi 2015; METHOD.md section 5): choose
//! basis rows `S` so that `Q[S, 0:n]`, `n = min(|S|, k)`, is as well conditioned as possible.
//!
//! For each size `|S| = 1..N` in turn: the first sample is the row whose first `k` components
//! have the largest norm; each further sample is the best of `n_random` random candidates; after
//! each addition, coordinate descent moves every sample to a neighbouring bin (one block along
//! any axis, `phi_d` periodic) while that lowers the condition number.
//!
//! The random candidates of a step are scored from one decomposition of the rows chosen so far
//! (`rank_one`: the same condition numbers as an SVD per candidate, at O(k^2) each).
//!
//! Candidates default to every basis row; on the rig they are the rows observed by reliable
//! pixels (the reconstruction picks among pixels), so every step, descent included, stays inside
//! the given candidate set. Seeded and deterministic. Pure: no files, no I/O; depends on the
//! basis only (not on the reconstruction, the materials or the rig).

use super::basis::Basis;
use super::rank_one::RowUpdate;
use nalgebra::DMatrix;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::collections::HashSet;

#[derive(Clone, Debug, PartialEq)]
pub struct SamplingSettings {
    /// Components considered (`k`); columns used are `min(|S|, k)`.
    pub k: usize,
    /// Random candidates tried for each new sample.
    pub n_random: usize,
    /// Passes of coordinate descent after each addition (stops early without improvement).
    pub descent_passes: usize,
    pub seed: u64,
}

impl Default for SamplingSettings {
    fn default() -> Self {
        Self {
            k: 20,
            n_random: 500,
            descent_passes: 4,
            seed: 0x5eed,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum SamplingError {
    #[error("asked for {wanted} samples but only {available} distinct candidate bins")]
    TooFewCandidates { wanted: usize, available: usize },
    #[error("candidate row {row} is outside the basis ({rows} rows)")]
    BadCandidate { row: usize, rows: usize },
    #[error("asked for zero samples")]
    Empty,
}

/// The condition number of `Q[rows, 0:n]` (2-norm); infinite when rank deficient.
pub fn condition_number(basis: &Basis, rows: &[usize], n: usize) -> f64 {
    let n = n.min(basis.basis_components());
    if rows.is_empty() || n == 0 {
        return f64::INFINITY;
    }
    let a = DMatrix::from_fn(rows.len(), n, |i, j| basis.q(rows[i], j));
    let sv = a.singular_values();
    let max = sv.max();
    let min = sv.min();
    if min > 0.0 && min.is_finite() {
        max / min
    } else {
        f64::INFINITY
    }
}

/// The first `n` entries of a row of `Q`, widened.
fn row_f64(basis: &Basis, row: usize, n: usize) -> Vec<f64> {
    basis.q_row(row, n).iter().map(|&x| f64::from(x)).collect()
}

/// `N` rows chosen among `candidates` (all rows when `None`), minimising
/// `cond(Q[S, 0:min(N, k)])`.
pub fn select_samples(
    basis: &Basis,
    n_samples: usize,
    candidates: Option<&[usize]>,
    settings: &SamplingSettings,
) -> Result<Vec<usize>, SamplingError> {
    select_samples_with(basis, n_samples, candidates, &[], settings)
}

/// As [`select_samples`], with rows that must be in `S` and never move (the paper's brightest
/// pixel, METHOD.md section 4). They come first in the result, replacing the largest-norm start;
/// they need not be among `candidates`. With more fixed rows than `n_samples`, all are returned.
pub fn select_samples_with(
    basis: &Basis,
    n_samples: usize,
    candidates: Option<&[usize]>,
    fixed: &[usize],
    settings: &SamplingSettings,
) -> Result<Vec<usize>, SamplingError> {
    if n_samples == 0 {
        return Err(SamplingError::Empty);
    }
    let rows = basis.n_rows();
    let mut pool: Vec<usize> = match candidates {
        Some(c) => c.to_vec(),
        None => (0..rows).collect(),
    };
    let mut fixed_rows: Vec<usize> = Vec::new();
    for &r in fixed {
        if !fixed_rows.contains(&r) {
            fixed_rows.push(r);
        }
    }
    if let Some(&row) = pool.iter().chain(&fixed_rows).find(|&&r| r >= rows) {
        return Err(SamplingError::BadCandidate { row, rows });
    }
    pool.extend(&fixed_rows);
    pool.sort_unstable();
    pool.dedup();
    if pool.len() < n_samples {
        return Err(SamplingError::TooFewCandidates {
            wanted: n_samples,
            available: pool.len(),
        });
    }
    let allowed: HashSet<usize> = pool.iter().copied().collect();
    let k = settings.k.min(basis.basis_components()).max(1);
    let mut rng = ChaCha8Rng::seed_from_u64(settings.seed);

    let norm = |r: usize| -> f64 {
        basis
            .q_row(r, k)
            .iter()
            .map(|&x| f64::from(x).powi(2))
            .sum()
    };
    let mut s = if fixed_rows.is_empty() {
        let first = pool
            .iter()
            .copied()
            .max_by(|&a, &b| norm(a).total_cmp(&norm(b)))
            .ok_or(SamplingError::Empty)?;
        vec![first]
    } else {
        fixed_rows.clone()
    };
    let n_fixed = if fixed_rows.is_empty() { 0 } else { s.len() };
    let mut chosen: HashSet<usize> = s.iter().copied().collect();

    while s.len() < n_samples {
        let n = (s.len() + 1).min(k);
        // Best of n_random random candidates (or all of them when the pool is small).
        let trial: Vec<usize> = if pool.len() - chosen.len() <= settings.n_random {
            pool.iter()
                .copied()
                .filter(|r| !chosen.contains(r))
                .collect()
        } else {
            let mut t = Vec::with_capacity(settings.n_random);
            while t.len() < settings.n_random {
                let r = pool[rng.gen_range(0..pool.len())];
                if !chosen.contains(&r) {
                    t.push(r);
                }
            }
            t
        };
        // cond([Q[S]; q_r]) for every candidate from one decomposition of Q[S]
        // (`rank_one`): the same values as `condition_number` of S plus r, at a fraction of
        // the cost.
        let current_rows: Vec<Vec<f64>> = s.iter().map(|&r| row_f64(basis, r, n)).collect();
        let refs: Vec<&[f64]> = current_rows.iter().map(Vec::as_slice).collect();
        let update = RowUpdate::new(&refs, n);
        let mut best = (f64::INFINITY, trial[0]);
        for &r in &trial {
            let c = update.condition_with(&row_f64(basis, r, n));
            if c < best.0 {
                best = (c, r);
            }
        }
        s.push(best.1);
        chosen.insert(best.1);

        // Coordinate descent over neighbouring bins, inside the candidate set.
        let mut current = condition_number(basis, &s, n);
        for _ in 0..settings.descent_passes {
            let mut improved = false;
            let mut order: Vec<usize> = (n_fixed..s.len()).collect();
            order.shuffle(&mut rng);
            for p in order {
                let old = s[p];
                for nb in basis.grid().neighbours(old) {
                    if !allowed.contains(&nb) || chosen.contains(&nb) {
                        continue;
                    }
                    s[p] = nb;
                    let c = condition_number(basis, &s, n);
                    if c < current {
                        current = c;
                        chosen.remove(&old);
                        chosen.insert(nb);
                        improved = true;
                        break;
                    }
                    s[p] = old;
                }
            }
            if !improved {
                break;
            }
        }
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::nbrdf::{self, Nbrdf};

    fn small_basis() -> Basis {
        let dir = nbrdf::default_dir();
        let names = [
            "blue-acrylic",
            "gold-paint",
            "pink-fabric",
            "teflon",
            "chrome",
            "green-latex",
            "black-oxidized-steel",
            "white-paint",
        ];
        let nets: Vec<(String, Nbrdf)> = names
            .iter()
            .map(|n| {
                let net = Nbrdf::load(&dir.join(format!("{n}.f32"))).expect("load");
                (n.to_string(), net)
            })
            .collect();
        crate::brdf::basis::coarse_test_basis(&nets, 12)
    }

    #[test]
    fn condition_number_of_known_matrices() {
        let basis = small_basis();
        // One row, one column: a 1x1 matrix has condition 1.
        assert!((condition_number(&basis, &[5], 1) - 1.0).abs() < 1e-12);
        // The same row twice with two columns: rank one.
        assert!(
            condition_number(&basis, &[5, 5], 2).is_infinite()
                || condition_number(&basis, &[5, 5], 2) > 1e6
        );
    }

    #[test]
    fn optimised_samples_beat_random_ones_and_respect_candidates() {
        let basis = small_basis();
        let settings = SamplingSettings {
            k: 10,
            n_random: 200,
            descent_passes: 3,
            seed: 7,
        };
        let s = select_samples(&basis, 10, None, &settings).expect("select");
        assert_eq!(s.len(), 10);
        let distinct: HashSet<_> = s.iter().collect();
        assert_eq!(distinct.len(), 10);
        let c_opt = condition_number(&basis, &s, 10);
        // Independent comparison: the median condition number of random 10-subsets.
        let mut rng = ChaCha8Rng::seed_from_u64(99);
        let mut random: Vec<f64> = (0..101)
            .map(|_| {
                let rows: Vec<usize> = (0..10).map(|_| rng.gen_range(0..basis.n_rows())).collect();
                condition_number(&basis, &rows, 10)
            })
            .collect();
        random.sort_by(f64::total_cmp);
        assert!(
            c_opt < random[50] / 10.0,
            "optimised {c_opt}, random median {}",
            random[50]
        );
        assert!(
            c_opt < random[0],
            "optimised {c_opt}, best random {}",
            random[0]
        );

        // Restricted to every third row: every sample comes from the set.
        let cands: Vec<usize> = (0..basis.n_rows()).step_by(3).collect();
        let s = select_samples(&basis, 8, Some(&cands), &settings).expect("select");
        assert!(s.iter().all(|r| r % 3 == 0));
        // Deterministic for a seed.
        let again = select_samples(&basis, 8, Some(&cands), &settings).expect("select");
        assert_eq!(s, again);
        assert!(matches!(
            select_samples(&basis, 5, Some(&[1, 2, 2, 3]), &settings),
            Err(SamplingError::TooFewCandidates { available: 3, .. })
        ));
        // Fixed rows stay, first and unmoved, even outside the candidates.
        let s = select_samples_with(&basis, 8, Some(&cands), &[1], &settings).expect("select");
        assert_eq!(s[0], 1);
        assert!(s[1..].iter().all(|r| r % 3 == 0));
    }
}
