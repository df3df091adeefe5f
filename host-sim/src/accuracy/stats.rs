//! Order statistics of error samples. A failed calibration counts as an
//! infinite error, so failures can never make a percentile look better.

/// Linear-interpolation percentile (the "type 7" definition) of `values`, `q` in [0, 1].
/// NaN counts as +infinity. `None` for an empty sample.
pub fn percentile(values: &[f64], q: f64) -> Option<f64> {
    let mut sorted: Vec<f64> = values
        .iter()
        .map(|v| if v.is_nan() { f64::INFINITY } else { *v })
        .collect();
    if sorted.is_empty() {
        return None;
    }
    sorted.sort_by(f64::total_cmp);
    let position = q.clamp(0.0, 1.0) * (sorted.len() - 1) as f64;
    let below = position.floor() as usize;
    let above = position.ceil() as usize;
    let (low, high) = (*sorted.get(below)?, *sorted.get(above)?);
    if low == high || !high.is_finite() {
        // Also avoids inf - inf: a percentile reaching into failures is infinite.
        return Some(if position > below as f64 { high } else { low });
    }
    Some(low + (high - low) * (position - below as f64))
}

pub fn median(values: &[f64]) -> Option<f64> {
    percentile(values, 0.5)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_interpolate_and_failures_count_as_infinite() {
        let values = [4.0, 1.0, 3.0, 2.0, 5.0];
        assert_eq!(median(&values), Some(3.0));
        assert_eq!(percentile(&values, 0.0), Some(1.0));
        assert_eq!(percentile(&values, 1.0), Some(5.0));
        assert_eq!(percentile(&values, 0.95), Some(4.8));
        assert_eq!(median(&[1.0, 2.0]), Some(1.5));
        assert_eq!(median(&[]), None);
        let with_failure = [1.0, f64::NAN, 2.0];
        assert_eq!(median(&with_failure), Some(2.0));
        assert_eq!(percentile(&with_failure, 0.95), Some(f64::INFINITY));
        assert_eq!(percentile(&[1.0, f64::INFINITY], 0.0), Some(1.0));
    }
}
