//! What one simulated pick leaves behind: the time series of truth and of the
//! controller's telemetry, the calibration, the events and the outcome. The
//! plots, the CSV files, the results table and the Monte Carlo read these.

use serde::{Deserialize, Serialize};
use shared::protocol::{CalibrationReport, FaultCause, PickPhase};

use super::invariants::SafetyWorst;
use crate::link::NoiseCounts;
use crate::world::CellLayout;

/// One sample of the run (every telemetry period of the controller).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TickRecord {
    pub t_s: f64,
    pub phase: PickPhase,
    /// The part's true grasp point (mean of its features) and yaw in the base frame.
    pub part_true_base_m: [f64; 3],
    pub part_true_yaw_rad: f64,
    /// The controller's fused estimate of the same (Eq 1), once it has one.
    pub part_est_base_m: Option<[f64; 3]>,
    pub part_est_yaw_rad: Option<f64>,
    /// The estimator's 1-sigma for the part position (0 before calibration).
    pub part_sigma_m: f64,
    /// The grasp point of the gripper (true, from the plant's joint angles) and
    /// where the controller sends it, with yaws.
    pub tool_true_base_m: [f64; 3],
    pub tool_true_yaw_rad: f64,
    pub tool_ref_base_m: [f64; 3],
    pub tool_ref_yaw_rad: f64,
    /// Conveyor angle (unwrapped, true) and speed, true and estimated.
    pub theta_true_rad: f64,
    pub theta_est_wrapped_rad: f64,
    pub omega_true_rad_s: f64,
    pub omega_est_rad_s: f64,
    /// Plant joint angles, speeds and the torque delivered (after saturation).
    pub q_rad: [f64; 6],
    pub qd_rad_s: [f64; 6],
    pub tau_nm: [f64; 6],
}

/// A phase change, as the controller reported it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PhaseEvent {
    pub t_s: f64,
    pub phase: PickPhase,
}

/// The calibration the controller reported, with the truth beside it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CalibrationRecord {
    pub t_s: f64,
    pub report: CalibrationReport,
    pub true_camera_height_m: f64,
    pub true_base_yaw_rad: f64,
    pub true_base_translation_m: [f64; 3],
}

/// How the pick ended.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum PickResult {
    /// Grasped, placed at the drop-off and back at the ready pose.
    Success,
    /// The gripper closed outside the tolerance.
    GraspMissed,
    /// The controller stopped on a fault (controlled stop).
    Fault(FaultCause),
    /// The simulation's time limit ran out in `PickPhase`.
    TimedOut(PickPhase),
}

/// The gripper's error against the part at the instant it closed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GraspRecord {
    pub t_s: f64,
    pub succeeded: bool,
    /// Grasp point of the gripper minus the part's, base frame, m.
    pub position_error_m: [f64; 3],
    pub yaw_error_rad: f64,
    pub relative_speed_m_s: f64,
    /// The controller's part estimate (fused, Eq 1) minus the truth at that instant.
    pub estimate_error_m: Option<[f64; 3]>,
    pub estimate_yaw_error_rad: Option<f64>,
}

impl GraspRecord {
    /// The record of the world's grasp `attempt`, without an estimate to score.
    pub fn of_attempt(attempt: &crate::world::GraspAttempt) -> Self {
        Self {
            t_s: attempt.t_s,
            succeeded: attempt.succeeded,
            position_error_m: attempt.position_error_base_m,
            yaw_error_rad: attempt.yaw_error_rad,
            relative_speed_m_s: attempt.relative_speed_m_s,
            estimate_error_m: None,
            estimate_yaw_error_rad: None,
        }
    }
}

/// What the serial link went through during the run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct LinkRecord {
    /// Sensor samples sent again because their command did not come back
    /// (lost on the way there or back).
    pub samples_resent: u64,
    /// Handshake and configuration messages sent again.
    pub session_resends: u64,
    /// Commands that came after their period was answered (a resend's echo).
    pub stale_commands: u64,
    /// Frames from the controller the host's decoder refused.
    pub replies_refused: u64,
    /// The controller's reports of frames it refused (`ErrorReport`s of a decode error).
    pub refusals_reported: u64,
    /// `PickTelemetry::frames_rejected` in the last telemetry received.
    pub controller_frames_rejected: u32,
    /// What a noise injector did, when the link has one.
    pub noise: Option<NoiseCounts>,
}

/// Everything one pick produced.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PickRun {
    pub experiment: String,
    pub seed: u64,
    pub layout: CellLayout,
    pub records: Vec<TickRecord>,
    pub phases: Vec<PhaseEvent>,
    pub calibrations: Vec<CalibrationRecord>,
    pub grasp: Option<GraspRecord>,
    pub result: PickResult,
    /// Where the part was put down, and how far from the drop-off.
    pub placed_error_m: Option<f64>,
    /// Simulated seconds from start until the controller first had a calibrated cell.
    pub calibrated_after_s: Option<f64>,
    pub duration_s: f64,
    /// Worst ratios over the run of |joint speed| and of |applied torque|
    /// (after the amplifier) to their limits.
    pub max_speed_ratio: f64,
    pub max_torque_ratio: f64,
    /// Lowest height of the grasp point above the disc surface while over the
    /// disc (within 5 cm of its rim) and not holding the part, m.
    pub min_tool_clearance_m: f64,
    /// The fastest joint's speed when the run ended, rad/s: a controlled stop
    /// must leave the arm at rest.
    #[serde(default)]
    pub end_joint_speed_rad_s: f64,
    #[serde(default)]
    pub link: LinkRecord,
    /// The worst value of every safety invariant over the run.
    #[serde(default)]
    pub safety: SafetyWorst,
    /// With `camera.source = "images"`: the in-loop front end's labels,
    /// scored against the truth.
    #[serde(default)]
    pub vision: Option<crate::world::image_vision::ImageVisionStats>,
}

impl PickRun {
    /// A run that produced nothing (the simulation itself failed).
    pub fn empty(experiment: &str, seed: u64) -> Self {
        Self {
            experiment: experiment.to_string(),
            seed,
            layout: CellLayout {
                disc_centre_base_m: [f64::NAN; 3],
                disc_radius_m: f64::NAN,
                camera_centre_base_m: [f64::NAN; 3],
                drop_off_base_m: [f64::NAN; 3],
            },
            records: Vec::new(),
            phases: Vec::new(),
            calibrations: Vec::new(),
            grasp: None,
            result: PickResult::TimedOut(PickPhase::Idle),
            placed_error_m: None,
            calibrated_after_s: None,
            duration_s: 0.0,
            max_speed_ratio: f64::NAN,
            max_torque_ratio: f64::NAN,
            min_tool_clearance_m: f64::NAN,
            end_joint_speed_rad_s: f64::NAN,
            link: LinkRecord::default(),
            safety: SafetyWorst::default(),
            vision: None,
        }
    }
}
