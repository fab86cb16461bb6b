//! Robust statistics shared by the calibration steps: median, MAD-based sigma and a mean that
//! rejects outliers (dust, hot pixels, glints) before averaging.
//!
//! Conventions: `mad_sigma` is scaled by 1.4826 so it estimates the standard deviation of
//! Gaussian data. Pure: no I/O.

/// Median of `values` (reorders them); `None` when empty or when a value is NaN.
pub fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() || values.iter().any(|v| v.is_nan()) {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let n = values.len();
    Some(if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    })
}

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

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn median_odd_even_and_nan() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&mut [4.0, 1.0, 2.0, 3.0]), Some(2.5));
        assert_eq!(median(&mut []), None);
        assert_eq!(median(&mut [1.0, f64::NAN]), None);
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
