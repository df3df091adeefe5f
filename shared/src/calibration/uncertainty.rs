//! Standard deviations of the refined estimate, read off the parameter covariance of the
//! bundle adjustment (the inverse Gauss-Newton information times the pixel variance).
//! They let a caller judge whether a calibration is good enough before trusting it.

use nalgebra::{SMatrix, Vector3};

use super::model::{BASE_OFFSET, FEATURE_OFFSET, PARAMETERS};
use crate::observation::MAX_PART_FEATURES;

/// One-sigma uncertainties of the refined estimate (metres, radians); serialised
/// beside the calibration result as `uncertainty_1sigma`.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct EstimateUncertainty {
    /// Of `camera.height_m`.
    pub camera_height_m: f64,
    /// Of the camera's optical centre in the disc frame, per axis.
    pub camera_position_m: [f64; 3],
    /// Of the camera's rotation, per axis of a small rotation in the camera frame.
    pub camera_rotation_rad: [f64; 3],
    /// Of `part.position_m` (the mean of the features), per axis.
    pub part_position_m: [f64; 3],
    /// Of `base_from_disc.yaw_rad`.
    pub base_yaw_rad: f64,
    /// Of `base_from_disc.translation_m`, per axis (0 for a known disc height).
    pub base_translation_m: [f64; 3],
}

fn sigma(covariance: &SMatrix<f64, PARAMETERS, PARAMETERS>, index: usize) -> f64 {
    libm::sqrt(
        covariance
            .get((index, index))
            .copied()
            .unwrap_or(0.0)
            .max(0.0),
    )
}

impl EstimateUncertainty {
    pub fn from_covariance(
        covariance: &SMatrix<f64, PARAMETERS, PARAMETERS>,
        feature_count: usize,
    ) -> Self {
        let axis = |offset: usize| {
            [
                sigma(covariance, offset),
                sigma(covariance, offset + 1),
                sigma(covariance, offset + 2),
            ]
        };
        // The part position is the mean of the features: its covariance is
        // (1/n^2) sum_ij C(f_i, f_j), 3x3 blocks of the feature covariance.
        let count = feature_count.clamp(1, MAX_PART_FEATURES);
        let mut part = SMatrix::<f64, 3, 3>::zeros();
        for i in 0..count {
            for j in 0..count {
                part +=
                    covariance.fixed_view::<3, 3>(FEATURE_OFFSET + 3 * i, FEATURE_OFFSET + 3 * j);
            }
        }
        part /= (count * count) as f64;
        let diagonal: Vector3<f64> = part.diagonal().map(|v| libm::sqrt(v.max(0.0)));
        Self {
            camera_height_m: sigma(covariance, 5),
            camera_position_m: axis(3),
            camera_rotation_rad: axis(0),
            part_position_m: [diagonal.x, diagonal.y, diagonal.z],
            base_yaw_rad: sigma(covariance, BASE_OFFSET),
            base_translation_m: axis(BASE_OFFSET + 1),
        }
    }
}
