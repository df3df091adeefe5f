//! The outlier gate: the same kind as the calibrator's second phase. A point
//! whose 2-D residual exceeds `outlier_gate_sigma` robust sigmas is dropped;
//! the robust sigma is the median residual norm over every observation divided
//! by 1.1774 (the median of the norm of a 2-D Gaussian with per-axis sigma 1),
//! floored at the configured pixel-noise prior so that a noise-free log keeps
//! its points. Gate and fit alternate until the set of kept points no longer
//! changes: the result is the least-squares (maximum-likelihood) optimum of the
//! points the gate keeps at that very optimum.

use shared::observation::CameraIntrinsics;

use super::model::BatchModel;
use super::observations::Observation;

/// Median norm of a 2-D standard Gaussian vector, `sqrt(2 ln 2)`.
pub const MEDIAN_NORM_PER_SIGMA: f64 = 1.1774;

/// Residual norms of every observation at `model` (infinite behind the camera).
pub fn residual_norms(
    camera: &CameraIntrinsics,
    model: &BatchModel,
    observations: &[Observation],
) -> Vec<f64> {
    observations
        .iter()
        .map(|observation| {
            model
                .residual(camera, observation)
                .map_or(f64::INFINITY, |r| r.norm())
        })
        .collect()
}

/// Median of `values` (NaN sorts last); 0 for none.
fn median(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    match sorted.len() {
        0 => 0.0,
        n if n % 2 == 1 => sorted.get(n / 2).copied().unwrap_or(0.0),
        n => {
            let low = sorted.get(n / 2 - 1).copied().unwrap_or(0.0);
            let high = sorted.get(n / 2).copied().unwrap_or(0.0);
            0.5 * (low + high)
        }
    }
}

/// Robust per-axis pixel sigma of residual `norms`.
pub fn robust_sigma_px(norms: &[f64]) -> f64 {
    median(norms) / MEDIAN_NORM_PER_SIGMA
}

/// The gate (px) for residual `norms`: `gate_sigmas * max(robust sigma, prior)`.
pub fn gate_px(norms: &[f64], gate_sigmas: f64, prior_sigma_px: f64) -> f64 {
    gate_sigmas * robust_sigma_px(norms).max(prior_sigma_px)
}

/// Which observations the gate keeps.
pub fn kept(norms: &[f64], gate_px: f64) -> Vec<bool> {
    norms.iter().map(|r| *r <= gate_px).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gate_scales_with_the_median_and_is_floored_by_the_prior() {
        let norms = [1.0, 2.0, 1.1774 * 2.0, 100.0, 3.0];
        assert!((robust_sigma_px(&norms) - 2.0).abs() < 1e-12);
        assert!((gate_px(&norms, 5.0, 0.5) - 10.0).abs() < 1e-12);
        assert_eq!(kept(&norms, 10.0), vec![true, true, true, false, true]);
        assert!((gate_px(&[0.0; 4], 5.0, 0.5) - 2.5).abs() < 1e-12);
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), 2.5);
    }
}
