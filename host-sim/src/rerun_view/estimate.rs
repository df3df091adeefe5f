//! The controller's side, from its telemetry: its estimate of the part's
//! pose in the base frame, where it wants the tool, its phases; and the
//! estimate against the truth at the telemetry's own instant (scoring only).

use anyhow::Result;
use nalgebra::Vector3;
use rerun::{Clear, Points3D, RecordingStream, Scalars, TextLog};
use shared::protocol::{PickPhase, PickTelemetry};

use super::cell::log_pose;
use super::names::{self, colour};
use crate::geometry::angle_distance;
use crate::world::WorldTruth;

/// What was last logged of the controller's side.
#[derive(Debug, Default)]
pub struct EstimateLog {
    phase: Option<PickPhase>,
    had_estimate: bool,
}

fn to_f64(v: [f32; 3]) -> Vector3<f64> {
    Vector3::from(v.map(f64::from))
}

impl EstimateLog {
    /// Logs one telemetry message at the truth's instant (the caller set
    /// the time).
    pub fn log(
        &mut self,
        rec: &RecordingStream,
        telemetry: &PickTelemetry,
        truth: &WorldTruth,
    ) -> Result<()> {
        if self.phase != Some(telemetry.phase) {
            self.phase = Some(telemetry.phase);
            let fault = telemetry
                .fault
                .map(|cause| format!(" ({cause:?})"))
                .unwrap_or_default();
            rec.log(
                names::PHASES,
                &TextLog::new(format!("{:?}{fault}", telemetry.phase)),
            )?;
        }
        rec.log(
            names::TOOL_REFERENCE,
            &Points3D::new([telemetry.tool_reference_base_m])
                .with_labels(["tool reference"])
                .with_colors([colour(names::ESTIMATE_COLOUR)])
                .with_radii([0.005]),
        )?;
        match telemetry.part_base_m {
            Some(estimate) => {
                let estimate_base_m = to_f64(estimate);
                let yaw_rad = f64::from(telemetry.part_yaw_base_rad);
                log_pose(rec, names::PART_ESTIMATE_POSE, &estimate_base_m, yaw_rad)?;
                rec.log(
                    names::PART_ESTIMATE,
                    &Points3D::new([estimate])
                        .with_labels(["estimate"])
                        .with_colors([colour(names::ESTIMATE_COLOUR)])
                        .with_radii([0.008]),
                )?;
                let error_m = (estimate_base_m - Vector3::from(truth.part_base_m)).norm();
                rec.log(names::PART_ERROR_MM, &Scalars::single(error_m * 1e3))?;
                rec.log(
                    names::PART_SIGMA_MM,
                    &Scalars::single(f64::from(telemetry.part_sigma_m) * 1e3),
                )?;
                // Two fingers: a yaw half a turn off grasps the same.
                let yaw_error_rad = angle_distance(yaw_rad, truth.part_yaw_rad).min(
                    angle_distance(yaw_rad + std::f64::consts::PI, truth.part_yaw_rad),
                );
                rec.log(
                    names::PART_YAW_ERROR_DEG,
                    &Scalars::single(yaw_error_rad.to_degrees()),
                )?;
                self.had_estimate = true;
            }
            None if self.had_estimate => {
                rec.log(names::PART_ESTIMATE_POSE, &Clear::flat())?;
                rec.log(names::PART_ESTIMATE, &Clear::flat())?;
                self.had_estimate = false;
            }
            None => {}
        }
        Ok(())
    }
}
