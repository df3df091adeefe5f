//! The simulated world of the full pick: a drawn workcell (camera, disc, part,
//! robot base: truth the controller never reads), the PUMA 560 plant, the disc
//! conveyor, the camera with its vision computer, and the gripper.
//!
//! The controller meets it only through the protocol: it is told the
//! [`CellConfig`] (nothing calibrated), reads [`SensorSample`]s and
//! [`CameraFeatureFrame`]s, and acts by
//! [`ActuatorCommand`](shared::protocol::ActuatorCommand)s, one per control
//! period. Everything else here (the truth, the layout, the grasp) is for the
//! runner's records and the tests.
//!
//! The part's grasp point is the mean of its features (the top centre of a
//! flat-topped part) and its yaw the direction from feature 0 to feature 1 (the
//! contract's part pose); on the disc it moves by the paper's Eq 1,
//! `p_base = Rz(yaw) Rz(theta) p_rotating + T`. Once grasped it is fixed to the
//! flange; released, it stays where the gripper opened (no falling model).
//!
//! Building the world of an experiment is in `build.rs`; one control period
//! and the part's motion are in `motion.rs`.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use shared::protocol::{CameraFeatureFrame, CellConfig, SensorSample, JOINTS};
use shared::robot::JointVector;

use super::conveyor::Conveyor;
use super::dimensions::DISC_RADIUS_M;
use super::gripper::GraspTolerance;
use super::homing_sensors::HomingSensors;
use super::image_vision::{ImageVision, ImageVisionStats};
use super::plant::{JointEncoders, RobotPlant};
use super::vision::CameraSim;
use super::workcell::Workcell;
use crate::scenario::pick::PickExperiment;

mod build;
#[cfg(test)]
mod config_tests;
mod motion;
#[cfg(test)]
mod tests;

/// Least horizontal gap between the disc's rim and the user's drop-off, m:
/// the world draws its layouts with the disc this far from the bin.
pub const DROP_OFF_CLEARANCE_M: f64 = 0.1;
/// Draws of the layout at most, for one with the disc clear of the drop-off.
const MAX_LAYOUT_DRAWS: usize = 400;
/// Distance from the base axis at which a stopped disc leaves the part, m.
pub const STOP_REACH_M: f64 = 0.6;
/// The unknown tool payload sits halfway down the gripper, on the flange's axis.
const TOOL_PAYLOAD_COM_FLANGE_M: [f64; 3] = [0.0, 0.0, shared::app::tool::TOOL_LENGTH_M / 2.0];
/// Telemetry period the world asks for, seconds (50 Hz).
const TELEMETRY_PERIOD_S: f64 = 0.02;

/// A drive given no new command holds the last one this long, then brakes.
pub const DRIVE_WATCHDOG_S: f64 = 0.005;
/// The brake's viscous coefficient, N m s/rad (it also holds the arm against
/// gravity, as a holding brake does).
const BRAKE_DAMPING_NM_S: f64 = 20.0;
/// Step of the search for the stop instant, seconds; refined by bisection.
const STOP_SEARCH_STEP_S: f64 = 0.01;

/// The true state of the world at one instant, base frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldTruth {
    pub time_s: f64,
    /// The part's grasp point (mean of its features), yaw and velocity.
    pub part_base_m: [f64; 3],
    pub part_yaw_rad: f64,
    pub part_velocity_base_m_s: [f64; 3],
    pub part_held: bool,
    /// The gripper's grasp point and yaw from the plant's true joint angles.
    pub tool_base_m: [f64; 3],
    pub tool_yaw_rad: f64,
    /// Conveyor angle (unwrapped, 0 at t = 0) and speed.
    pub theta_rad: f64,
    pub omega_rad_s: f64,
    pub q_rad: [f64; JOINTS],
    pub qd_rad_s: [f64; JOINTS],
    /// The torque the drives last delivered (after saturation).
    pub tau_nm: [f64; JOINTS],
}

/// What happened when the gripper closed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GraspAttempt {
    pub t_s: f64,
    pub succeeded: bool,
    /// Gripper grasp point minus the part's, base frame.
    pub position_error_base_m: [f64; 3],
    pub horizontal_error_m: f64,
    pub vertical_error_m: f64,
    /// Yaw error modulo pi (two fingers).
    pub yaw_error_rad: f64,
    pub relative_speed_m_s: f64,
}

/// Where the part is.
#[derive(Debug, Clone, PartialEq)]
enum PartState {
    /// On the disc, its features fixed in the rotating frame.
    OnDisc,
    /// In the gripper, its features fixed in the flange frame.
    Held { features_flange: Vec<Vector3<f64>> },
    /// Put down where the gripper opened.
    Placed { features_base: Vec<Vector3<f64>> },
}

/// The simulated workcell.
#[derive(Debug)]
pub struct World {
    experiment: PickExperiment,
    workcell: Workcell,
    plant: RobotPlant,
    encoders: JointEncoders,
    /// The counters' power-on offsets, the potentiometers, the index pulses.
    homing_sensors: HomingSensors,
    conveyor: Conveyor,
    camera: CameraSim,
    /// The vision computer on rendered images (`camera.source = "images"`);
    /// without it the camera delivers the marks' projections with noise.
    image_vision: Option<ImageVision>,
    tolerance: GraspTolerance,
    control_period_s: f64,
    ticks: u64,
    sensor_seq: u32,
    part: PartState,
    gripper_closed: bool,
    grasp: Option<GraspAttempt>,
    placed_base: Option<[f64; 3]>,
    last_tau: JointVector<f64>,
    drop_off_base: Vector3<f64>,
    /// The disc surface's height as the user measured it (experiment 2 only):
    /// the truth plus an error within the scenario's tolerance.
    disc_height_measured_m: Option<f64>,
    /// The camera was knocked to its new pose (the bump fault has happened).
    camera_bumped: bool,
    /// Consecutive periods without a command (a stall), for the drives' watchdog.
    unattended_ticks: u64,
}

fn array(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

fn mean(points: &[Vector3<f64>]) -> Vector3<f64> {
    let count = points.len().max(1) as f64;
    points.iter().fold(Vector3::zeros(), |sum, p| sum + p) / count
}

/// Yaw of the direction feature 0 -> feature 1 in the XY-plane (the contract's part yaw).
fn part_yaw(features: &[Vector3<f64>]) -> f64 {
    match (features.first(), features.get(1)) {
        (Some(a), Some(b)) => (b.y - a.y).atan2(b.x - a.x),
        _ => 0.0,
    }
}

/// The fixed geometry of the cell for the top view, all in the base frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CellLayout {
    pub disc_centre_base_m: [f64; 3],
    pub disc_radius_m: f64,
    pub camera_centre_base_m: [f64; 3],
    pub drop_off_base_m: [f64; 3],
}

impl World {
    /// What an integrator tells the controller: intrinsics (A5), L, the encoders'
    /// scales, the user's drop-off and (experiment 2 only) the disc surface's
    /// height as measured, within its tolerance. Nothing calibrated and nothing
    /// read off the world's truth: no camera pose, no base pose, no part, no
    /// pixel noise (the controller measures it from its residuals).
    pub fn cell_config(&self) -> CellConfig {
        let intrinsics = self.workcell.camera.intrinsics;
        let rate = self.experiment.robot.control_rate_hz;
        // The gripper's capture, from its datasheet: the user knows it.
        let gripper = &self.experiment.gripper;
        CellConfig {
            image_width_px: u16::try_from(intrinsics.width).unwrap_or(u16::MAX),
            image_height_px: u16::try_from(intrinsics.height).unwrap_or(u16::MAX),
            f_px: intrinsics.f_px as f32,
            cx_px: intrinsics.cx as f32,
            cy_px: intrinsics.cy as f32,
            reference_radius_m: self.workcell.reference_radius_m as f32,
            part_feature_count: self.experiment.part.feature_count,
            conveyor_counts_per_rev: self.conveyor.counts_per_rev(),
            conveyor_counter_bits: self.conveyor.width().bits(),
            joint_counts_per_rad: self.encoders.counts_per_rad.map(|c| c as f32),
            disc_height_in_base_m: self.disc_height_measured_m.map(|z| z as f32),
            drop_off_base_m: array(&self.drop_off_base).map(|x| x as f32),
            camera_period_ms: self.experiment.camera.frame_period_ms,
            telemetry_period_ticks: (rate * TELEMETRY_PERIOD_S).round().clamp(1.0, 65_535.0) as u16,
            home_at_power_on: self.experiment.robot.homing.counters_start_anywhere,
            grasp_capture_m: [gripper.horizontal_m as f32, gripper.vertical_m as f32],
            grasp_capture_yaw_rad: gripper.yaw_deg.to_radians() as f32,
            // The disc's drawing gives its radius, as it gives the reference's.
            disc_radius_m: Some(super::dimensions::DISC_RADIUS_M as f32),
        }
    }

    pub fn time_s(&self) -> f64 {
        self.ticks as f64 * self.control_period_s
    }

    pub fn control_period_s(&self) -> f64 {
        self.control_period_s
    }

    pub fn experiment(&self) -> &PickExperiment {
        &self.experiment
    }

    pub fn conveyor(&self) -> &Conveyor {
        &self.conveyor
    }

    pub fn plant(&self) -> &RobotPlant {
        &self.plant
    }

    pub fn camera(&self) -> &CameraSim {
        &self.camera
    }

    /// The in-loop vision computer's scored labels (`None` on ideal points).
    pub fn image_vision_stats(&self) -> Option<ImageVisionStats> {
        self.image_vision.as_ref().map(ImageVision::stats)
    }

    /// The homing sensors (their drawn counter offsets: truth, for scoring).
    pub fn homing_sensors(&self) -> &HomingSensors {
        &self.homing_sensors
    }

    /// Encoder readings now: joint counts from the plant's true angles, the
    /// conveyor's raw (wrapping) counter.
    pub fn sensor_sample(&mut self) -> SensorSample {
        let t = self.time_s();
        let q = self.plant.state().q;
        let sample = SensorSample {
            seq: self.sensor_seq,
            time_us: (t * 1e6).round() as u64,
            joint_counts: self.homing_sensors.counters(&q),
            conveyor_counts: self.conveyor.encoder_raw(t),
            part_in_gripper: matches!(self.part, PartState::Held { .. }),
            joint_pots_rad: self.homing_sensors.potentiometers(&q),
            joint_index_counts: self.homing_sensors.latched(),
        };
        self.sensor_seq = self.sensor_seq.wrapping_add(1);
        sample
    }

    /// Camera frames that have arrived by now (none while the vision link is down:
    /// those are lost).
    pub fn due_camera_frames(&mut self) -> Vec<CameraFeatureFrame> {
        let now = self.time_s();
        let frames = self.camera.due_frames(now);
        match self.experiment.faults.vision_outage {
            Some(outage) if outage.contains(now) => Vec::new(),
            _ => frames,
        }
    }

    /// The control loop is stalled now (the control-stall fault): no sensor
    /// sample is read and no command comes; see [`World::apply_unattended`].
    pub fn control_stalled(&self) -> bool {
        self.experiment
            .faults
            .control_stall
            .is_some_and(|stall| stall.contains(self.time_s()))
    }

    pub fn grasp(&self) -> Option<GraspAttempt> {
        self.grasp
    }

    pub fn placed_position_base(&self) -> Option<[f64; 3]> {
        self.placed_base
    }

    pub fn drop_off_base(&self) -> [f64; 3] {
        array(&self.drop_off_base)
    }

    /// The fixed geometry for the top view, base frame.
    pub fn layout(&self) -> CellLayout {
        CellLayout {
            disc_centre_base_m: array(&self.workcell.base_from_disc_translation_m),
            disc_radius_m: DISC_RADIUS_M,
            camera_centre_base_m: array(
                &self
                    .workcell
                    .base_from_disc(&self.workcell.camera.optical_centre_disc),
            ),
            drop_off_base_m: array(&self.drop_off_base),
        }
    }

    /// The drawn workcell: the truth the controller's calibration is compared with.
    pub fn workcell(&self) -> &Workcell {
        &self.workcell
    }

    /// Moves the clock to `ticks` periods without integrating the plant (tests
    /// that need the disc somewhere else).
    #[cfg(test)]
    fn set_ticks(&mut self, ticks: u64) {
        self.ticks = ticks;
    }

    /// Puts the arm at `q` moving at `qd` (tests that need the gripper somewhere).
    #[cfg(test)]
    fn set_arm(&mut self, q: JointVector<f64>, qd: JointVector<f64>) {
        self.plant.set_state(super::plant::JointState { q, qd });
    }
}
