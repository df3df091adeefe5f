//! The worker: the pick's slow, low-priority part. It owns the self-calibrator
//! (Sections 2 and 3: the ellipse, the virtual rotation, Eqs 3 to 8 and 10 to
//! 15) and runs the jobs the control loop asks for: an estimate (then the poses
//! to show the marks at) or an intercept plan. It never touches the arm; the
//! control loop applies a result at the job's fixed due time.

use heapless::Vec;

use super::build::controller_model;
use super::cell::{Cell, ConfigError};
use super::estimate::CellEstimate;
use super::handoff::{JobOutcome, JobRequest, JobResult, JobTicket, VisionNews, WorkItem};
use super::jobs::{
    calibration_poses, joints_at, part_path_enters_reach, plan_part_intercept, ConveyorSnapshot,
    MAX_CALIBRATION_POSES,
};
use super::motion::Prediction;
use super::pace::{paced, CalibrationPose};
use super::settings::{at_most, PickSettings};
use super::PickCalibrator;
use crate::calibration::CalibrationError;
use crate::observation::ObservationFrame;
use crate::planning::{ArcPoint, InterceptPlan, PlanError, TaskState};
use crate::protocol::{CellConfig, FaultCause};
use crate::robot::Puma560;

/// The calibrator and the job runner.
#[derive(Debug, Clone)]
pub struct PickWorker {
    cell: Cell,
    settings: PickSettings,
    model: Puma560<f32>,
    calibrator: PickCalibrator,
}

impl PickWorker {
    /// The worker for the cell `config`.
    pub fn new(config: &CellConfig, settings: PickSettings) -> Result<Self, ConfigError> {
        let cell = Cell::new(config)?;
        let calibrator = PickCalibrator::new(&cell.log_header(), cell.calibration_config())
            .map_err(|_| {
                ConfigError::new(
                    "camera intrinsics or reference_radius_m",
                    "are refused by the calibrator",
                )
            })?;
        Ok(Self {
            cell,
            settings,
            model: controller_model()?,
            calibrator,
        })
    }

    /// Takes one item of its queue: an observation goes to the calibrator (a
    /// refused one is reported), a job runs to completion.
    pub fn process(&mut self, item: &WorkItem) -> Option<VisionNews> {
        match item {
            WorkItem::Observation(observation) => self.absorb(observation),
            WorkItem::Job(ticket) => Some(VisionNews::Result(self.run(ticket))),
        }
    }

    /// Gives one observation to the calibrator (news when it is refused).
    /// Out of line, like [`PickWorker::plan`]: on the firmware the estimate's
    /// frame lies under the bundle adjustment (the deepest stack, under both
    /// interrupt levels) and a frame is the union of everything inlined into
    /// it, so the observation's and the plan's temporaries stay out of it.
    ///
    /// When this frame fills a store before the pick has adopted an estimate
    /// (a camera of 30 Hz fills 256 frames in 8.5 s, long before the search
    /// ends), the worker estimates the camera and the part from what it holds
    /// and adopts that, so that the frames that follow are folded rather than
    /// thinned away (issue 20: three frames in four of the search were lost).
    /// On the board this one frame then costs an estimate; at the paper's 5 Hz
    /// the stores fill after the pick's own estimates, and it never happens.
    #[inline(never)]
    fn absorb(&mut self, observation: &ObservationFrame) -> Option<VisionNews> {
        match self.calibrator.push(observation) {
            Ok(()) => {
                adopt_before_thinning(&mut self.calibrator);
                None
            }
            Err(_) => Some(VisionNews::Refused),
        }
    }

    /// Runs one job.
    pub fn run(&mut self, ticket: &JobTicket) -> JobResult {
        let outcome = match ticket.request {
            JobRequest::Estimate {
                preliminary,
                time_us,
                start_pose,
                q_now,
                from,
                waist_centre_azimuth,
            } => JobOutcome::Estimate(self.estimate(
                preliminary,
                time_us,
                &start_pose,
                &q_now,
                (&from, waist_centre_azimuth),
            )),
            JobRequest::Plan {
                start,
                q_start,
                conveyor,
                estimate,
            } => JobOutcome::Plan(self.plan(&start, &q_start, &conveyor, &estimate)),
        };
        JobResult {
            session: ticket.session,
            job_id: ticket.job_id,
            outcome,
        }
    }

    /// Plans the intercept (out of line: see [`PickWorker::absorb`]).
    #[inline(never)]
    fn plan(
        &self,
        start: &TaskState<f32>,
        q_start: &crate::robot::JointVector<f32>,
        conveyor: &ConveyorSnapshot,
        estimate: &CellEstimate,
    ) -> Result<(InterceptPlan<f32>, Prediction), PlanError> {
        plan_part_intercept(
            start,
            q_start,
            estimate,
            conveyor,
            &self.settings,
            &self.model,
        )
    }

    /// The estimate is trusted and used: what the calibrator's stores have no
    /// room for from now on is folded at it rather than thinned away (a host
    /// replaying the pick's log adopts where this did: `host-sim calibrate
    /// --adopt-after-frames`).
    fn adopt(&mut self) {
        self.calibrator.adopt_last_estimate();
    }

    /// Self-calibrates, refusing an estimate the pick cannot trust.
    fn estimate(
        &mut self,
        preliminary: bool,
        time_us: u64,
        start_pose: &ArcPoint<f32>,
        q_now: &crate::robot::JointVector<f32>,
        (from, waist_centre_azimuth): (&ArcPoint<f32>, f32),
    ) -> Result<(CellEstimate, Vec<CalibrationPose, MAX_CALIBRATION_POSES>), FaultCause> {
        let (result, sigma) = self
            .calibrator
            .estimate_with_uncertainty()
            .map_err(|error| match error {
                CalibrationError::TooFewObservations {
                    what: "end-effector sightings",
                    ..
                } => FaultCause::EffectorNotSeen,
                // The search waits at its end for frames of the part; none
                // came: say that, not that the calibration failed.
                CalibrationError::TooFewObservations {
                    what: "frames showing the part",
                    found: 0,
                    ..
                } => FaultCause::PartNotSeen,
                _ => FaultCause::CalibrationFailed,
            })?;
        let estimate = CellEstimate::new(&result, &sigma, time_us).with_folding(&self.calibrator);
        let report = &estimate.report;
        let trusted = report.sigma_part_m.is_finite()
            && report.sigma_base_m.is_finite()
            && (preliminary || report.sigma_part_m <= self.settings.max_part_sigma_m)
            && (preliminary || report.sigma_base_m <= self.settings.max_base_sigma_m);
        if !trusted {
            return Err(FaultCause::CalibrationFailed);
        }
        // Robust weights hide a few stray detections, not a second camera
        // pose: views that fit none report it through their residual. The
        // preliminary estimate is held to this as much as the final one: the
        // calibration poses are planned from it, so one that mixes two camera
        // poses would send the arm to heights computed from no real cell.
        if !at_most(
            report.rms_reprojection_px,
            self.settings.max_rms_reprojection_px,
        ) {
            return Err(FaultCause::CameraMoved);
        }
        // Nor a second cell: when the camera moved or the encoder slipped while
        // the calibrator gathered its frames, the views before and after cannot
        // all fit, and the robust fit rejects the minority wholesale.
        let points_per_frame = 2 + u32::from(self.cell.config.part_feature_count);
        let points = result
            .quality
            .frames_used
            .saturating_mul(points_per_frame)
            .max(1);
        let rejected = result.quality.outliers_rejected as f32 / points as f32;
        if !at_most(rejected, self.settings.max_rejected_fraction) {
            return Err(FaultCause::CalibrationFailed);
        }
        if preliminary {
            // Asked for as the arm sets off back over the marks: the poses
            // start from where that return ends.
            let q_from = joints_at(&self.model, from, q_now);
            let q_now = &q_from;
            let poses = calibration_poses(
                &estimate,
                &self.cell.log_header().camera,
                start_pose,
                q_now,
                &self.settings,
                &self.model,
            );
            // Nowhere over the disc can the arm show the marks to the camera:
            // the robot cannot be calibrated against this disc.
            if poses.is_empty() {
                return Err(FaultCause::DiscOutOfReach);
            }
            let poses = paced(&poses, from, waist_centre_azimuth, q_now, &self.model);
            self.adopt();
            Ok((estimate, poses))
        } else if part_path_enters_reach(&estimate, q_now, &self.model) {
            self.adopt();
            Ok((estimate, Vec::new()))
        } else {
            Err(FaultCause::PartOutOfReach)
        }
    }
}

/// The worker's rule for a calibrator fed before anyone asked for an
/// estimate: when its next frame or sighting would be thinned away, it
/// estimates and adopts (see [`PickWorker::absorb`]). True when it adopted.
/// Public so that a host replaying the worker's input applies the same rule
/// at the same frames.
pub fn adopt_before_thinning(calibrator: &mut PickCalibrator) -> bool {
    calibrator.about_to_thin() && calibrator.estimate_and_adopt()
}
