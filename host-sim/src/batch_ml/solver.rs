//! Plain (unweighted) least squares over a fixed set of observations by
//! Levenberg-Marquardt on the dense normal equations (nalgebra `DMatrix`, at
//! most 34 unknowns). With Gaussian pixel noise of one standard deviation for
//! every point, the minimum of the summed squared reprojection errors is the
//! maximum-likelihood estimate.

use nalgebra::{DMatrix, DVector};
use shared::observation::CameraIntrinsics;

use super::model::{BatchModel, Layout};
use super::observations::Observation;
use super::BatchError;

/// Most Levenberg-Marquardt iterations of one fit.
const MAX_ITERATIONS: u32 = 200;
/// Damping beyond which no step is taken any more: the model is at the minimum.
const MAX_DAMPING: f64 = 1e16;
/// The fit ends when the undamped Gauss-Newton step (the distance to the
/// minimum of the local quadratic model) moves no parameter by more than this
/// (m or rad); a damped step could be small while weakly observed directions
/// (a few end-effector sightings) are still far from their minimum.
const STEP_TOLERANCE: f64 = 1e-12;
/// Below this Gauss-Newton step (m or rad), a last step that lowered the cost
/// by no more than its rounding also ends the fit: what is left is rounding.
const ROUNDING_STEP: f64 = 1e-9;

/// The problem one fit solves: the observations, which of them count, the camera.
#[derive(Clone, Copy)]
pub struct Problem<'a> {
    pub camera: &'a CameraIntrinsics,
    pub layout: Layout,
    pub observations: &'a [Observation],
    /// `inliers[i]`: observation `i` counts (the others are gated out).
    pub inliers: &'a [bool],
}

impl Problem<'_> {
    fn counted(&self) -> impl Iterator<Item = &Observation> + '_ {
        self.observations
            .iter()
            .zip(self.inliers.iter())
            .filter_map(|(observation, inlier)| inlier.then_some(observation))
    }

    /// Sum of squared residuals of the counted observations; infinite when one
    /// of them falls behind the camera.
    pub fn cost(&self, model: &BatchModel) -> f64 {
        self.counted()
            .map(|observation| {
                model
                    .residual(self.camera, observation)
                    .map_or(f64::INFINITY, |r| r.norm_squared())
            })
            .sum()
    }

    /// `J^T J` and `J^T r` of the counted observations at `model`, accumulated
    /// from each residual's nonzero columns.
    pub fn normal_equations(
        &self,
        model: &BatchModel,
    ) -> Result<(DMatrix<f64>, DVector<f64>), BatchError> {
        let n = self.layout.parameter_count();
        let mut information = DMatrix::<f64>::zeros(n, n);
        let mut gradient = DVector::<f64>::zeros(n);
        for observation in self.counted() {
            let linearised = model
                .linearise(self.camera, &self.layout, observation)
                .ok_or(BatchError::BehindCamera {
                    frame: observation.frame,
                })?;
            let columns = linearised.columns();
            for &(row, a) in columns {
                gradient[row] += a.dot(&linearised.residual);
                for &(column, b) in columns {
                    information[(row, column)] += a.dot(&b);
                }
            }
        }
        Ok((information, gradient))
    }
}

/// The minimum reached and how.
#[derive(Debug, Clone)]
pub struct Fit {
    pub model: BatchModel,
    pub cost: f64,
    pub iterations: u32,
}

/// `(A + damping diag(A)) step = -g` by Cholesky, `None` if not positive definite.
fn damped_step(
    information: &DMatrix<f64>,
    gradient: &DVector<f64>,
    damping: f64,
) -> Option<DVector<f64>> {
    let mut damped = information.clone();
    for i in 0..damped.nrows() {
        let diagonal = damped[(i, i)];
        damped[(i, i)] = diagonal + damping * diagonal.max(1e-12);
    }
    let step = damped.cholesky()?.solve(&(-gradient));
    step.iter().all(|v| v.is_finite()).then_some(step)
}

/// Levenberg-Marquardt from `start` to the least-squares minimum of `problem`.
pub fn least_squares(problem: &Problem<'_>, start: BatchModel) -> Result<Fit, BatchError> {
    let mut model = start;
    let mut cost = problem.cost(&model);
    if !cost.is_finite() {
        return Err(BatchError::StartBehindCamera);
    }
    let mut damping = 1e-3;
    let mut iterations = 0;
    let mut last_decrease = f64::INFINITY;
    while iterations < MAX_ITERATIONS {
        iterations += 1;
        let (information, gradient) = problem.normal_equations(&model)?;
        if let Some(newton) = damped_step(&information, &gradient, 0.0) {
            let rounding = last_decrease <= 1e-14 * cost && newton.amax() < ROUNDING_STEP;
            if newton.amax() < STEP_TOLERANCE || rounding {
                break;
            }
        }
        let mut accepted = None;
        while damping < MAX_DAMPING {
            if let Some(step) = damped_step(&information, &gradient, damping) {
                let candidate = model.retract(&problem.layout, &step);
                let candidate_cost = problem.cost(&candidate);
                if candidate_cost <= cost {
                    accepted = Some((candidate, candidate_cost));
                    damping = (damping / 10.0).max(1e-15);
                    break;
                }
            }
            damping *= 4.0;
        }
        let Some((candidate, candidate_cost)) = accepted else {
            break;
        };
        last_decrease = cost - candidate_cost;
        model = candidate;
        cost = candidate_cost;
    }
    Ok(Fit {
        model,
        cost,
        iterations,
    })
}
