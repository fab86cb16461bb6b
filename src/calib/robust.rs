//! Robust statistics shared by the calibration steps: median, MAD-based sigma and a mean that
//! rejects outliers (dust, hot pixels, glints) before averaging.
//!
//! The median itself is `crate::stats::median`, shared with the reconstruction.
//!
//! Conventions: `mad_sigma` is scaled by 1.4826 so it estimates the standard deviation of
//! Gaussian data. Pure: no I/O.

use crate::stats::median;

/// 1.4826 times the median absolute deviation from `centre`: a standard deviation that a few
/// outliers cannot inflate.
pub fn mad_sigma(values: &[f64], centre: f64) -> Option<f64> {
    let mut dev: Vec<f64> = values.iter().map(|v| (v - centre).abs()).collect();
    median(&mut dev).map(|m| 1.4826 * m)
}

/// The result of [`robust_mean`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RobustMean {
    pub mean: f64,
    /// Standard deviation of the kept values.
    pub std_dev: f64,
    /// Standard error of `mean` (std_dev / sqrt(kept)).
    pub std_error: f64,
    pub kept: usize,
    pub rejected: usize,
}

/// Mean of the values within `k` MAD-sigmas of the median. When the MAD is zero (quantised or
/// constant data) values equal to the median are kept. `None` when nothing is left.
pub fn robust_mean(values: &[f64], k: f64) -> Option<RobustMean> {
    let mut sorted = values.to_vec();
    let med = median(&mut sorted)?;
    let sigma = mad_sigma(values, med)?;
    let tol = k * sigma;
    let kept: Vec<f64> = values
        .iter()
        .copied()
        .filter(|v| (v - med).abs() <= tol)
        .collect();
    if kept.is_empty() {
        return None;
    }
    let n = kept.len() as f64;
    let mean = kept.iter().sum::<f64>() / n;
    let var = if kept.len() > 1 {
        kept.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)
    } else {
        0.0
    };
    Some(RobustMean {
        mean,
        std_dev: var.sqrt(),
        std_error: (var / n).sqrt(),
        kept: kept.len(),
        rejected: values.len() - kept.len(),
    })
}

/// The value at the centroid of scattered samples `(x, y, v)` of a smooth surface (a board under
/// a light that falls off across it), robustly: a quadratic in `x` and `y` fitted by least
/// squares to the values within `k` MAD-sigmas of the median, then refitted twice to those within
/// `k` MAD-sigmas of the fit (dust, hot pixels, glints). For a flat surface it is the mean of the
/// kept values; unlike the mean it is not pulled by a curved falloff. `std_dev` is the residual
/// scatter, `std_error` the fitted centre's. Falls back to [`robust_mean`] with fewer than 30
/// samples or a degenerate layout (a single row). `None` when nothing is left.
pub fn robust_surface_centre(samples: &[(f64, f64, f64)], k: f64) -> Option<RobustMean> {
    let values: Vec<f64> = samples.iter().map(|s| s.2).collect();
    let first = robust_mean(&values, k)?;
    if samples.len() < 30 {
        return Some(first);
    }
    let n = samples.len() as f64;
    let (mx, my) = samples
        .iter()
        .fold((0.0, 0.0), |(a, b), s| (a + s.0 / n, b + s.1 / n));
    let half = samples
        .iter()
        .map(|s| (s.0 - mx).abs().max((s.1 - my).abs()))
        .fold(0.0, f64::max)
        .max(1.0);
    let row = |s: &(f64, f64, f64)| {
        let (u, v) = ((s.0 - mx) / half, (s.1 - my) / half);
        nalgebra::SVector::<f64, 6>::new(1.0, u, v, u * u, u * v, v * v)
    };
    let centre = |s: &(f64, f64, f64)| s.2;
    // the first cut: within k sigmas of the median, as the robust mean did
    let mut kept: Vec<bool> = {
        let mut sorted = values.clone();
        let med = median(&mut sorted)?;
        let sigma = mad_sigma(&values, med)?;
        values
            .iter()
            .map(|v| (v - med).abs() <= k * sigma)
            .collect()
    };
    let mut result = None;
    for _ in 0..3 {
        let mut ata = nalgebra::SMatrix::<f64, 6, 6>::zeros();
        let mut atb = nalgebra::SVector::<f64, 6>::zeros();
        for (s, _) in samples.iter().zip(&kept).filter(|(_, k)| **k) {
            let r = row(s);
            ata += r * r.transpose();
            atb += r * centre(s);
        }
        let Some(inv) = ata.try_inverse() else {
            return Some(first);
        };
        let coef = inv * atb;
        let residuals: Vec<f64> = samples
            .iter()
            .map(|s| centre(s) - row(s).dot(&coef))
            .collect();
        let kept_res: Vec<f64> = residuals
            .iter()
            .zip(&kept)
            .filter(|(_, k)| **k)
            .map(|(r, _)| *r)
            .collect();
        let used = kept_res.len();
        if used < 7 {
            return Some(first);
        }
        let var = kept_res.iter().map(|r| r * r).sum::<f64>() / (used - 6) as f64;
        result = Some(RobustMean {
            mean: coef[0],
            std_dev: var.sqrt(),
            std_error: (var * inv[(0, 0)]).max(0.0).sqrt(),
            kept: used,
            rejected: samples.len() - used,
        });
        // a noiseless surface leaves rounding-level residuals: keep those
        let tol = (k * mad_sigma(&kept_res, 0.0)?).max(1e-9 * coef[0].abs() + 1e-300);
        kept = residuals.iter().map(|r| r.abs() <= tol).collect();
    }
    result
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    /// A board whose values fall off quadratically away from its centre, with dust: the fitted
    /// centre is the centre's value, where the mean is pulled down by the falloff.
    #[test]
    fn surface_centre_is_not_pulled_by_a_curved_falloff() {
        let mut s = Vec::new();
        for y in 0..40 {
            for x in 0..60 {
                let (u, v) = ((x as f64 - 29.5) / 30.0, (y as f64 - 19.5) / 30.0);
                let noise = 0.001 * (((x * 7 + y * 13) % 11) as f64 - 5.0);
                s.push((
                    x as f64,
                    y as f64,
                    1.0 - 0.06 * (u * u + v * v) + 0.02 * u + noise,
                ));
            }
        }
        s[100].2 = 0.1; // dust
        s[777].2 = 5.0; // a hot pixel
        let r = robust_surface_centre(&s, 3.5).unwrap();
        assert!((r.mean - 1.0).abs() < 5e-4, "{r:?}");
        assert!(r.rejected >= 2 && r.std_error < 1e-3);
        let values: Vec<f64> = s.iter().map(|s| s.2).collect();
        let mean = robust_mean(&values, 3.5).unwrap().mean;
        assert!(1.0 - mean > 0.01, "the plain mean is pulled down: {mean}");
        // a flat patch: the fit is the mean
        let flat: Vec<(f64, f64, f64)> = (0..100)
            .map(|i| ((i % 10) as f64, (i / 10) as f64, 0.25))
            .collect();
        let r = robust_surface_centre(&flat, 3.5).unwrap();
        assert!((r.mean - 0.25).abs() < 1e-12);
    }

    #[test]
    fn robust_mean_ignores_outliers_and_mad_matches_gaussian_sigma() {
        // values 0..=100 scaled, plus two wild outliers
        let mut v: Vec<f64> = (0..=100).map(|i| 10.0 + (i as f64 - 50.0) * 0.01).collect();
        v.push(1000.0);
        v.push(-1000.0);
        let r = robust_mean(&v, 3.0).unwrap();
        assert!((r.mean - 10.0).abs() < 1e-12);
        assert_eq!(r.rejected, 2);
        // uniform on [-0.5, 0.5]: MAD = 0.25
        let s = mad_sigma(&v[..101], 10.0).unwrap();
        assert!((s - 1.4826 * 0.25).abs() < 1e-3, "{s}");
    }
}
