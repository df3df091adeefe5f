//! The maximum-likelihood limit of a log: a full batch solve over EVERY frame
//! and EVERY end-effector sighting of an observation log, with unbounded memory,
//! to measure how much the fixed-memory calibrator (`shared::calibration`,
//! at most 1024 stored frames, evenly thinned beyond) gives away.
//!
//! Unknowns: the camera pose in the disc frame (6), the part's feature points
//! in the rotating frame (3 each) and `base_from_disc` (yaw and translation;
//! the translation's z is held at the disc height in the base frame when the
//! configuration gives it, the paper's experiment 2). Observations: the disc
//! centre, the reference point `(L cos theta, L sin theta, 0)`, the part's
//! features (Eq 1) and the end-effector points known in the base frame (Eq 9).
//! With Gaussian pixel noise the plain least-squares minimum is the
//! maximum-likelihood estimate; gross outliers are gated as the calibrator
//! gates them ([`gate`]). The projection, its Jacobians and the solver are
//! this module's own, independent of `shared::calibration::refine`; only the
//! start is the calibrator's estimate, and the optimum does not depend on it
//! (the tests start from a perturbed point and land on the same optimum).
//!
//! One concept per module:
//! - [`observations`]: the log flattened into observations.
//! - [`model`]: the parameterisation, projection and analytic Jacobians.
//! - [`solver`]: dense Levenberg-Marquardt over a fixed set of observations.
//! - [`gate`]: the outlier gate (5 robust sigmas).
//! - [`covariance`]: the Cramér-Rao bound at the optimum.
//! - [`result`]: to and from the contract's calibration result.

pub mod covariance;
pub mod gate;
pub mod model;
pub mod observations;
pub mod result;
pub mod solver;

use std::fmt;

use shared::calibration::{CalibrationConfig, EstimateUncertainty};
use shared::observation::{CalibrationQuality, CalibrationResult};

use crate::log::ObservationLog;
use model::Layout;
use solver::Problem;

/// Most rounds of gating and fitting before the kept set must have settled.
const MAX_GATE_ROUNDS: u32 = 20;

/// Why the batch solve has no answer.
#[derive(Debug, Clone, PartialEq)]
pub enum BatchError {
    /// A part detection with the wrong number of features.
    FeatureCount {
        frame: usize,
        expected: usize,
        found: usize,
    },
    /// Fewer residuals than unknowns.
    TooFewObservations {
        observations: usize,
        parameters: usize,
    },
    /// A kept point lies behind the camera at the current model.
    BehindCamera { frame: usize },
    /// The start puts a point behind the camera.
    StartBehindCamera,
    /// The normal equations are singular.
    Singular { stage: &'static str },
}

impl fmt::Display for BatchError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::FeatureCount {
                frame,
                expected,
                found,
            } => write!(
                f,
                "frame {frame}: {found} part features, the header says {expected}"
            ),
            Self::TooFewObservations {
                observations,
                parameters,
            } => write!(
                f,
                "{observations} image points are too few for {parameters} unknowns"
            ),
            Self::BehindCamera { frame } => {
                write!(f, "frame {frame}: a kept point is behind the camera")
            }
            Self::StartBehindCamera => write!(f, "the start puts a point behind the camera"),
            Self::Singular { stage } => write!(f, "singular normal equations: {stage}"),
        }
    }
}

impl std::error::Error for BatchError {}

/// The batch estimate with its Cramér-Rao uncertainty.
#[derive(Debug, Clone)]
pub struct BatchEstimate {
    /// In the contract's format. `quality.pixel_sigma_px` is the robust
    /// (median-based) per-axis sigma of all residuals, as the calibrator reports it.
    pub result: CalibrationResult,
    /// One-sigma uncertainties, `sigma^2 (J^T J)^-1` at the optimum.
    pub uncertainty: EstimateUncertainty,
    /// Per-axis pixel sigma from the kept residuals, `sqrt(sum |r|^2 / (2 N - parameters))`:
    /// what scales the covariance.
    pub measured_sigma_px: f64,
    /// Image points in the log, and how many the gate kept.
    pub observations: usize,
    pub observations_kept: usize,
    /// Unknowns solved for.
    pub parameters: usize,
    /// Levenberg-Marquardt iterations over all rounds, and the gate's rounds.
    pub iterations: u32,
    pub gate_rounds: u32,
    /// Whether the kept set settled within the rounds allowed.
    pub gate_settled: bool,
}

/// The batch maximum-likelihood estimate of `log`, started from `start` (the
/// calibrator's estimate, or any nearby point). `config` gives the known disc
/// height, the outlier gate (`outlier_gate_sigma`) and its floor (`pixel_sigma`).
pub fn batch_estimate(
    log: &ObservationLog,
    config: &CalibrationConfig,
    start: &CalibrationResult,
) -> Result<BatchEstimate, BatchError> {
    let camera = &log.header.camera;
    let observations = observations::observations_of(log)?;
    let layout = Layout {
        feature_count: log.header.part_feature_count,
        base_free: observations
            .iter()
            .any(|o| matches!(o.target, observations::Target::Effector(_))),
        base_height_free: config.disc_height_in_base_m.is_none(),
    };
    if start.part.features_m.len() != layout.feature_count {
        return Err(BatchError::FeatureCount {
            frame: 0,
            expected: layout.feature_count,
            found: start.part.features_m.len(),
        });
    }
    let mut model = result::model_from_result(start, config.disc_height_in_base_m);
    let mut inliers: Vec<bool> = Vec::new();
    let mut iterations = 0;
    let mut cost = f64::INFINITY;
    let mut gate_rounds = 0;
    let mut gate_settled = false;
    while gate_rounds < MAX_GATE_ROUNDS {
        let norms = gate::residual_norms(camera, &model, &observations);
        let gate_px = gate::gate_px(&norms, config.outlier_gate_sigma, config.pixel_sigma);
        let kept = gate::kept(&norms, gate_px);
        if kept == inliers {
            gate_settled = true;
            break;
        }
        inliers = kept;
        gate_rounds += 1;
        let kept_count = inliers.iter().filter(|k| **k).count();
        if 2 * kept_count <= layout.parameter_count() {
            return Err(BatchError::TooFewObservations {
                observations: kept_count,
                parameters: layout.parameter_count(),
            });
        }
        let problem = Problem {
            camera,
            layout,
            observations: &observations,
            inliers: &inliers,
        };
        let fit = solver::least_squares(&problem, model)?;
        iterations += fit.iterations;
        model = fit.model;
        cost = fit.cost;
    }
    let problem = Problem {
        camera,
        layout,
        observations: &observations,
        inliers: &inliers,
    };
    let covariance = covariance::covariance_at(&problem, &model, cost)?;
    let uncertainty = covariance.uncertainty(&layout, &model);
    let quality = quality(log, &observations, &inliers, cost, &model, camera);
    Ok(BatchEstimate {
        result: result::result_from_model(&model, quality),
        uncertainty,
        measured_sigma_px: covariance.pixel_sigma_px,
        observations: observations.len(),
        observations_kept: inliers.iter().filter(|k| **k).count(),
        parameters: layout.parameter_count(),
        iterations,
        gate_rounds,
        gate_settled,
    })
}

/// The fit's quality in the contract's terms: frames with at least one kept
/// point, frames whose end-effector sighting kept a point, the RMS 2-D
/// reprojection distance of the kept points, the points gated out and the
/// robust per-axis sigma of all residuals.
fn quality(
    log: &ObservationLog,
    observations: &[observations::Observation],
    inliers: &[bool],
    cost: f64,
    model: &model::BatchModel,
    camera: &shared::observation::CameraIntrinsics,
) -> CalibrationQuality {
    let mut frame_used = vec![false; log.frames.len()];
    let mut effector_used = vec![false; log.frames.len()];
    for (observation, _) in observations
        .iter()
        .zip(inliers.iter())
        .filter(|(_, kept)| **kept)
    {
        if let Some(used) = frame_used.get_mut(observation.frame) {
            *used = true;
        }
        if matches!(observation.target, observations::Target::Effector(_)) {
            if let Some(used) = effector_used.get_mut(observation.frame) {
                *used = true;
            }
        }
    }
    let count =
        |flags: &[bool]| u32::try_from(flags.iter().filter(|f| **f).count()).unwrap_or(u32::MAX);
    let kept = inliers.iter().filter(|k| **k).count();
    CalibrationQuality {
        frames_used: count(&frame_used),
        rms_reprojection_px: (cost / kept.max(1) as f64).sqrt(),
        effector_frames_used: count(&effector_used),
        outliers_rejected: u32::try_from(observations.len() - kept).unwrap_or(u32::MAX),
        pixel_sigma_px: gate::robust_sigma_px(&gate::residual_norms(camera, model, observations)),
    }
}
