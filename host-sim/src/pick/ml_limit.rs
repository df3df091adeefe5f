//! How far the controller's final estimate is from the maximum-likelihood limit
//! of the very data it saw (issue 20): the pick's own log up to its final
//! estimate, solved by the independent full batch solve ([`crate::batch_ml`],
//! every frame and every sighting, unbounded memory), both scored against the
//! world's truth. `host-sim montecarlo --ml-limit` does it for every trial.

use anyhow::{anyhow, Result};

use super::own_log::{controller_estimate, truth_of, LoggedPick};
use crate::accuracy::metrics::{compare, ErrorMetrics};
use crate::batch_ml::batch_estimate;
use crate::log::ObservationLog;

/// The controller's final estimate and the batch solve of its data, each
/// against the truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LimitErrors {
    /// The controller's final estimate's errors.
    pub controller: ErrorMetrics,
    /// The batch solve's errors on the same frames.
    pub limit: ErrorMetrics,
}

/// Solves the frames the controller's final estimate was made from in full
/// batch and scores both estimates. An error when the pick made no final
/// estimate (nothing to compare) or the solve fails.
pub fn limit_of(logged: &LoggedPick) -> Result<LimitErrors> {
    let estimate = controller_estimate(logged, &[])
        .ok_or_else(|| anyhow!("the pick made no final estimate"))?;
    let truth = truth_of(logged);
    let worker = &logged.worker;
    let frames = worker
        .frames
        .get(..estimate.controller.log_frames)
        .ok_or_else(|| anyhow!("the log is shorter than the final estimate's frames"))?;
    let log = ObservationLog {
        header: worker.header,
        frames: frames.to_vec(),
    };
    let batch = batch_estimate(&log, &worker.config, &estimate.result)
        .map_err(|error| anyhow!("batch solve: {error}"))?;
    Ok(LimitErrors {
        controller: compare(&estimate.result, &truth.result)?,
        limit: compare(&batch.result, &truth.result)?,
    })
}
