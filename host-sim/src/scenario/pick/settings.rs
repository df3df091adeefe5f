//! The settings of one pick experiment: the conveyor, the camera, the part,
//! the robot, the gripper, the cell's layout and the faults the world injects.

use anyhow::{bail, Result};
use serde::{Deserialize, Serialize};

/// Faults of the cell the world injects (issue 7's faults during a pick), each
/// at a set time of the run. The camera's own settings carry its noise,
/// dropouts, outliers and latency.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WorldFaults {
    /// The camera is knocked to a new pose.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_bump: Option<CameraBump>,
    /// The link from the vision computer is down: no frame arrives in the window.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vision_outage: Option<FaultWindow>,
    /// The control loop (or the controller's link to the drives) stalls: no
    /// period runs in the window. The drives hold the last torque for
    /// `DRIVE_WATCHDOG_S`, then brake the arm and hold it against gravity.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub control_stall: Option<FaultWindow>,
    /// The conveyor encoder misses a burst of counts.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub missed_counts: Option<MissedCounts>,
    /// The conveyor changes speed (stops, speeds up, reverses).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub conveyor_change: Option<SpeedChange>,
    /// The conveyor counter starts this many counts below its wrap, so it
    /// wraps early in the run (otherwise its start is drawn at random).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub counter_counts_before_wrap: Option<u32>,
    /// One joint's homing channel is broken from power-on.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub homing: Option<crate::world::homing_sensors::HomingFault>,
}

impl WorldFaults {
    pub fn is_none(&self) -> bool {
        *self == Self::default()
    }
}

/// The camera's pose changes at `at_s`: turned by `rotation_deg` about its own
/// x axis and moved `shift_m` along it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraBump {
    pub at_s: f64,
    pub rotation_deg: f64,
    pub shift_m: f64,
}

/// A fault lasting from `at_s` for `duration_s`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FaultWindow {
    pub at_s: f64,
    pub duration_s: f64,
}

impl FaultWindow {
    pub fn contains(&self, t_s: f64) -> bool {
        t_s >= self.at_s && t_s < self.at_s + self.duration_s
    }
}

/// From `at_s` the encoder stops counting until it has missed `counts` edges;
/// with `instant`, its value jumps back by `counts` at once instead (a glitch).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MissedCounts {
    pub at_s: f64,
    pub counts: u32,
    #[serde(default)]
    pub instant: bool,
}

/// From `at_s` the disc's speed ramps at `acceleration_rad_s2` to `speed_rad_s`
/// and stays there (no ripple).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpeedChange {
    pub at_s: f64,
    pub speed_rad_s: f64,
    pub acceleration_rad_s2: f64,
}

/// Ranges of the cell's layout, drawn uniformly per seed; the world keeps the
/// layouts the arm can serve (`world::serve`), or with `layouts` only those it
/// cannot (to show how the controller stops on them), or any.
///
/// The defaults are the layouts the PUMA 560 can reach the parts in: the disc
/// in any direction round the robot; its centre from 0.65 m (the disc's 0.45 m
/// radius and the robot's 0.2 m column) to 1.0 m from the base axis (the
/// gripper-down reach is 0.80 m, 93 % of the 0.864 m stretch, and parts ride
/// 0.10 to 0.30 m from the disc's centre); its surface 0.30 m (the start
/// pose's gripper clears a 7 cm part by 0.1 m) to 0.60 m (near the robot's
/// foot: the reach at the grasp is still 0.69 m) below the shoulder.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CellSettings {
    /// Disc centre's distance from the robot's base axis, m. At least the disc's
    /// radius (0.45 m) plus the robot's column (0.2 m): the disc never overlaps the robot.
    pub disc_distance_m: [f64; 2],
    /// Disc surface below the shoulder axis (0.672 m above the base), m: low
    /// enough for the arm's start pose to clear a 7 cm part.
    pub disc_below_shoulder_m: [f64; 2],
    /// Direction of the disc centre from the robot's front (+X), degrees
    /// (joint 1 turns at most 160 degrees either way: behind the robot only
    /// part of the disc is in reach, and `layouts` decides).
    pub disc_azimuth_deg: [f64; 2],
    /// Which of the drawn layouts the world keeps (optional, default servable).
    #[serde(default)]
    pub layouts: LayoutKind,
}

/// Which drawn layouts the world keeps.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LayoutKind {
    /// Only those the arm can serve (`world::serve::check_serve`).
    #[default]
    Servable,
    /// Only those it cannot: the controller must stop on them, saying why.
    Unservable,
    /// Every layout drawn.
    Any,
}

impl Default for CellSettings {
    fn default() -> Self {
        Self {
            disc_distance_m: [0.65, 1.0],
            disc_below_shoulder_m: [0.30, 0.60],
            disc_azimuth_deg: [-180.0, 180.0],
            layouts: LayoutKind::Servable,
        }
    }
}

/// How the disc turns and how its encoder reads.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConveyorSettings {
    /// Mean speed, rad/s; negative turns clockwise.
    pub speed_rad_s: f64,
    /// Speed ripple amplitude as a fraction of the mean speed, in [0, 1).
    pub ripple_fraction: f64,
    /// Ripple frequency, Hz (>= 0).
    pub ripple_hz: f64,
    /// Encoder counts per disc revolution (default 4096).
    #[serde(default = "default_counts_per_rev")]
    pub counts_per_rev: u32,
    /// Width of the hardware counter: 16 or 32 bits.
    pub counter_bits: u8,
    /// Optional: stop the disc with the part in front of the robot.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stop: Option<StopSettings>,
}

fn default_counts_per_rev() -> u32 {
    4096
}

/// The operator stops the conveyor: the world picks the first instant at or
/// after `after_s` from which, decelerating at `deceleration_rad_s2`, the part
/// comes to rest at the disc azimuth nearest the robot's base axis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StopSettings {
    /// Earliest start of the stop, s (the controller calibrates before).
    pub after_s: f64,
    /// Constant deceleration of the ramp to rest, rad/s^2 (> 0).
    pub deceleration_rad_s2: f64,
}

/// The overhead camera and its vision computer.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSettings {
    /// Trigger period the controller is told to use, ms (200 = the paper's 5 Hz).
    pub frame_period_ms: u16,
    /// Standard deviation of the Gaussian noise on each pixel coordinate.
    pub pixel_sigma_px: f64,
    /// Probability that a detection group (centre, reference, the part, the
    /// effector pair) is missing from a frame, in [0, 1).
    pub dropout_probability: f64,
    /// Probability that one point is a gross outlier (uniform over the image), in [0, 1).
    pub outlier_probability: f64,
    /// Mean delay from exposure to the frame's arrival at the controller, ms.
    pub latency_ms: f64,
    /// The delay varies uniformly by up to this much either way, ms (< latency).
    pub latency_jitter_ms: f64,
    /// Range of the optical axis' tilt from the downward vertical, degrees [low, high].
    pub tilt_deg: [f64; 2],
    /// Injected failures (none by default).
    #[serde(default)]
    pub faults: CameraFaults,
    /// What the controller's frames are made from (the marks' projections
    /// with noise unless set).
    #[serde(default)]
    pub source: CameraSource,
}

/// Where the labelled points the controller receives come from.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum CameraSource {
    /// The marks' true projections with Gaussian noise, group dropouts and
    /// outliers (`pixel_sigma_px`, `dropout_probability`, `outlier_probability`).
    #[default]
    Points,
    /// Each frame rendered as an image (the `image` settings) and labelled
    /// by the project's detector and identifier; the point-noise settings
    /// are not used.
    Images,
}

/// Camera failures to inject, for testing the controller's fallbacks.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraFaults {
    /// From this time on, s, the camera delivers no frames at all.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub blackout_after_s: Option<f64>,
    /// The vision computer never finds the gripper's marks.
    #[serde(default)]
    pub effector_hidden: bool,
}

/// The part on the disc.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PartSettings {
    /// Feature points the vision computer reports on the part (2..=8).
    pub feature_count: u8,
    /// Height of its flat top above the disc, m (all features on it).
    pub height_m: f64,
    /// Mass added to the arm's payload once grasped, kg.
    pub mass_kg: f64,
}

/// The true arm against the controller's table model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotSettings {
    /// Each link's true mass is the table's scaled by a seeded uniform draw in
    /// [1 - e, 1 + e]; e in [0, 1).
    pub link_mass_error: f64,
    /// Tool payload the controller does not know, kg.
    pub payload_kg: f64,
    /// Joint encoder counts per motor revolution (1000: 250 lines in quadrature),
    /// through each joint's gear ratio.
    pub joint_counts_per_motor_rev: f64,
    /// Control periods per second.
    pub control_rate_hz: f64,
    /// RK4 steps of the plant per control period (>= 1).
    pub plant_substeps: u32,
    /// The true drives' spreads from the table and the amplifier (optional:
    /// the defaults of [`DriveSettings`]).
    #[serde(default)]
    pub drive: DriveSettings,
    /// The counters' power-on offsets, the potentiometers and the index
    /// pulses (optional: the defaults of
    /// [`HomingSensorSettings`](crate::world::homing_sensors::HomingSensorSettings)).
    #[serde(default)]
    pub homing: crate::world::homing_sensors::HomingSensorSettings,
}

/// How far the true drives may be from the controller's table (see
/// `world::drive` for the model and why these defaults) (each drawn
/// uniformly within +-the fraction, per joint and per cell), and the
/// amplifier's and motors' fixed behaviour. Zero everywhere is the table
/// itself with an ideal amplifier.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveSettings {
    /// Friction (viscous and Coulomb) scaled by a draw in [1 - e, 1 + e].
    pub friction_error: f64,
    /// Motor armature inertia scaled by a draw in [1 - e, 1 + e].
    pub armature_error: f64,
    /// `k_true / k_nominal` drawn in [1 - e, 1 + e].
    pub torque_constant_error: f64,
    /// The current loop's first-order time constant, ms (0: no lag).
    pub current_loop_time_constant_ms: f64,
    /// Commutation torque ripple, a fraction of the torque (peak).
    pub torque_ripple_fraction: f64,
    /// Ripple cycles per motor revolution.
    pub torque_ripple_cycles_per_motor_rev: f64,
}

impl Default for DriveSettings {
    fn default() -> Self {
        Self {
            friction_error: 0.3,
            armature_error: 0.3,
            torque_constant_error: 0.05,
            current_loop_time_constant_ms: 0.5,
            torque_ripple_fraction: 0.03,
            torque_ripple_cycles_per_motor_rev: 16.0,
        }
    }
}

impl DriveSettings {
    /// The table's drives and an ideal amplifier.
    pub fn exact() -> Self {
        Self {
            friction_error: 0.0,
            armature_error: 0.0,
            torque_constant_error: 0.0,
            current_loop_time_constant_ms: 0.0,
            torque_ripple_fraction: 0.0,
            torque_ripple_cycles_per_motor_rev: 0.0,
        }
    }

    /// Refuses values outside their ranges, naming the field.
    pub fn validate(&self) -> Result<()> {
        let fraction = |name: &str, value: f64, high: f64| -> Result<()> {
            if !(value.is_finite() && (0.0..high).contains(&value)) {
                bail!("robot.drive.{name} = {value} is out of range: it must be in [0, {high})");
            }
            Ok(())
        };
        fraction("friction_error", self.friction_error, 1.0)?;
        fraction("armature_error", self.armature_error, 1.0)?;
        fraction("torque_constant_error", self.torque_constant_error, 0.5)?;
        fraction("torque_ripple_fraction", self.torque_ripple_fraction, 0.5)?;
        fraction(
            "current_loop_time_constant_ms",
            self.current_loop_time_constant_ms,
            100.0,
        )?;
        fraction(
            "torque_ripple_cycles_per_motor_rev",
            self.torque_ripple_cycles_per_motor_rev,
            1000.0,
        )?;
        Ok(())
    }
}

/// When closing the gripper holds the part (see `world::gripper`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GripperSettings {
    /// Largest horizontal distance of the grasp point from the part's, m.
    pub horizontal_m: f64,
    /// Largest vertical distance, m.
    pub vertical_m: f64,
    /// Largest yaw error (modulo 180 degrees: two fingers), degrees.
    pub yaw_deg: f64,
    /// Largest speed of the gripper relative to the part, m/s.
    pub relative_speed_m_s: f64,
}
