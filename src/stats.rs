//! Order statistics shared across the tool (calibration, reconstruction, the BRDF basis): one
//! median, by selection, a weighted median, and a nearest-rank percentile; and a sample's mean
//! with its standard error. Pure: no I/O.

/// Median of `values` (reorders them); `None` when empty or when a value is NaN. A selection,
/// not a sort: linear in the number of values (millions of a 24 MP board's pixels).
pub fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() || values.iter().any(|v| v.is_nan()) {
        return None;
    }
    let n = values.len();
    let (lower, &mut upper, _) = values.select_nth_unstable_by(n / 2, f64::total_cmp);
    Some(if n % 2 == 1 {
        upper
    } else {
        // the largest of the lower half is the other middle value
        let below = lower.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        0.5 * (below + upper)
    })
}

/// The weighted median of `(value, weight)` pairs (reorders them): the smallest value at which
/// the weights below and at it reach half of the total; `None` when there is no positive weight.
pub fn weighted_median(values: &mut [(f64, f64)]) -> Option<f64> {
    values.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = values.iter().map(|v| v.1).sum();
    if total.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let mut acc = 0.0;
    values.iter().find_map(|&(x, w)| {
        acc += w;
        (acc >= 0.5 * total).then_some(x)
    })
}

/// Nearest-rank percentile of values sorted ascending (`q` in [0, 1], clamped); NaN for none.
pub fn percentile_sorted(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
    sorted[i]
}

/// The mean of `values` and its standard error (the sample standard deviation, n - 1, over
/// sqrt(n)); (0, 0) for none, the standard error 0 for one value.
pub fn mean_and_standard_error(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n.max(1.0);
    let sd =
        (values.iter().map(|d| (d - mean) * (d - mean)).sum::<f64>() / (n - 1.0).max(1.0)).sqrt();
    (mean, sd / n.max(1.0).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weighted_median_is_the_middle_of_the_weight() {
        assert_eq!(weighted_median(&mut []), None);
        assert_eq!(
            weighted_median(&mut [(3.0, 1.0), (1.0, 1.0), (2.0, 1.0)]),
            Some(2.0)
        );
        // a heavy value wins over several light ones
        assert_eq!(
            weighted_median(&mut [(5.0, 4.0), (1.0, 1.0), (2.0, 1.0)]),
            Some(5.0)
        );
        assert_eq!(weighted_median(&mut [(1.0, 0.0)]), None);
    }

    #[test]
    fn median_odd_even_and_nan() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&mut [4.0, 1.0, 2.0, 3.0]), Some(2.5));
        assert_eq!(median(&mut []), None);
        assert_eq!(median(&mut [1.0, f64::NAN]), None);
    }

    #[test]
    fn mean_and_standard_error_of_a_sample() {
        let (m, se) = mean_and_standard_error(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(m, 2.5);
        // sample sd sqrt(5/3), over sqrt(4)
        assert!((se - (5.0f64 / 3.0).sqrt() / 2.0).abs() < 1e-15);
        assert_eq!(mean_and_standard_error(&[]), (0.0, 0.0));
        assert_eq!(mean_and_standard_error(&[7.0]), (7.0, 0.0));
    }
}
