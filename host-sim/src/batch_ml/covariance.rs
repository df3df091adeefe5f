//! The Cramér-Rao bound at the optimum: with Gaussian pixel noise of per-axis
//! variance `sigma^2`, the covariance of an unbiased estimate is at least
//! `sigma^2 (J^T J)^-1`, which the least-squares estimate reaches
//! asymptotically. `sigma` is measured from the kept residuals,
//! `sigma^2 = sum |r|^2 / (2 N - parameters)`.

use nalgebra::{DMatrix, Matrix3, Vector3};
use shared::calibration::uncertainty::{part_in_base_sigmas, GraspCovariance, GraspGeometry};
use shared::calibration::EstimateUncertainty;

use super::model::{BatchModel, Layout};
use super::solver::Problem;
use super::BatchError;

/// The parameter covariance and the noise it was scaled with.
#[derive(Debug, Clone)]
pub struct Covariance {
    /// `sigma^2 (J^T J)^-1`, laid out as [`Layout`].
    pub parameters: DMatrix<f64>,
    /// The measured per-axis pixel sigma, px.
    pub pixel_sigma_px: f64,
}

/// The covariance at `model` (the optimum of `problem`, whose cost is `cost`).
pub fn covariance_at(
    problem: &Problem<'_>,
    model: &BatchModel,
    cost: f64,
) -> Result<Covariance, BatchError> {
    let (information, _) = problem.normal_equations(model)?;
    let kept = problem.inliers.iter().filter(|k| **k).count();
    let parameters = problem.layout.parameter_count();
    let dof = (2 * kept).saturating_sub(parameters);
    if dof == 0 {
        return Err(BatchError::TooFewObservations {
            observations: kept,
            parameters,
        });
    }
    let variance = cost / dof as f64;
    let inverse = information
        .cholesky()
        .ok_or(BatchError::Singular {
            stage: "covariance (J^T J not positive definite)",
        })?
        .inverse();
    Ok(Covariance {
        parameters: inverse * variance,
        pixel_sigma_px: variance.sqrt(),
    })
}

/// Square roots of the diagonal of `jacobian * covariance * jacobian^T`, where
/// `jacobian` (3 x parameters) maps parameter increments to a 3-vector.
fn propagated_sigmas(covariance: &DMatrix<f64>, jacobian: &DMatrix<f64>) -> [f64; 3] {
    let propagated = jacobian * covariance * jacobian.transpose();
    [0, 1, 2].map(|axis| {
        propagated
            .get((axis, axis))
            .copied()
            .unwrap_or(0.0)
            .max(0.0)
            .sqrt()
    })
}

fn sigma(covariance: &DMatrix<f64>, index: usize) -> f64 {
    covariance
        .get((index, index))
        .copied()
        .unwrap_or(0.0)
        .max(0.0)
        .sqrt()
}

impl Covariance {
    /// The one-sigma uncertainties in the calibrator's format (same JSON as
    /// `host-sim calibrate`'s `uncertainty_1sigma`).
    pub fn uncertainty(&self, layout: &Layout, model: &BatchModel) -> EstimateUncertainty {
        let n = layout.parameter_count();
        let covariance = &self.parameters;
        // Optical centre c = -R^T t: dc = -R^T [t]x d_rotation - R^T dt.
        let rotation_transposed: Matrix3<f64> = model.camera_from_disc.matrix().transpose();
        let d_rotation = -(rotation_transposed * model.camera_translation.cross_matrix());
        let d_translation = -rotation_transposed;
        let mut centre = DMatrix::<f64>::zeros(3, n);
        centre
            .view_mut((0, Layout::CAMERA_ROTATION), (3, 3))
            .copy_from(&d_rotation);
        centre
            .view_mut((0, Layout::CAMERA_TRANSLATION), (3, 3))
            .copy_from(&d_translation);
        let camera_position_m = propagated_sigmas(covariance, &centre);

        // Part position: the mean of the features.
        let mut mean = DMatrix::<f64>::zeros(3, n);
        let share = 1.0 / layout.feature_count.max(1) as f64;
        for index in 0..layout.feature_count {
            for axis in 0..3 {
                mean[(axis, layout.feature(index) + axis)] = share;
            }
        }
        let part_position_m = propagated_sigmas(covariance, &mean);

        let (base_yaw_rad, base_translation_m) = match layout.base() {
            Some(base) => {
                let mut translation = [0.0; 3];
                for (axis, slot) in translation.iter_mut().enumerate().take(layout.base_axes()) {
                    *slot = sigma(covariance, base + 1 + axis);
                }
                (sigma(covariance, base), translation)
            }
            None => (0.0, [0.0; 3]),
        };
        let axis = |offset: usize| [0, 1, 2].map(|i| sigma(covariance, offset + i));
        let [part_base_horizontal_m, part_base_vertical_m, part_yaw_base_rad] =
            part_in_base(covariance, layout, model, &mean);
        EstimateUncertainty {
            camera_height_m: camera_position_m[2],
            camera_position_m,
            camera_rotation_rad: axis(Layout::CAMERA_ROTATION),
            part_position_m,
            base_yaw_rad,
            base_translation_m,
            part_base_horizontal_m,
            part_base_vertical_m,
            part_yaw_base_rad,
        }
    }
}

/// The part's sigmas in the base frame, through the same propagation as the
/// calibrator's (`part_in_base_sigmas`) from this solve's own covariance.
fn part_in_base(
    covariance: &DMatrix<f64>,
    layout: &Layout,
    model: &BatchModel,
    mean: &DMatrix<f64>,
) -> [f64; 3] {
    let n = layout.parameter_count();
    // Rows: the features' mean, base yaw, base translation, feature 1 - 0.
    let mut rows = DMatrix::<f64>::zeros(10, n);
    rows.view_mut((0, 0), (3, n)).copy_from(mean);
    if let Some(base) = layout.base() {
        rows[(3, base)] = 1.0;
        for axis in 0..layout.base_axes() {
            rows[(4 + axis, base + 1 + axis)] = 1.0;
        }
    }
    if layout.feature_count >= 2 {
        for axis in 0..3 {
            rows[(7 + axis, layout.feature(1) + axis)] = 1.0;
            rows[(7 + axis, layout.feature(0) + axis)] = -1.0;
        }
    }
    let joint = &rows * covariance * rows.transpose();
    let grasp = GraspCovariance::from_fn(|r, c| joint[(r, c)]);
    let count = model.features_rotating.len().max(1) as f64;
    let part_rotating = model
        .features_rotating
        .iter()
        .fold(Vector3::zeros(), |sum, f| sum + f)
        / count;
    let yaw_line_rotating = match model.features_rotating.as_slice() {
        [first, second, ..] => second - first,
        _ => Vector3::zeros(),
    };
    let geometry = GraspGeometry {
        part_rotating,
        yaw_line_rotating,
        base_yaw: model.base_yaw_rad,
    };
    part_in_base_sigmas(&grasp, &geometry)
}

/// Root-sum-square of a per-axis sigma, for printing.
pub fn norm(sigmas: [f64; 3]) -> f64 {
    Vector3::from(sigmas).norm()
}
