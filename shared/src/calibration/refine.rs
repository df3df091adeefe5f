//! Beyond the paper: robust Levenberg-Marquardt bundle adjustment over every stored
//! observation — camera pose (6), feature points (3 each) and `base_from_disc` (4, or 3
//! when the disc height is known) — with the disc centre and the reference point
//! `(L cos theta, L sin theta, 0)` as observations of known disc points.
//!
//! With Gaussian pixel noise this is the maximum-likelihood estimate; gross outliers are
//! handled by a Huber loss (phase 1) and then a hard gate on the residual at
//! `outlier_gate_sigma` robust sigmas (phase 2). Memory is fixed whatever the number of
//! frames: the normal equations are kept as the arrowhead's blocks and solved by the
//! Schur complement ([`super::normal_blocks`]), 2.8 KiB instead of a dense 34x34 matrix.

use super::config::CalibrationConfig;
use super::error::CalibrationError;
use super::folded::FoldedInformation;
use super::frame_store::FrameView;
use super::model::{for_each_observation, Observation, Projector, WorkcellModel};
use super::normal_blocks::{
    Freedom, Increment, MarginalCovariance, NormalBlocks, NormalRun, RUN_POINTS,
};
use super::pinhole::Pinhole;
use super::records::EffectorRecord;
use super::rim::RimSummary;

/// What the refinement sees: stored observations and how to treat them.
#[derive(Clone, Copy)]
pub struct Problem<'a> {
    /// The camera.
    pub pinhole: Pinhole,
    /// The stored frames.
    pub frames: FrameView<'a>,
    /// The stored sightings.
    pub effectors: &'a [EffectorRecord],
    /// How many features the part has.
    pub feature_count: usize,
    /// The paper's L, m.
    pub reference_radius_m: f64,
    /// Fix `base_translation.z` (known disc height) instead of estimating it.
    pub fix_base_height: bool,
    /// The observations the store had no room for, as normal equations.
    pub folded: Option<&'a FoldedInformation>,
    /// The disc's rim averaged over the frames, where it was measured.
    pub rim: Option<&'a RimSummary>,
}

impl Problem<'_> {
    /// Calls `visit` for every stored image point (frames, then sightings).
    pub fn for_each_observation(&self, visit: impl FnMut(&Observation)) {
        for_each_observation(
            self.frames,
            self.effectors,
            self.feature_count,
            self.reference_radius_m,
            visit,
        );
    }
}

/// Robust weighting of one phase: Huber threshold and optional hard gate (pixels).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Loss {
    huber_px: f64,
    gate_px: Option<f64>,
    /// The noise this phase assumes, px: what counts as progress is measured
    /// in its variance ([`PROGRESS_CHI2`]), and the rim is weighed against it.
    sigma_px: f64,
    /// Whether the pass adds the rim's terms (not the covariance's pass,
    /// whose noise is measured in that pass: `at_optimum` adds them after).
    weighs_rim: bool,
}

impl Loss {
    /// The least decrease of the cost (px^2) that an iteration must make.
    fn progress_px2(&self) -> f64 {
        0.5 * PROGRESS_CHI2 * self.sigma_px * self.sigma_px
    }

    /// IRLS weight of a residual of squared norm `r2` (its root taken only
    /// beyond the Huber threshold).
    fn weight(&self, r2: f64) -> f64 {
        if let Some(gate) = self.gate_px {
            if r2 > gate * gate {
                return 0.0;
            }
        }
        if r2 <= self.huber_px * self.huber_px {
            1.0
        } else {
            self.huber_px / norm_from_squared(r2)
        }
    }

    /// Huber cost of a residual of squared norm `r2`, constant beyond the gate
    /// (a gated point neither pulls nor pays more).
    /// A point pushed behind the camera pays the gate's price.
    fn behind_camera_cost(&self) -> f64 {
        self.cost(self.gate_px.map_or(1e12, |gate| gate * gate))
    }

    fn cost(&self, r2: f64) -> f64 {
        let k = self.huber_px;
        let capped = match self.gate_px {
            Some(gate) if r2 > gate * gate => gate * gate,
            _ => r2,
        };
        if capped <= k * k {
            0.5 * capped
        } else {
            k * norm_from_squared(capped) - 0.5 * k * k
        }
    }
}

/// `sqrt(r2)` through f32: good to 1e-7 of itself, what a Huber weight, a Huber
/// cost beyond the threshold and a histogram bin need; an f64 square root is a
/// bit-by-bit software loop on the Cortex-M4F, several times the f32 one.
fn norm_from_squared(r2: f64) -> f64 {
    if r2 < f64::from(f32::MAX) {
        f64::from(libm::sqrtf(r2 as f32))
    } else {
        libm::sqrt(r2)
    }
}

/// Result of the refinement with its fit statistics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refined {
    /// The refined workcell.
    pub model: WorkcellModel,
    /// RMS 2-D reprojection distance over the points kept (px).
    pub rms_px: f64,
    /// The pixel noise measured from the residuals at the optimum: a robust
    /// per-axis standard deviation (px), which overrides the configured prior.
    pub pixel_sigma_px: f64,
    /// Points beyond the gate.
    pub outliers: u32,
    /// Inverse of the Gauss-Newton information matrix scaled by sigma^2: the parameter
    /// covariance of the camera, the base and the part position.
    pub covariance: Option<MarginalCovariance>,
}

fn total_cost(problem: &Problem<'_>, model: &WorkcellModel, loss: &Loss) -> f64 {
    let mut cost = 0.0;
    let projector = Projector::<f64>::new(model, &problem.pinhole);
    problem.for_each_observation(|observation| {
        cost += match projector.residual(observation) {
            Some(r) => loss.cost(r.norm_squared()),
            None => loss.behind_camera_cost(),
        };
    });
    cost + problem.folded.map_or(0.0, |folded| folded.cost(model))
        + problem
            .rim
            .map_or(0.0, |rim| rim.cost(model, &problem.pinhole, loss.sigma_px))
}

/// What the normal equations are summed in.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Sums {
    /// Each point's Jacobian and products in f32, over runs of [`RUN_POINTS`],
    /// the runs in f64: on the Cortex-M4F, whose FPU has no f64, the f64 pass
    /// was almost all software floating point.
    Mixed,
    /// All in f64: for a system too near singular for f32's rounding
    /// ([`NormalBlocks::weakest_pivot_ratio`] under [`MIN_MIXED_PIVOT_RATIO`]).
    Double,
}

/// The weakest pivot ratio at which [`Sums::Mixed`] is kept: f32 sums move
/// the entries by about 1e-6 of the diagonal, a hundredth of this.
/// docs/calibration.md ("Precision") has the measured ratios.
const MIN_MIXED_PIVOT_RATIO: f64 = 1e-4;

/// What a pass over the points sums beside the normal equations, from the
/// same residuals: on the Cortex-M4F a pass is millions of instructions, so
/// the first iteration of a phase takes its starting cost from here and the
/// covariance's pass gives the fit's statistics.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct PassSums {
    /// The loss's cost at the model: [`total_cost`]'s when the pass computed
    /// its residuals in f64.
    cost: f64,
    /// Squared residual norms of the points the loss keeps (weight above 0).
    kept_squares: f64,
    /// Those points.
    kept: u32,
    /// Points gated out or behind the camera.
    dropped: u32,
}

impl PassSums {
    /// One point's residual of squared norm `r2` (`None`: behind the camera).
    fn add(&mut self, loss: &Loss, r2: Option<f64>) -> f64 {
        let Some(r2) = r2 else {
            self.cost += loss.behind_camera_cost();
            self.dropped = self.dropped.saturating_add(1);
            return 0.0;
        };
        self.cost += loss.cost(r2);
        let weight = loss.weight(r2);
        if weight == 0.0 || r2.is_nan() {
            self.dropped = self.dropped.saturating_add(1);
        } else {
            self.kept_squares += r2;
            self.kept = self.kept.saturating_add(1);
        }
        weight
    }
}

/// The Gauss-Newton normal equations at `model`, in arrowhead blocks written
/// into the caller's `blocks` (filled in place rather than returned: no second
/// copy on a firmware stack), and what the pass sums beside them (the folded
/// observations' cost included, not their points). With `exact_cost` the pass's cost is the f64 [`total_cost`]'s (the first
/// pass of a phase, whose cost the phase compares its steps with); without,
/// a [`Sums::Mixed`] pass computes every point in f32 and its cost is good
/// only for statistics (RMS, outliers).
fn normal_equations(
    problem: &Problem<'_>,
    model: &WorkcellModel,
    loss: &Loss,
    sums: Sums,
    exact_cost: bool,
    blocks: &mut NormalBlocks,
) -> PassSums {
    *blocks = NormalBlocks::zeros();
    let mut pass = match sums {
        Sums::Mixed => mixed_normal_equations(problem, model, loss, exact_cost, blocks),
        Sums::Double => {
            let mut pass = PassSums::default();
            let projector = Projector::<f64>::new(model, &problem.pinhole);
            problem.for_each_observation(|observation| {
                let point = projector.residual_with_jacobian(observation);
                let weight = pass.add(loss, point.map(|(r, _)| r.norm_squared()));
                if let Some((residual, jacobian)) = point.filter(|_| weight != 0.0) {
                    blocks.accumulate(&jacobian.camera, &jacobian.other, &residual, weight);
                }
            });
            pass
        }
    };
    if let Some(folded) = problem.folded {
        folded.add_to(blocks, model);
        pass.cost += folded.cost(model);
    }
    // The rim's weight is relative to the pixel noise the loss assumes; the
    // covariance's pass adds it once that noise is measured (`at_optimum`).
    if let (Some(rim), true) = (problem.rim, loss.weighs_rim) {
        rim.add_to(blocks, model, &problem.pinhole, loss.sigma_px);
        pass.cost += rim.cost(model, &problem.pinhole, loss.sigma_px);
    }
    pass
}

/// [`Sums::Mixed`]: the points' residuals, Jacobians and products in f32
/// (with `exact_cost` the residuals the cost is summed from in f64 as well),
/// summed over runs of [`RUN_POINTS`] in f32 and the runs in f64. The f32
/// residuals move the step by what some 3e-5 px on every point would: the
/// iterations still stop where the f64 cost does (its comparisons decide).
fn mixed_normal_equations(
    problem: &Problem<'_>,
    model: &WorkcellModel,
    loss: &Loss,
    exact_cost: bool,
    blocks: &mut NormalBlocks,
) -> PassSums {
    let mut run = NormalRun::zeros();
    let mut in_run = 0u32;
    let mut pass = PassSums::default();
    let features = problem.feature_count;
    let single = Projector::<f32>::new(model, &problem.pinhole);
    let double = exact_cost.then(|| Projector::<f64>::new(model, &problem.pinhole));
    problem.for_each_observation(|observation| {
        let point = single.residual_with_jacobian(observation);
        let squared = match &double {
            Some(double) => double.residual(observation).map(|r| r.norm_squared()),
            None => point.map(|(r, _)| f64::from(r.norm_squared())),
        };
        let weight = pass.add(loss, squared);
        let Some((residual, jacobian)) = point.filter(|_| weight != 0.0) else {
            return;
        };
        run.accumulate(&jacobian.camera, &jacobian.other, &residual, weight as f32);
        in_run += 1;
        if in_run == RUN_POINTS {
            blocks.add_run(&mut run, features);
            in_run = 0;
        }
    });
    blocks.add_run(&mut run, features);
    pass
}

/// What the data can move: unused feature slots, the base without sightings and a
/// known base height are held.
fn freedom(problem: &Problem<'_>) -> Freedom {
    let base = !problem.effectors.is_empty()
        || problem.folded.is_some_and(|folded| folded.sightings() > 0);
    Freedom {
        feature_count: problem.feature_count,
        base_free: [base, base, base, base && !problem.fix_base_height],
    }
}

/// An iteration is progress when it lowers the chi-square (the cost over half
/// the noise's variance) by more than this: a step that moves the estimate
/// by a thousandth of its standard deviation along the step. Smaller ones
/// change nothing a cell can use, and on the Cortex-M4F every iteration is a
/// pass over every point (some 30 million instructions for the pick's final
/// estimate): the earlier rule, a relative decrease of 1e-12 of the cost, ran
/// each phase to the last digit, 10 passes and 8 cost evaluations for the
/// pick's final estimate (experiment-2-7cm seed 1) where this takes 8 and 6,
/// with the same estimate to the micrometre. At 1e-4 it took 6 and 4, but
/// two solutions of the same data from different starts then differed by
/// 0.3 % of their error (`calibration_optimum`); at 1e-6, by 0.06 % at most.
const PROGRESS_CHI2: f64 = 1e-6;

/// The Gauss-Newton model's decrease of the cost for `step`:
/// `-(g^T x + x^T N x / 2)`.
fn predicted_decrease(blocks: &NormalBlocks, step: &Increment) -> f64 {
    -(blocks.gradient().dot(step) + 0.5 * step.dot(&blocks.apply(step)))
}

/// Levenberg-Marquardt on one loss; returns the improved model.
fn minimise(
    problem: &Problem<'_>,
    start: WorkcellModel,
    loss: &Loss,
    max_iterations: u32,
    sums: &mut Sums,
) -> Result<WorkcellModel, CalibrationError> {
    let mut model = start;
    // The model's cost: from the first pass over the points, then from the
    // accepted candidate's evaluation.
    let mut cost = f64::INFINITY;
    let mut damping = 1e-4;
    let freedom = freedom(problem);
    let mut blocks = NormalBlocks::zeros();
    for iteration in 0..max_iterations {
        // Only the first pass's cost is read: later ones come from the
        // accepted candidates' f64 evaluations.
        let first = iteration == 0;
        let mut at_model = normal_equations(problem, &model, loss, *sums, first, &mut blocks).cost;
        if first
            && *sums == Sums::Mixed
            && blocks.weakest_pivot_ratio(&freedom) < MIN_MIXED_PIVOT_RATIO
        {
            *sums = Sums::Double;
            at_model = normal_equations(problem, &model, loss, *sums, first, &mut blocks).cost;
        }
        if iteration == 0 {
            cost = at_model;
        }
        let mut improved = false;
        while damping < 1e10 {
            let Some(step) = blocks.damped_step(&freedom, damping) else {
                damping *= 10.0;
                continue;
            };
            if !step.iter().all(|v| v.is_finite()) {
                return Err(CalibrationError::NumericalFailure {
                    stage: "bundle adjustment step",
                });
            }
            // What the quadratic model promises; once that is below what the
            // loop counts as progress, no damping can make a step that counts
            // (without this stop, each phase's last iteration evaluated the
            // cost some thirty times while the damping climbed to its limit).
            if predicted_decrease(&blocks, &step) <= loss.progress_px2() {
                break;
            }
            let candidate = model.retract(&step);
            let candidate_cost = total_cost(problem, &candidate, loss);
            if candidate_cost <= cost {
                let decrease = cost - candidate_cost;
                model = candidate;
                cost = candidate_cost;
                damping = (damping / 3.0).max(1e-9);
                improved = decrease > loss.progress_px2() && step.norm() > 1e-13;
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
/// number of points): median of a 2-D Gaussian residual's norm is 1.1774 sigma. The
/// histogram spans 32 `nominal_sigma`; the median is interpolated within its bin.
/// Out of line, so that its histogram is not in `fit`'s frame under `minimise`.
#[inline(never)]
fn robust_sigma(problem: &Problem<'_>, model: &WorkcellModel, nominal_sigma: f64) -> f64 {
    const BINS: usize = 128;
    const RANGE_SIGMAS: f64 = 32.0;
    let bin_width = nominal_sigma * RANGE_SIGMAS / BINS as f64;
    let mut histogram = [0u32; BINS];
    let mut total = 0u32;
    // f32 residuals: a histogram bin is a 128th of 32 sigmas wide.
    let projector = Projector::<f32>::new(model, &problem.pinhole);
    problem.for_each_observation(|observation| {
        let r = projector
            .residual(observation)
            .map_or(f64::INFINITY, |r| f64::from(libm::sqrtf(r.norm_squared())));
        let bin = if r.is_finite() {
            (r / bin_width) as usize
        } else {
            BINS - 1
        };
        if let Some(count) = histogram.get_mut(bin.min(BINS - 1)) {
            *count += 1;
        }
        total += 1;
    });
    let half = f64::from(total) / 2.0;
    let mut running = 0u32;
    for (bin, count) in histogram.iter().enumerate() {
        let before = f64::from(running);
        running += count;
        if f64::from(running) > half {
            let within = (half - before) / f64::from((*count).max(1));
            let median = (bin as f64 + within) * bin_width;
            return median / 1.1774;
        }
    }
    nominal_sigma * RANGE_SIGMAS
}

/// The pixel noise of `model`'s residuals: a first robust scale on the prior's
/// histogram, then a second on a histogram sized by the first (fine bins
/// whatever the noise is, between a sixteenth and 16 times the prior).
pub(super) fn measured_sigma(problem: &Problem<'_>, model: &WorkcellModel, prior: f64) -> f64 {
    let first = robust_sigma(problem, model, prior).clamp(prior / 16.0, prior * 16.0);
    robust_sigma(problem, model, first)
}

/// The fit of both phases before its statistics and covariance.
struct Fit {
    model: WorkcellModel,
    sums: Sums,
    gate_px: f64,
}

/// Runs both phases and reports the fit.
///
/// The two halves are separate, never-inlined functions so that their working
/// sets (each holds its own 2.8 KiB [`NormalBlocks`]) are never on the stack at
/// the same time (the firmware's RAM budget).
#[inline(never)]
pub fn refine(
    problem: &Problem<'_>,
    start: WorkcellModel,
    config: &CalibrationConfig,
) -> Result<Refined, CalibrationError> {
    let fit = fit(problem, start, config)?;
    let optimum = at_optimum(problem, &fit.model, fit.sums, fit.gate_px)?;
    let pixel_sigma_px = measured_sigma(problem, &fit.model, config.pixel_sigma);
    Ok(Refined {
        model: fit.model,
        rms_px: optimum.rms_px,
        pixel_sigma_px,
        outliers: optimum.outliers,
        covariance: optimum.covariance,
    })
}

/// Both robust phases.
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
        sigma_px: sigma,
        weighs_rim: true,
    };
    let mut sums = Sums::Mixed;
    let model = minimise(problem, start, &phase1, config.max_iterations, &mut sums)?;
    let sigma_robust = robust_sigma(problem, &model, sigma).max(sigma * 0.25);
    let phase2 = Loss {
        huber_px: config.huber_k * sigma_robust,
        gate_px: Some(config.outlier_gate_sigma * sigma_robust.max(sigma)),
        sigma_px: sigma_robust,
        weighs_rim: true,
    };
    let model = minimise(problem, model, &phase2, config.max_iterations, &mut sums)?;
    Ok(Fit {
        model,
        sums,
        gate_px: phase2.gate_px.unwrap_or(f64::INFINITY),
    })
}

/// The fit's statistics and covariance at the optimum.
struct Optimum {
    /// RMS of the residuals inside the gate (the folded ones at their
    /// linearisation), px.
    rms_px: f64,
    /// Points outside it (or behind the camera).
    outliers: u32,
    covariance: Option<MarginalCovariance>,
}

/// The residuals' RMS inside the gate and the covariance of the Gauss-Newton
/// fit at the optimum, with that measured noise level: the inverse of the
/// undamped information `J^T J` (unit weights inside the gate) times the
/// per-axis pixel variance `rms^2 / 2`, as far as the uncertainty reads it.
/// One pass over the points gives both.
#[inline(never)]
fn at_optimum(
    problem: &Problem<'_>,
    model: &WorkcellModel,
    sums: Sums,
    gate: f64,
) -> Result<Optimum, CalibrationError> {
    let unit = Loss {
        huber_px: f64::INFINITY,
        gate_px: Some(gate),
        // Only the progress rule reads it, and no iteration runs here.
        sigma_px: 1.0,
        weighs_rim: false,
    };
    let mut blocks = NormalBlocks::zeros();
    let pass = normal_equations(problem, model, &unit, sums, false, &mut blocks);
    let (mut squares, mut kept, mut outliers) = (pass.kept_squares, pass.kept, pass.dropped);
    if let Some(folded) = problem.folded {
        squares += folded.squares();
        kept = kept.saturating_add(folded.points());
        outliers = outliers.saturating_add(folded.outliers());
    }
    if kept == 0 {
        return Err(CalibrationError::NumericalFailure {
            stage: "bundle adjustment (no inliers)",
        });
    }
    let rms_px = libm::sqrt(squares / f64::from(kept));
    let variance = (rms_px * rms_px / 2.0).max(1e-30);
    if let Some(rim) = problem.rim {
        rim.add_to(&mut blocks, model, &problem.pinhole, libm::sqrt(variance));
    }
    Ok(Optimum {
        rms_px,
        outliers,
        covariance: blocks.covariance(&freedom(problem), variance),
    })
}
