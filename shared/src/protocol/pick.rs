//! Messages of the pick session (protocol v3; see [`super::Message`]).
//!
//! The host (simulator or vision computer) first sends [`CellConfig`]: what an
//! integrator knows without calibrating anything (the camera's intrinsics, the
//! reference mark's radius, the encoders' scales, where to drop parts). From then
//! on the controller answers every sensor sample with an actuator command, and
//! reports [`PickTelemetry`] at a bounded rate and a [`CalibrationReport`] after
//! every self-calibration.

use serde::{Deserialize, Serialize};

use super::JOINTS;

/// What the controller is told about the cell. Nothing here is a calibration:
/// the camera's pose, the disc's pose and the part are found by the controller.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CellConfig {
    /// Image size and pinhole intrinsics (known, paper assumption A5).
    pub image_width_px: u16,
    /// Image height, pixels.
    pub image_height_px: u16,
    /// Focal length, pixels.
    pub f_px: f32,
    /// Principal point, column, pixels.
    pub cx_px: f32,
    /// Principal point, row, pixels.
    pub cy_px: f32,
    /// The paper's L: distance from the disc centre to the reference mark.
    pub reference_radius_m: f32,
    /// Feature points the vision computer reports on the part (2..=8).
    pub part_feature_count: u8,
    /// Conveyor encoder counts per revolution of the disc.
    pub conveyor_counts_per_rev: u32,
    /// Width of the conveyor's hardware counter: 16 or 32 bits.
    pub conveyor_counter_bits: u8,
    /// Joint encoder counts per radian of each joint (0 counts at q = 0).
    pub joint_counts_per_rad: [f32; JOINTS],
    /// The paper's experiment 2: the disc surface's height in the base frame, when known.
    pub disc_height_in_base_m: Option<f32>,
    /// Where to put picked parts: the gripper's grasp point in the base frame.
    pub drop_off_base_m: [f32; 3],
    /// Camera trigger period, milliseconds (200 = the paper's slow 5 Hz vision).
    pub camera_period_ms: u16,
    /// Control periods between two telemetry messages (0: no telemetry).
    pub telemetry_period_ticks: u16,
    /// The joint counters are incremental and started at zero wherever the
    /// arm stood at power-on: the controller homes the joints
    /// (potentiometers, then index pulses; `crate::app::power_on_homing`)
    /// before the pick moves. False: zero counts is already q = 0 (a board
    /// whose counters were homed before). Added in v5.
    pub home_at_power_on: bool,
    /// How far off the part may be when the gripper closes and still be
    /// grasped (the gripper's datasheet): horizontally and vertically, m.
    /// The pick shows its marks again until its estimate is sure within
    /// these. Added in v7.
    pub grasp_capture_m: [f32; 2],
    /// The same for the part's yaw, rad. Added in v7.
    pub grasp_capture_yaw_rad: f32,
    /// The disc's radius to its rim, m, where the vision computer measures
    /// the rim (`CameraFeatureFrame::rim`). Added in v9.
    pub disc_radius_m: Option<f32>,
}

/// Where the pick stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PickPhase {
    /// Not configured yet, or waiting for the first sensor sample.
    Idle,
    /// Watching the disc turn; the arm sweeps its marks through the camera's view.
    SearchEffector,
    /// Showing the marks at chosen poses above the disc (robot-to-disc calibration).
    CalibrateBase,
    /// Waiting for the calibration to be computed.
    Estimating,
    /// Waiting for a steady conveyor and a reachable part; planning the intercept.
    Locate,
    /// Following the planned path that meets the moving part.
    Intercept,
    /// Above the grasp point, matching the part's velocity.
    Track,
    /// Lowering the gripper onto the part while following it.
    Descend,
    /// Closing the gripper on the part.
    Grasp,
    /// Lifting the part off the disc.
    Lift,
    /// Carrying the part to the drop-off and lowering it there.
    Place,
    /// Opening the gripper over the drop-off.
    Release,
    /// Going back to the start pose.
    Return,
    /// The part is placed and the arm is back at its ready pose.
    Done,
    /// Decelerating to a stop after a fault.
    Stopping,
    /// Holding still after a fault; see the fault cause.
    Faulted,
}

/// Why the controller stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FaultCause {
    /// A configuration value is out of range (the field is named in `detail`).
    BadConfig,
    /// Self-calibration failed or is not trustworthy.
    CalibrationFailed,
    /// The end effector's marks were never seen by the camera during the search.
    EffectorNotSeen,
    /// No camera frame arrived within the staleness limit.
    VisionStale,
    /// No sensor sample (link loss) within the watchdog limit.
    LinkLost,
    /// The part is or will be out of the arm's reach, or no intercept exists.
    PartUnreachable,
    /// The arm lagged its reference by more than the tracking limit.
    TrackingError,
    /// The conveyor encoder jumped or its time went backwards.
    ConveyorEncoder,
    /// A joint encoder reading was implausible (jump beyond the speed limit).
    JointEncoder,
    /// The control law could not produce a finite torque.
    ControlFailure,
    /// A phase took longer than its timeout.
    Timeout,
    /// No control period ran for longer than the stall limit (the control loop
    /// or its plant link stalled): the drives' own watchdog held the arm, and
    /// the controller will not carry on a motion planned before the gap.
    ControlStall,
    /// The camera no longer sees the disc where its calibration says it
    /// should (the camera was moved): the cell must be calibrated again.
    CameraMoved,
    /// The disc's angle seen by the camera and the conveyor encoder's
    /// disagree by more than a grasp can tolerate (counts were missed).
    ConveyorSlip,
    /// A joint ran faster than its speed limit: the joint brake took over.
    JointOverspeed,
    /// The gripper closed (or carried) without a part: its part-present
    /// switch stayed open.
    GraspMissed,
    /// The motion reference leapt (a motion handed over to one that starts
    /// elsewhere): refused, and the arm stopped from the last good reference.
    ReferenceJump,
    /// Before the calibration was accepted, a motion would have taken the
    /// gripper further below the heights at which the camera saw its marks
    /// than the pick allows (`PickSettings::max_descent_step_m`): the
    /// estimate it was planned from is not trusted that far.
    BelowSafeHeight,
    /// No pose over the disc is both within the arm's reach (joint ranges
    /// included) and in the camera's view with the gripper's marks: the
    /// robot cannot be calibrated against this disc (the disc is out of
    /// reach, or the camera does not see the gripper over it).
    DiscOutOfReach,
    /// The part's circle on the disc (its path as the disc turns) never
    /// enters the arm's workspace (reach, joint ranges, clear of the base
    /// axis): the part can never be grasped in this layout.
    PartOutOfReach,
    /// Homing: a joint's potentiometer read no number, moved with the joint
    /// at rest, or disagreed with the encoder by more than its tolerance
    /// (at the index, or once homed). Added in v5.
    HomingPotentiometer,
    /// Homing: a joint travelled its search span without an index pulse (a
    /// dead index channel or a stalled joint). Added in v5.
    HomingIndexNotSeen,
    /// The search ended without the gripper's marks seen often enough, and
    /// no camera frame ever showed the disc's reference mark: the vision
    /// stage never identified the disc (the cell cannot be calibrated
    /// against it), rather than the camera not seeing the gripper
    /// (`EffectorNotSeen`). Added in v8.
    DiscNotSeen,
    /// No camera frame had shown the part whole (every feature labelled)
    /// when the search's wait for it ran out: the vision stage never
    /// identified the part (or none rides on the disc), rather than the
    /// calibration failing on the data it had (`CalibrationFailed`).
    /// Added in v10.
    PartNotSeen,
}

/// A snapshot of the controller's estimates, sent every `telemetry_period_ticks`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PickTelemetry {
    /// The sample's time, microseconds.
    pub time_us: u64,
    /// Where the pick stands.
    pub phase: PickPhase,
    /// Why it stopped, if it did.
    pub fault: Option<FaultCause>,
    /// Conveyor angle (wrapped to (-pi, pi]), speed, and their 1-sigma.
    pub theta_rad: f32,
    /// Conveyor speed, rad/s.
    pub omega_rad_s: f32,
    /// 1-sigma of the conveyor angle, rad.
    pub sigma_theta_rad: f32,
    /// 1-sigma of the conveyor speed, rad/s.
    pub sigma_omega_rad_s: f32,
    /// The part's fused pose in the base frame (Eq 1), once calibrated.
    pub part_base_m: Option<[f32; 3]>,
    /// The part's yaw in the base frame, rad (0 before calibration).
    pub part_yaw_base_rad: f32,
    /// The part's velocity in the base frame, m/s (0 before calibration).
    pub part_velocity_base_m_s: [f32; 3],
    /// 1-sigma of the part's position in the base frame from the estimator
    /// (the root of `sigma_grasp_horizontal_m^2 + sigma_grasp_vertical_m^2`;
    /// v7, before it the rotating frame's, which left out the base).
    pub part_sigma_m: f32,
    /// The grasp point (tool centre) measured through the joint encoders, and where it is sent.
    pub tool_base_m: [f32; 3],
    /// Where the grasp point is sent (the reference), base frame.
    pub tool_reference_base_m: [f32; 3],
    /// The flange's yaw measured through the joint encoders, rad.
    pub tool_yaw_rad: f32,
    /// The reference yaw, wrapped to (-pi, pi].
    pub tool_reference_yaw_rad: f32,
    /// Camera frames paired with their trigger, and those refused (unknown or stale trigger).
    pub frames_paired: u32,
    /// Camera frames that matched no trigger (see `frames_paired`).
    pub frames_unpaired: u32,
    /// Control periods whose torque was clipped to the drive limits.
    pub saturated_ticks: u32,
    /// Frames from the host that the controller's decoder refused (corrupt,
    /// bad CRC, oversized, not a message), since the controller started.
    pub frames_rejected: u32,
}

/// The result of a self-calibration, summarised for telemetry (f32).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CalibrationReport {
    /// When the estimate was made, microseconds.
    pub time_us: u64,
    /// The camera's height above the disc plane, m.
    pub camera_height_m: f32,
    /// Angle of the camera's optical axis from the disc's downward normal.
    pub camera_tilt_rad: f32,
    /// `base_from_disc`'s yaw (Eqs 13 and 14), rad.
    pub base_yaw_rad: f32,
    /// `base_from_disc`'s translation (Eq 15), m.
    pub base_translation_m: [f32; 3],
    /// The part in the rotating frame (mean of its features) and its yaw.
    pub part_rotating_m: [f32; 3],
    /// The part's yaw in the rotating frame, rad.
    pub part_yaw_rotating_rad: f32,
    /// 1-sigma of the part position, the base translation and the base yaw.
    pub sigma_part_m: f32,
    /// 1-sigma of the base translation, m (see `sigma_part_m`).
    pub sigma_base_m: f32,
    /// 1-sigma of the base yaw, rad (see `sigma_part_m`).
    pub sigma_base_yaw_rad: f32,
    /// Frames the estimate used.
    pub frames_used: u16,
    /// Sightings of the gripper's marks the estimate used.
    pub effector_frames_used: u16,
    /// Root mean square reprojection error of the fit, pixels.
    pub rms_reprojection_px: f32,
    /// Image points the fit gated as outliers (stored and folded). v6.
    pub points_gated: u32,
    /// Frames folded into the calibrator's normal equations (those its store
    /// had no room for since it adopted an estimate). v6.
    pub frames_folded: u32,
    /// Times folded frames disagreed with a later optimum (a wrong estimate
    /// adopted, a camera that creeps) and were discarded. v6.
    pub folds_discarded: u16,
    /// 1-sigma of the part in the base frame (Eq 1), horizontally at the
    /// worst disc angle, m: the part and the base both lean on the camera, so
    /// this is what the grasp has to cover, not `sigma_part_m` and
    /// `sigma_base_m` apart. v7.
    pub sigma_grasp_horizontal_m: f32,
    /// 1-sigma of the part's height in the base frame, m. v7.
    pub sigma_grasp_vertical_m: f32,
    /// 1-sigma of the part's yaw in the base frame, rad. v7.
    pub sigma_grasp_yaw_rad: f32,
}
