//! Standard deviations of the refined estimate, read off the parameter covariance of the
//! bundle adjustment (the inverse Gauss-Newton information times the pixel variance, as
//! [`super::normal_blocks::MarginalCovariance`] keeps it). They let a caller judge
//! whether a calibration is good enough before trusting it.

use super::normal_blocks::{ArrowMatrix, MarginalCovariance, CAMERA_PARAMETERS};

/// One-sigma uncertainties of the refined estimate (metres, radians); serialised
/// beside the calibration result as `uncertainty_1sigma`.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
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

/// Square root of a variance on the diagonal (0 for a negative rounding residue).
fn sigma<const N: usize>(covariance: &nalgebra::SMatrix<f64, N, N>, index: usize) -> f64 {
    libm::sqrt(
        covariance
            .get((index, index))
            .copied()
            .unwrap_or(0.0)
            .max(0.0),
    )
}

impl EstimateUncertainty {
    /// Standard deviations from the marginal `covariance` of the refined parameters.
    pub fn from_covariance(covariance: &MarginalCovariance) -> Self {
        let arrow: &ArrowMatrix = &covariance.camera_and_base;
        let axis = |offset: usize| {
            [
                sigma(arrow, offset),
                sigma(arrow, offset + 1),
                sigma(arrow, offset + 2),
            ]
        };
        let part = &covariance.part_position;
        let base = CAMERA_PARAMETERS;
        Self {
            camera_height_m: sigma(arrow, 5),
            camera_position_m: axis(3),
            camera_rotation_rad: axis(0),
            part_position_m: [sigma(part, 0), sigma(part, 1), sigma(part, 2)],
            base_yaw_rad: sigma(arrow, base),
            base_translation_m: axis(base + 1),
        }
    }
}
