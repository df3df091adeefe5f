//! Self-calibration from vision (paper Sections 2 and 3): conic fit of the reference
//! point's image, virtual rotation, part localisation with heights, and the
//! robot-base-to-disc transform, followed by a robust bundle adjustment.
//!
//! Use: [`SelfCalibrator::new`] with the log header and a [`CalibrationConfig`], then
//! [`SelfCalibrator::push`] every frame (an invalid frame is refused with a typed error and
//! changes nothing), then [`SelfCalibrator::estimate`] (maximum likelihood, robust) or
//! [`SelfCalibrator::paper_estimate`] (the paper's own two-frame / one-pose method, for
//! comparison). [`SelfCalibrator::estimate_with_uncertainty`] adds standard deviations.
//!
//! How `estimate` gets there: the disc-plane homography of the centre and reference
//! detections (theta-aware, so a quarter turn suffices) gives the camera pose; if it cannot
//! be had, the paper's virtual rotation does (robust conic, Steps 1 to 4). Eq 8 over all
//! frames gives the features, Eqs 10 to 15 over all sightings `base_from_disc`. A
//! Levenberg-Marquardt bundle adjustment over every stored detection (Huber loss, then a
//! 5-sigma gate) then reaches the likelihood optimum: the tests show that it lands on the
//! same solution as when started from the true workcell, and that its reported standard
//! deviations match the actual errors.
//!
//! One concept per module:
//! - [`conic`]: Step 2, recursive least-squares ellipse fit with normalisation.
//! - [`virtual_rotation`]: Steps 1, 3, 4 (`R_k`, `R_z`, `R_y`), camera height and pose.
//! - [`homography`]: beyond the paper, a theta-aware start that also works on short arcs.
//! - [`part`]: Eqs 3 to 8, feature points with heights by least squares over all frames.
//! - [`effector`]: Eqs 10 to 15, end-effector depths and `base_from_disc`.
//! - [`model`], [`pinhole`]: the workcell model and the contract's camera.
//! - [`refine`]: robust Levenberg-Marquardt bundle adjustment (maximum likelihood).
//! - [`normal_blocks`]: its arrowhead normal equations, solved by the Schur complement.
//! - [`cholesky`]: the in-place Cholesky factorisation those solves use.
//! - [`uncertainty`]: standard deviations of the refined estimate.
//! - [`store`], [`records`]: bounded, thinned storage of observations (f32 pixels).
//! - [`frame_store`]: the frames' store, packed at the part's feature count.
//! - [`folded`]: what the stores have no room for, kept as normal equations.
//! - [`recent_bias`]: the latest folded points' mean residual: a creeping camera.
//! - [`calibrator`]: [`SelfCalibrator`], the incremental estimator tying it together.

pub mod calibrator;
pub mod cholesky;
pub mod config;
pub mod conic;
pub mod effector;
pub mod error;
pub mod folded;
pub mod frame_store;
pub mod homography;
pub mod model;
pub mod normal_blocks;
pub mod part;
pub mod pinhole;
pub mod recent_bias;
pub mod records;
pub mod refine;
pub mod rim;
pub mod store;
pub mod uncertainty;
pub mod virtual_rotation;

/// `value > threshold`, false for NaN: `!exceeds(x, t)` rejects NaN along with small values.
pub(crate) fn exceeds(value: f64, threshold: f64) -> bool {
    value > threshold
}

pub use calibrator::{FirmwareCalibrator, HostCalibrator, SelfCalibrator};
pub use config::CalibrationConfig;
pub use error::{CalibrationError, ConicKind};
pub use uncertainty::EstimateUncertainty;
