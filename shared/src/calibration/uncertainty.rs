//! Standard deviations of the refined estimate, read off the parameter covariance of the
//! bundle adjustment (the inverse Gauss-Newton information times the pixel variance, as
//! [`super::normal_blocks::MarginalCovariance`] keeps it). They let a caller judge
//! whether a calibration is good enough before trusting it.

use nalgebra::{Matrix2, Matrix3, SMatrix, Vector2, Vector3};

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
    /// Of the part in the base frame (Eq 1), horizontally (the root of the
    /// horizontal covariance's trace), at the worst angle the disc turns it
    /// to: what the gripper's horizontal capture has to cover. The base and
    /// the part both lean on the camera, so this is not the two added apart.
    #[serde(default)]
    pub part_base_horizontal_m: f64,
    /// Of the part's height in the base frame (the same at every angle).
    #[serde(default)]
    pub part_base_vertical_m: f64,
    /// Of the part's yaw in the base frame (its feature 0 to 1 line plus the
    /// base yaw); 0 with fewer than two features.
    #[serde(default)]
    pub part_yaw_base_rad: f64,
}

/// Where the estimate puts the part, as far as its uncertainty in the base
/// frame depends on it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GraspGeometry {
    /// The features' mean in the rotating frame, m.
    pub part_rotating: Vector3<f64>,
    /// Feature 1 minus feature 0 in the rotating frame, m (zero with one feature).
    pub yaw_line_rotating: Vector3<f64>,
    /// `base_from_disc`'s yaw, rad.
    pub base_yaw: f64,
}

/// The joint covariance of what puts the part in the base frame (Eq 1): the
/// features' mean (rows 0..3), the base yaw (3), the base translation (4..7)
/// and the yaw line (7..10). The mean-to-line block is not read.
pub type GraspCovariance = SMatrix<f64, 10, 10>;

/// Angles of the disc at which the horizontal uncertainty is taken: its
/// dependence on the angle is a sum of first and second harmonics, so 16
/// samples find its worst to well within a percent.
const DISC_ANGLE_SAMPLES: usize = 16;

/// The part's one-sigma horizontal and vertical position and yaw in the base
/// frame: `p_base = Rz(base_yaw + theta) p_rotating + t` (Eq 1) propagated to
/// first order, worst over theta for the horizontal.
pub fn part_in_base_sigmas(covariance: &GraspCovariance, geometry: &GraspGeometry) -> [f64; 3] {
    let position = covariance.fixed_view::<7, 7>(0, 0);
    let mut horizontal: f64 = 0.0;
    let mut vertical = 0.0;
    for sample in 0..DISC_ANGLE_SAMPLES {
        let angle =
            geometry.base_yaw + core::f64::consts::TAU * sample as f64 / DISC_ANGLE_SAMPLES as f64;
        let (s, c) = libm::sincos(angle);
        let p = &geometry.part_rotating;
        let mut jacobian = SMatrix::<f64, 3, 7>::zeros();
        let rotation = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
        jacobian.fixed_view_mut::<3, 3>(0, 0).copy_from(&rotation);
        jacobian
            .fixed_view_mut::<3, 1>(0, 3)
            .copy_from(&Vector3::new(-s * p.x - c * p.y, c * p.x - s * p.y, 0.0));
        jacobian
            .fixed_view_mut::<3, 3>(0, 4)
            .copy_from(&Matrix3::identity());
        let propagated: Matrix3<f64> = jacobian * position * jacobian.transpose();
        horizontal = horizontal.max(propagated.m11 + propagated.m22);
        vertical = propagated.m33;
    }
    let line = Vector2::new(geometry.yaw_line_rotating.x, geometry.yaw_line_rotating.y);
    let length_squared = line.norm_squared();
    let yaw = if length_squared > 0.0 {
        // The line's direction moves by its normal displacement over its length.
        let normal = Vector2::new(-line.y, line.x) / length_squared;
        let line_xy: Matrix2<f64> = covariance.fixed_view::<2, 2>(7, 7).into_owned();
        let line_with_yaw: Vector2<f64> = covariance.fixed_view::<2, 1>(7, 3).into_owned();
        let base_yaw: f64 = covariance.fixed_view::<1, 1>(3, 3).to_scalar();
        normal.dot(&(line_xy * normal)) + base_yaw + 2.0 * normal.dot(&line_with_yaw)
    } else {
        0.0
    };
    [horizontal, vertical, yaw].map(|variance| libm::sqrt(variance.max(0.0)))
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
    /// Standard deviations from the marginal `covariance` of the refined
    /// parameters, the part's in the base frame at `geometry`.
    pub fn from_covariance(covariance: &MarginalCovariance, geometry: &GraspGeometry) -> Self {
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
        let mut grasp = GraspCovariance::zeros();
        grasp.fixed_view_mut::<3, 3>(0, 0).copy_from(part);
        let base_block = arrow.fixed_view::<4, 4>(base, base);
        grasp.fixed_view_mut::<4, 4>(3, 3).copy_from(&base_block);
        let part_base = covariance.part_and_arrow.fixed_view::<3, 4>(0, base);
        grasp.fixed_view_mut::<3, 4>(0, 3).copy_from(&part_base);
        grasp
            .fixed_view_mut::<4, 3>(3, 0)
            .copy_from(&part_base.transpose());
        grasp
            .fixed_view_mut::<3, 3>(7, 7)
            .copy_from(&covariance.yaw_line);
        let line_base = covariance.yaw_line_and_arrow.fixed_view::<3, 4>(0, base);
        grasp.fixed_view_mut::<3, 4>(7, 3).copy_from(&line_base);
        grasp
            .fixed_view_mut::<4, 3>(3, 7)
            .copy_from(&line_base.transpose());
        let [part_base_horizontal_m, part_base_vertical_m, part_yaw_base_rad] =
            part_in_base_sigmas(&grasp, geometry);
        Self {
            camera_height_m: sigma(arrow, 5),
            camera_position_m: axis(3),
            camera_rotation_rad: axis(0),
            part_position_m: [sigma(part, 0), sigma(part, 1), sigma(part, 2)],
            base_yaw_rad: sigma(arrow, base),
            base_translation_m: axis(base + 1),
            part_base_horizontal_m,
            part_base_vertical_m,
            part_yaw_base_rad,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::splitmix;

    /// A standard normal draw (Box-Muller).
    fn normal(state: &mut u64) -> f64 {
        let u = splitmix(state).max(1e-300);
        let v = splitmix(state);
        libm::sqrt(-2.0 * libm::log(u)) * libm::cos(core::f64::consts::TAU * v)
    }

    /// The part in the base frame of a perturbed estimate, exactly (Eq 1).
    fn part_base(geometry: &GraspGeometry, z: &SMatrix<f64, 10, 1>, theta: f64) -> Vector3<f64> {
        let angle = geometry.base_yaw + z[3] + theta;
        let p = geometry.part_rotating + z.fixed_view::<3, 1>(0, 0);
        let (s, c) = libm::sincos(angle);
        Vector3::new(c * p.x - s * p.y, s * p.x + c * p.y, p.z) + z.fixed_view::<3, 1>(4, 0)
    }

    #[test]
    fn the_part_in_base_sigmas_are_those_of_samples() {
        for seed in 1..4u64 {
            let mut state = seed * 7919;
            // A random covariance of millimetres and milliradians with strong
            // correlations (a shared camera error).
            let scale = SMatrix::<f64, 10, 1>::from_fn(|r, _| if r == 3 { 0.03 } else { 2e-3 });
            let mixing = SMatrix::<f64, 10, 10>::from_fn(|_, _| splitmix(&mut state) - 0.5);
            let shape = mixing * mixing.transpose() + SMatrix::<f64, 10, 10>::identity() * 0.05;
            let covariance = GraspCovariance::from_fn(|r, c| shape[(r, c)] * scale[r] * scale[c]);
            let geometry = GraspGeometry {
                part_rotating: Vector3::new(0.31, -0.12, 0.04),
                yaw_line_rotating: Vector3::new(0.025, 0.035, 0.002),
                base_yaw: 0.3 * seed as f64,
            };
            let [horizontal, vertical, yaw] = part_in_base_sigmas(&covariance, &geometry);
            let cholesky = covariance.cholesky().unwrap().l();
            let samples = 20_000;
            let mut sum_horizontal = [0.0; DISC_ANGLE_SAMPLES];
            let (mut sum_vertical, mut sum_yaw) = (0.0, 0.0);
            let line_yaw = libm::atan2(geometry.yaw_line_rotating.y, geometry.yaw_line_rotating.x);
            for _ in 0..samples {
                let z = cholesky * SMatrix::<f64, 10, 1>::from_fn(|_, _| normal(&mut state));
                for (k, sum) in sum_horizontal.iter_mut().enumerate() {
                    let theta = core::f64::consts::TAU * k as f64 / DISC_ANGLE_SAMPLES as f64;
                    let e = part_base(&geometry, &z, theta)
                        - part_base(&geometry, &SMatrix::zeros(), theta);
                    *sum += e.x * e.x + e.y * e.y;
                }
                sum_vertical += z[2] * z[2] + z[6] * z[6] + 2.0 * z[2] * z[6];
                let line = geometry.yaw_line_rotating + z.fixed_view::<3, 1>(7, 0);
                let e = libm::atan2(line.y, line.x) - line_yaw + z[3];
                sum_yaw += e * e;
            }
            let n = samples as f64;
            let worst = sum_horizontal.iter().fold(0.0f64, |a, &b| a.max(b)) / n;
            for (what, got, sampled) in [
                ("horizontal", horizontal, libm::sqrt(worst)),
                ("vertical", vertical, libm::sqrt(sum_vertical / n)),
                ("yaw", yaw, libm::sqrt(sum_yaw / n)),
            ] {
                assert!(
                    (got / sampled - 1.0).abs() < 0.03,
                    "seed {seed} {what}: {got} vs sampled {sampled}"
                );
            }
        }
    }

    #[test]
    fn one_feature_has_no_yaw_sigma() {
        let covariance = GraspCovariance::identity() * 1e-6;
        let geometry = GraspGeometry {
            part_rotating: Vector3::new(0.3, 0.0, 0.04),
            yaw_line_rotating: Vector3::zeros(),
            base_yaw: 0.0,
        };
        let [horizontal, vertical, yaw] = part_in_base_sigmas(&covariance, &geometry);
        assert_eq!(yaw, 0.0);
        assert!((vertical - libm::sqrt(2e-6)).abs() < 1e-12);
        assert!(horizontal > vertical);
    }
}
