//! What the pick's three parts hand each other. The control loop
//! ([`super::PickController`], high priority) never waits for the others: it
//! latches the encoders at each camera trigger and asks for background jobs; the
//! frame pairer ([`super::pairing::FramePairer`], on the link) turns each camera frame
//! into an observation; the worker ([`super::worker::PickWorker`], low priority) feeds
//! the calibrator and runs the jobs. The firmware passes these through
//! critical-section channels between its tasks; the in-process simulator calls
//! the same three parts in the same order, so both run the same pick.
//!
//! Order is what makes a run deterministic: the worker sees observations and
//! job requests in the order they were made, and a job's result is applied by
//! the control loop at a fixed time after the request (its budget), never
//! "when it happens to arrive".

use heapless::Vec;

use super::estimate::CellEstimate;
use super::jobs::{ConveyorSnapshot, MAX_CALIBRATION_POSES};
use super::motion::Prediction;
use super::pace::CalibrationPose;
use crate::fusion::LatchedSample;
use crate::observation::ObservationFrame;
use crate::planning::{ArcPoint, InterceptPlan, PlanError, TaskState};
use crate::protocol::FaultCause;
use crate::robot::JointVector;

/// Background work the control loop asks for.
#[derive(Debug, Clone, Copy, PartialEq)]
#[allow(clippy::large_enum_variant)]
pub enum JobRequest {
    /// Self-calibrate from what the calibrator holds (Sections 2 and 3); a
    /// preliminary estimate also chooses the poses to show the marks at.
    Estimate {
        /// A preliminary estimate (from the search) rather than the final one.
        preliminary: bool,
        /// Controller time of the request (stamped on the estimate).
        time_us: u64,
        /// Where the arm started (the poses keep its wrist).
        start_pose: ArcPoint<f32>,
        /// Joint angles now (the poses' IK seed).
        q_now: JointVector<f32>,
        /// Where the flange rests now: the first calibration move starts here.
        from: ArcPoint<f32>,
        /// The route's waist-centre azimuth (the arcs' azimuths keep within
        /// half a turn of it).
        waist_centre_azimuth: f32,
    },
    /// Plan the intercept of the part (Eq 1 predicted forward).
    Plan {
        /// Where the arm is, at rest, when the plan starts.
        start: TaskState<f32>,
        /// The joint angles there (the inverse kinematics' seed).
        q_start: JointVector<f32>,
        /// The conveyor as the plan sees it.
        conveyor: ConveyorSnapshot,
        /// The calibration the plan uses (Eq 1's `base_from_disc` and `p_rotating`).
        estimate: CellEstimate,
    },
}

/// A job with the identity its result must come back with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JobTicket {
    /// Which configuration (session) asked; results of an older one are ignored.
    pub session: u32,
    /// Which request of that session; a cancelled job's late result is ignored.
    pub job_id: u32,
    /// What to compute.
    pub request: JobRequest,
}

/// What a job produced.
#[derive(Debug, Clone, PartialEq)]
#[allow(clippy::large_enum_variant)]
pub enum JobOutcome {
    /// An estimate and, if preliminary, the poses to show the marks at; or why it was
    /// refused.
    Estimate(Result<(CellEstimate, Vec<CalibrationPose, MAX_CALIBRATION_POSES>), FaultCause>),
    /// The intercept and the conveyor's prediction it assumed; or why none exists.
    Plan(Result<(InterceptPlan<f32>, Prediction), PlanError>),
}

/// A job's result, with its ticket's identity.
#[derive(Debug, Clone, PartialEq)]
pub struct JobResult {
    /// The session of the ticket answered.
    pub session: u32,
    /// The job of the ticket answered.
    pub job_id: u32,
    /// What came of it.
    pub outcome: JobOutcome,
}

/// From the control loop to the frame pairer: the encoders at a camera trigger.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriggerRecord {
    /// The encoders at the trigger.
    pub latched: LatchedSample,
    /// Controller time of the first sensor sample (observation time zero).
    pub start_time_us: u64,
    /// The part still lies on the disc at the trigger, so the frame may feed
    /// the calibrator (after the grasp it would show a part off the disc).
    pub feeds_calibrator: bool,
}

/// From the control loop, for the other two parts (in this order).
#[derive(Debug, Clone, Copy, PartialEq)]
#[allow(clippy::large_enum_variant)]
pub enum ControlEvent {
    /// For the frame pairer.
    Trigger(TriggerRecord),
    /// For the worker.
    Job(JobTicket),
}

/// The worker's input queue, in order.
#[derive(Debug, Clone, PartialEq)]
#[allow(clippy::large_enum_variant)]
pub enum WorkItem {
    /// A paired frame for the calibrator.
    Observation(ObservationFrame),
    /// A job to compute.
    Job(JobTicket),
}

/// What one camera frame saw of the disc, with the conveyor angle latched at
/// its trigger: enough for the control loop to check, after calibration, that
/// the camera and the encoder still agree with the calibrated cell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiscView {
    /// The conveyor angle at the trigger (unwrapped, from the first sample).
    pub theta: f32,
    /// Where the camera saw the disc's centre, if it did.
    pub centre_px: Option<[f32; 2]>,
    /// Where the camera saw the reference mark, if it did.
    pub reference_px: Option<[f32; 2]>,
    /// The frame, given to the calibrator, showed the part's features.
    pub part_seen: bool,
}

/// Where the camera saw the gripper's marks, from the encoders latched at
/// the trigger: the marks' direction round the base axis (the disc is that
/// way, roughly) and their height. A height at which the camera saw the
/// marks is one the arm has been at, in the camera's view, before anything
/// was calibrated: the pick descends from such heights in bounded steps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sighting {
    /// Unit vector (base frame, horizontal) towards the first mark.
    pub direction_xy: [f32; 2],
    /// The same towards the marks' midpoint (the flange's axis: the marks
    /// sit either side of it).
    pub flange_direction_xy: [f32; 2],
    /// The first mark's height in the base frame, m.
    pub mark_z_m: f32,
}

/// From the pairer and the worker back to the control loop.
#[derive(Debug, Clone, PartialEq)]
#[allow(clippy::large_enum_variant)]
pub enum VisionNews {
    /// A frame was paired with its trigger; `sighting` where the effector
    /// marks it saw were (from the encoders latched at the trigger), if it
    /// saw them; `view` what it saw of the disc, for the view monitor.
    Paired {
        /// Where the marks were, if the camera saw them.
        sighting: Option<Sighting>,
        /// What it saw of the disc.
        view: Option<DiscView>,
    },
    /// A frame matched no pending trigger (late, repeated or unknown).
    Unpaired,
    /// A paired frame the calibrator refused (bad detections, time going back).
    Refused,
    /// A job finished.
    Result(JobResult),
}
