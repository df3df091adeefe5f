//! Beyond the paper: robust Levenberg-Marquardt bundle adjustment over every stored
//! observation — camera pose (6), feature points (3 each) and `base_from_disc` (4, or 3
//! when the disc height is known) — with the disc centre and the reference point
//! `(L cos theta, L sin theta, 0)` as observations of known disc points.
//!
//! With Gaussian pixel noise this is the maximum-likelihood estimate; gross outliers are
//! handled by a Huber loss (phase 1) and then a hard gate on the residual at
//! `outlier_gate_sigma` robust sigmas (phase 2). Memory is fixed: the normal equations
//! are one `PARAMETERS x PARAMETERS` matrix whatever the number of frames.

use nalgebra::{SMatrix, Vector2};

use super::config::CalibrationConfig;
use super::error::CalibrationError;
use super::model::{
    for_each_observation, OtherBlock, WorkcellModel, BASE_OFFSET, FEATURE_OFFSET, PARAMETERS,
};
use super::pinhole::Pinhole;
use super::records::{EffectorRecord, FrameRecord};

type Normal = SMatrix<f64, PARAMETERS, PARAMETERS>;
type Gradient = SMatrix<f64, PARAMETERS, 1>;

/// What the refinement sees: stored observations and how to treat them.
#[derive(Clone, Copy)]
pub struct Problem<'a> {
    pub pinhole: Pinhole,
    pub frames: &'a [FrameRecord],
    pub effectors: &'a [EffectorRecord],
    pub feature_count: usize,
    pub reference_radius_m: f64,
    /// Fix `base_translation.z` (known disc height) instead of estimating it.
    pub fix_base_height: bool,
}

/// Robust weighting of one phase: Huber threshold and optional hard gate (pixels).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Loss {
    huber_px: f64,
    gate_px: Option<f64>,
}

impl Loss {
    /// IRLS weight of a residual of norm `r`.
    fn weight(&self, r: f64) -> f64 {
        if let Some(gate) = self.gate_px {
            if r > gate {
                return 0.0;
            }
        }
        if r <= self.huber_px {
            1.0
        } else {
            self.huber_px / r
        }
    }

    /// Huber cost, constant beyond the gate (a gated point neither pulls nor pays more).
    fn cost(&self, r: f64) -> f64 {
        let k = self.huber_px;
        let capped = match self.gate_px {
            Some(gate) if r > gate => gate,
            _ => r,
        };
        if capped <= k {
            0.5 * capped * capped
        } else {
            k * capped - 0.5 * k * k
        }
    }
}

/// Result of the refinement with its fit statistics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refined {
    pub model: WorkcellModel,
    /// RMS 2-D reprojection distance over the points kept (px).
    pub rms_px: f64,
    /// Points beyond the gate.
    pub outliers: u32,
    /// Inverse of the Gauss-Newton information matrix scaled by sigma^2: parameter covariance.
    pub covariance: Option<Normal>,
}

fn total_cost(problem: &Problem<'_>, model: &WorkcellModel, loss: &Loss) -> f64 {
    let mut cost = 0.0;
    for_each_observation(
        problem.frames,
        problem.effectors,
        problem.feature_count,
        problem.reference_radius_m,
        |observation| {
            cost += match model.residual(&problem.pinhole, observation) {
                Some(r) => loss.cost(r.norm()),
                // A point pushed behind the camera pays the gate's price.
                None => loss.cost(loss.gate_px.unwrap_or(1e6)),
            };
        },
    );
    cost
}

/// The Gauss-Newton normal equations at `model`, written into the caller's
/// `normal` and `gradient` (9 KiB a matrix: filled in place rather than
/// returned, so a firmware stack does not hold a second copy).
fn normal_equations(
    problem: &Problem<'_>,
    model: &WorkcellModel,
    loss: &Loss,
    normal: &mut Normal,
    gradient: &mut Gradient,
) {
    normal.fill(0.0);
    gradient.fill(0.0);
    for_each_observation(
        problem.frames,
        problem.effectors,
        problem.feature_count,
        problem.reference_radius_m,
        |observation| {
            let Some((residual, jacobian)) =
                model.residual_with_jacobian(&problem.pinhole, observation)
            else {
                return;
            };
            let weight = loss.weight(residual.norm());
            if weight == 0.0 {
                return;
            }
            accumulate(
                normal,
                gradient,
                &jacobian.camera,
                &jacobian.other,
                &residual,
                weight,
            );
        },
    );
}

fn accumulate(
    normal: &mut Normal,
    gradient: &mut Gradient,
    camera: &SMatrix<f64, 2, 6>,
    other: &OtherBlock,
    residual: &Vector2<f64>,
    weight: f64,
) {
    let camera_t = camera.transpose() * weight;
    let mut cc = normal.fixed_view_mut::<6, 6>(0, 0);
    cc += camera_t * camera;
    let mut gc = gradient.fixed_view_mut::<6, 1>(0, 0);
    gc += camera_t * residual;
    let (offset, block): (usize, SMatrix<f64, 2, 4>) = match *other {
        OtherBlock::None => return,
        OtherBlock::Feature { index, jacobian } => {
            if index >= crate::observation::MAX_PART_FEATURES {
                return;
            }
            let mut padded = SMatrix::<f64, 2, 4>::zeros();
            padded.fixed_view_mut::<2, 3>(0, 0).copy_from(&jacobian);
            // The 4th column is zero, so spilling into the next slot adds nothing.
            (FEATURE_OFFSET + 3 * index, padded)
        }
        OtherBlock::Base(block) => (BASE_OFFSET, block),
    };
    let block_t = block.transpose() * weight;
    let cross = camera_t * block;
    let mut co = normal.fixed_view_mut::<6, 4>(0, offset);
    co += cross;
    let mut oc = normal.fixed_view_mut::<4, 6>(offset, 0);
    oc += cross.transpose();
    let mut oo = normal.fixed_view_mut::<4, 4>(offset, offset);
    oo += block_t * block;
    let mut go = gradient.fixed_view_mut::<4, 1>(offset, 0);
    go += block_t * residual;
}

/// Solves `a x = b` for a symmetric positive-definite `a` by Cholesky, in
/// place: `a`'s lower triangle becomes the factor L (a = L L^T) and `b`
/// becomes x. False, with `a` and `b` spoilt, when `a` is not positive
/// definite (a pivot not above zero, or not finite).
fn cholesky_solve_in_place(a: &mut Normal, b: &mut Gradient) -> bool {
    let n = PARAMETERS;
    let at = |a: &Normal, i: usize, j: usize| a.get((i, j)).copied().unwrap_or(0.0);
    for j in 0..n {
        let mut pivot = at(a, j, j);
        for k in 0..j {
            let l = at(a, j, k);
            pivot -= l * l;
        }
        if !(pivot.is_finite() && pivot > 0.0) {
            return false;
        }
        let diagonal = libm::sqrt(pivot);
        if let Some(e) = a.get_mut((j, j)) {
            *e = diagonal;
        }
        for i in (j + 1)..n {
            let mut value = at(a, i, j);
            for k in 0..j {
                value -= at(a, i, k) * at(a, j, k);
            }
            if let Some(e) = a.get_mut((i, j)) {
                *e = value / diagonal;
            }
        }
    }
    // L y = b, then L^T x = y.
    for i in 0..n {
        let mut value = b.get(i).copied().unwrap_or(0.0);
        for k in 0..i {
            value -= at(a, i, k) * b.get(k).copied().unwrap_or(0.0);
        }
        if let Some(e) = b.get_mut(i) {
            *e = value / at(a, i, i);
        }
    }
    for i in (0..n).rev() {
        let mut value = b.get(i).copied().unwrap_or(0.0);
        for k in (i + 1)..n {
            value -= at(a, k, i) * b.get(k).copied().unwrap_or(0.0);
        }
        if let Some(e) = b.get_mut(i) {
            *e = value / at(a, i, i);
        }
    }
    true
}

/// Parameters the data cannot move: unused feature slots, base (no sightings), base z.
fn frozen(problem: &Problem<'_>, index: usize) -> bool {
    if (FEATURE_OFFSET..BASE_OFFSET).contains(&index) {
        return (index - FEATURE_OFFSET) / 3 >= problem.feature_count;
    }
    if index >= BASE_OFFSET {
        return problem.effectors.is_empty()
            || (problem.fix_base_height && index == BASE_OFFSET + 3);
    }
    false
}

/// Levenberg-Marquardt on one loss; returns the improved model.
fn minimise(
    problem: &Problem<'_>,
    start: WorkcellModel,
    loss: &Loss,
    max_iterations: u32,
) -> Result<WorkcellModel, CalibrationError> {
    let mut model = start;
    let mut cost = total_cost(problem, &model, loss);
    let mut damping = 1e-4;
    // One damped copy for every try, factorised in place: a firmware stack
    // holds the normal matrix and this one (9 KiB each), not also a factor.
    let mut damped = Normal::zeros();
    let mut normal = Normal::zeros();
    let mut gradient = Gradient::zeros();
    for _ in 0..max_iterations {
        normal_equations(problem, &model, loss, &mut normal, &mut gradient);
        let mut improved = false;
        while damping < 1e10 {
            damped.copy_from(&normal);
            for i in 0..PARAMETERS {
                let diagonal = damped.get((i, i)).copied().unwrap_or(0.0);
                let value = if frozen(problem, i) {
                    1.0
                } else {
                    diagonal * (1.0 + damping) + 1e-12
                };
                if let Some(entry) = damped.get_mut((i, i)) {
                    *entry = value;
                }
                if frozen(problem, i) {
                    for j in 0..PARAMETERS {
                        if j != i {
                            if let Some(e) = damped.get_mut((i, j)) {
                                *e = 0.0;
                            }
                            if let Some(e) = damped.get_mut((j, i)) {
                                *e = 0.0;
                            }
                        }
                    }
                }
            }
            let mut rhs = -gradient;
            for i in 0..PARAMETERS {
                if frozen(problem, i) {
                    if let Some(e) = rhs.get_mut(i) {
                        *e = 0.0;
                    }
                }
            }
            let mut step = rhs;
            if !cholesky_solve_in_place(&mut damped, &mut step) {
                damping *= 10.0;
                continue;
            }
            if !step.iter().all(|v| v.is_finite()) {
                return Err(CalibrationError::NumericalFailure {
                    stage: "bundle adjustment step",
                });
            }
            let candidate = model.retract(&step);
            let candidate_cost = total_cost(problem, &candidate, loss);
            if candidate_cost <= cost {
                let decrease = cost - candidate_cost;
                model = candidate;
                cost = candidate_cost;
                damping = (damping / 3.0).max(1e-9);
                improved = decrease > 1e-12 * cost.max(1e-30) && step.norm() > 1e-13;
                break;
            }
            damping *= 4.0;
        }
        if !improved {
            break;
        }
    }
    Ok(model)
}

/// Robust scale of the residual norms from a fixed histogram (memory independent of the
/// number of points): median of a 2-D Gaussian residual's norm is 1.1774 sigma.
fn robust_sigma(problem: &Problem<'_>, model: &WorkcellModel, nominal_sigma: f64) -> f64 {
    const BINS: usize = 128;
    const RANGE_SIGMAS: f64 = 32.0;
    let bin_width = nominal_sigma * RANGE_SIGMAS / BINS as f64;
    let mut histogram = [0u32; BINS];
    let mut total = 0u32;
    for_each_observation(
        problem.frames,
        problem.effectors,
        problem.feature_count,
        problem.reference_radius_m,
        |observation| {
            let r = model
                .residual(&problem.pinhole, observation)
                .map_or(f64::INFINITY, |r| r.norm());
            let bin = if r.is_finite() {
                (r / bin_width) as usize
            } else {
                BINS - 1
            };
            if let Some(count) = histogram.get_mut(bin.min(BINS - 1)) {
                *count += 1;
            }
            total += 1;
        },
    );
    let half = total / 2;
    let mut running = 0u32;
    for (bin, count) in histogram.iter().enumerate() {
        running += count;
        if running > half {
            let median = (bin as f64 + 0.5) * bin_width;
            return median / 1.1774;
        }
    }
    nominal_sigma * RANGE_SIGMAS
}

/// The fit of both phases before its covariance.
struct Fit {
    model: WorkcellModel,
    rms_px: f64,
    outliers: u32,
    gate_px: f64,
}

/// Runs both phases and reports the fit.
///
/// The two halves are separate, never-inlined functions so that their large
/// locals (each `PARAMETERS x PARAMETERS` matrix is 9 KiB) are never on the
/// stack at the same time: on the firmware the estimate runs in 128 KiB.
#[inline(never)]
pub fn refine(
    problem: &Problem<'_>,
    start: WorkcellModel,
    config: &CalibrationConfig,
) -> Result<Refined, CalibrationError> {
    let fit = fit(problem, start, config)?;
    let covariance = covariance_at(problem, &fit.model, fit.gate_px, fit.rms_px);
    Ok(Refined {
        model: fit.model,
        rms_px: fit.rms_px,
        outliers: fit.outliers,
        covariance,
    })
}

/// Both robust phases, then the residual statistics at the optimum.
#[inline(never)]
fn fit(
    problem: &Problem<'_>,
    start: WorkcellModel,
    config: &CalibrationConfig,
) -> Result<Fit, CalibrationError> {
    let sigma = config.pixel_sigma;
    let phase1 = Loss {
        huber_px: config.huber_k * sigma,
        gate_px: None,
    };
    let model = minimise(problem, start, &phase1, config.max_iterations)?;
    let sigma_robust = robust_sigma(problem, &model, sigma).max(sigma * 0.25);
    let phase2 = Loss {
        huber_px: config.huber_k * sigma_robust,
        gate_px: Some(config.outlier_gate_sigma * sigma_robust.max(sigma)),
    };
    let model = minimise(problem, model, &phase2, config.max_iterations)?;
    let gate = phase2.gate_px.unwrap_or(f64::INFINITY);
    let mut sum_squares = 0.0;
    let mut kept = 0u32;
    let mut outliers = 0u32;
    for_each_observation(
        problem.frames,
        problem.effectors,
        problem.feature_count,
        problem.reference_radius_m,
        |observation| match model.residual(&problem.pinhole, observation) {
            Some(r) if r.norm() <= gate => {
                sum_squares += r.norm_squared();
                kept += 1;
            }
            _ => outliers += 1,
        },
    );
    if kept == 0 {
        return Err(CalibrationError::NumericalFailure {
            stage: "bundle adjustment (no inliers)",
        });
    }
    let rms_px = libm::sqrt(sum_squares / f64::from(kept));
    Ok(Fit {
        model,
        rms_px,
        outliers,
        gate_px: gate,
    })
}

/// Covariance of the Gauss-Newton fit at the optimum, with the measured noise level.
#[inline(never)]
fn covariance_at(
    problem: &Problem<'_>,
    model: &WorkcellModel,
    gate: f64,
    rms_px: f64,
) -> Option<Normal> {
    let unit = Loss {
        huber_px: f64::INFINITY,
        gate_px: Some(gate),
    };
    let mut normal = Normal::zeros();
    let mut gradient = Gradient::zeros();
    normal_equations(problem, model, &unit, &mut normal, &mut gradient);
    for i in 0..PARAMETERS {
        if frozen(problem, i) {
            for j in 0..PARAMETERS {
                let value = if i == j { 1.0 } else { 0.0 };
                if let Some(e) = normal.get_mut((i, j)) {
                    *e = value;
                }
                if let Some(e) = normal.get_mut((j, i)) {
                    *e = value;
                }
            }
        }
    }
    let variance = (rms_px * rms_px / 2.0).max(1e-30);
    if !normal.try_inverse_mut() {
        return None;
    }
    normal *= variance;
    // Frozen parameters are known exactly.
    for i in 0..PARAMETERS {
        if frozen(problem, i) {
            if let Some(e) = normal.get_mut((i, i)) {
                *e = 0.0;
            }
        }
    }
    Some(normal)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A symmetric positive-definite matrix of the normal equations' size.
    fn spd(seed: u64) -> Normal {
        let mut state = seed;
        let m = Normal::from_fn(|_, _| crate::test_rng::splitmix(&mut state) - 0.5);
        m * m.transpose() + Normal::identity() * 0.1
    }

    #[test]
    fn the_in_place_solve_agrees_with_nalgebras_cholesky() {
        for seed in 1..20 {
            let a = spd(seed);
            let b = Gradient::from_fn(|i, _| (i as f64 * 0.37).sin());
            let expected = nalgebra::Cholesky::new(a).unwrap().solve(&b);
            let (mut factor, mut x) = (a, b);
            assert!(cholesky_solve_in_place(&mut factor, &mut x));
            let scale = expected.norm();
            assert!((x - expected).norm() <= 1e-9 * scale, "seed {seed}");
            assert!((a * x - b).norm() <= 1e-9 * b.norm() * a.norm());
        }
    }

    #[test]
    fn a_matrix_that_is_not_positive_definite_is_refused() {
        let mut a = spd(3);
        if let Some(e) = a.get_mut((5, 5)) {
            *e = -1.0;
        }
        let mut b = Gradient::zeros();
        assert!(!cholesky_solve_in_place(&mut a, &mut b));
        let mut nan = spd(4);
        if let Some(e) = nan.get_mut((0, 0)) {
            *e = f64::NAN;
        }
        assert!(!cholesky_solve_in_place(&mut nan, &mut b));
    }
}
