//! Pick scenario files (TOML): the experiments the simulated pick runs, after the
//! paper's Section 5 (experiment 1: disc height unknown; experiment 2: disc
//! height known, parts 4 and 7 cm high; the conveyor turns the part into the
//! robot's workspace and stops) plus a part picked off the turning disc.
//!
//! Every field is required unless marked optional or defaulted; unknown fields are
//! refused, so a misspelt key is an error naming it (with the line, as `toml`
//! reports it), never a silently ignored setting.

use std::path::Path;

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};

/// The embedded default scenario file (`host-sim scenarios/default.toml`).
pub const DEFAULT_SCENARIO_TOML: &str = include_str!("../../scenarios/default.toml");

/// A scenario file: a list of experiments (`[[experiment]]` tables).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PickScenarioFile {
    pub experiment: Vec<PickExperiment>,
}

/// One experiment: the cell, its noise, and what the controller is told.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PickExperiment {
    /// Unique name, used on the command line.
    pub name: String,
    pub description: String,
    /// The paper's experiment 2: the controller is told the disc surface's height
    /// in the base frame (experiment 1 finds it from the effector marks).
    pub disc_height_known: bool,
    /// Simulated seconds after which the run is abandoned as timed out.
    pub time_limit_s: f64,
    pub conveyor: ConveyorSettings,
    pub camera: CameraSettings,
    pub part: PartSettings,
    pub robot: RobotSettings,
    pub gripper: GripperSettings,
    /// Where the disc stands relative to the robot (the cell's layout, drawn
    /// per seed; unknown to the controller).
    #[serde(default)]
    pub cell: CellSettings,
    /// Faults the world injects during the run (none by default).
    #[serde(default, skip_serializing_if = "WorldFaults::is_none")]
    pub faults: WorldFaults,
}

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

/// Ranges of the cell's layout, drawn uniformly per seed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CellSettings {
    /// Disc centre's distance from the robot's base axis, m. At least the disc's
    /// radius (0.45 m) plus the robot's column (0.2 m): the disc never overlaps the robot.
    pub disc_distance_m: [f64; 2],
    /// Disc surface below the shoulder axis (0.672 m above the base), m: low
    /// enough for the arm's start pose to clear a 7 cm part.
    pub disc_below_shoulder_m: [f64; 2],
    /// Direction of the disc centre from the robot's front (+X), degrees: the
    /// robot faces the conveyor (joint 1 turns at most 160 degrees either way).
    pub disc_azimuth_deg: [f64; 2],
}

impl Default for CellSettings {
    fn default() -> Self {
        Self {
            disc_distance_m: [0.65, 0.78],
            disc_below_shoulder_m: [0.30, 0.45],
            disc_azimuth_deg: [-90.0, 90.0],
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

impl PickScenarioFile {
    /// The scenario file built into the binary (five experiments).
    pub fn embedded_default() -> Result<Self> {
        Self::parse(DEFAULT_SCENARIO_TOML).context("the embedded default scenario file")
    }

    /// One experiment of the embedded default file, by name.
    pub fn default_experiment(name: &str) -> Result<PickExperiment> {
        Self::embedded_default()?.experiment(name).cloned()
    }

    /// Reads and validates a scenario file.
    pub fn from_path(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read scenario file {}", path.display()))?;
        Self::parse(&text).with_context(|| format!("scenario file {}", path.display()))
    }

    /// Parses and validates TOML text.
    pub fn parse(text: &str) -> Result<Self> {
        let file: Self = toml::from_str(text).map_err(|e| anyhow::anyhow!("{e}"))?;
        file.validate()?;
        Ok(file)
    }

    /// The file as TOML, for users to copy and edit.
    pub fn to_toml_string(&self) -> Result<String> {
        toml::to_string_pretty(self).context("writing the scenario as TOML")
    }

    /// The experiment called `name`.
    pub fn experiment(&self, name: &str) -> Result<&PickExperiment> {
        self.experiment
            .iter()
            .find(|e| e.name == name)
            .with_context(|| {
                let names: Vec<&str> = self.experiment.iter().map(|e| e.name.as_str()).collect();
                format!(
                    "no experiment \"{name}\" in the scenario file (it has: {})",
                    names.join(", ")
                )
            })
    }

    pub fn validate(&self) -> Result<()> {
        if self.experiment.is_empty() {
            bail!("the scenario file has no [[experiment]]");
        }
        for (index, experiment) in self.experiment.iter().enumerate() {
            if self
                .experiment
                .iter()
                .take(index)
                .any(|e| e.name == experiment.name)
            {
                bail!("experiment name \"{}\" is used twice", experiment.name);
            }
            experiment
                .validate()
                .with_context(|| format!("experiment \"{}\"", experiment.name))?;
        }
        Ok(())
    }
}

impl PickExperiment {
    fn validate_faults(&self) -> Result<()> {
        let f = &self.faults;
        let time = |field: &str, t: f64| check(field, t, t >= 0.0, ">= 0");
        if let Some(bump) = f.camera_bump {
            time("faults.camera_bump.at_s", bump.at_s)?;
            check(
                "faults.camera_bump.rotation_deg",
                bump.rotation_deg,
                bump.rotation_deg.abs() <= 30.0,
                "within +-30",
            )?;
            check(
                "faults.camera_bump.shift_m",
                bump.shift_m,
                bump.shift_m.abs() <= 0.5,
                "within +-0.5",
            )?;
        }
        for (name, window) in [
            ("vision_outage", f.vision_outage),
            ("control_stall", f.control_stall),
        ] {
            if let Some(w) = window {
                time(&format!("faults.{name}.at_s"), w.at_s)?;
                check(
                    &format!("faults.{name}.duration_s"),
                    w.duration_s,
                    w.duration_s > 0.0,
                    "> 0",
                )?;
            }
        }
        if let Some(missed) = f.missed_counts {
            time("faults.missed_counts.at_s", missed.at_s)?;
        }
        if let Some(change) = f.conveyor_change {
            time("faults.conveyor_change.at_s", change.at_s)?;
            check(
                "faults.conveyor_change.speed_rad_s",
                change.speed_rad_s,
                change.speed_rad_s.abs() <= 5.0,
                "within +-5",
            )?;
            check(
                "faults.conveyor_change.acceleration_rad_s2",
                change.acceleration_rad_s2,
                change.acceleration_rad_s2 > 0.0,
                "> 0",
            )?;
            if self.conveyor.stop.is_some() {
                bail!("faults.conveyor_change needs an experiment without conveyor.stop");
            }
        }
        Ok(())
    }
}

/// `value` must satisfy `ok`; the error names the field and the rule.
fn check(field: &str, value: f64, ok: bool, rule: &str) -> Result<()> {
    if value.is_finite() && ok {
        Ok(())
    } else {
        bail!("{field} = {value} is out of range: it must be {rule}")
    }
}

fn probability(field: &str, p: f64) -> Result<()> {
    check(field, p, (0.0..1.0).contains(&p), "in [0, 1)")
}

impl PickExperiment {
    /// Range checks, each naming its field.
    pub fn validate(&self) -> Result<()> {
        if self.name.trim().is_empty() {
            bail!("name must not be empty");
        }
        check(
            "time_limit_s",
            self.time_limit_s,
            self.time_limit_s > 0.0,
            "> 0",
        )?;

        let l = &self.cell;
        for (field, [low, high], min, max) in [
            ("cell.disc_distance_m", l.disc_distance_m, 0.65, 1.2),
            (
                "cell.disc_below_shoulder_m",
                l.disc_below_shoulder_m,
                0.0,
                0.67,
            ),
            ("cell.disc_azimuth_deg", l.disc_azimuth_deg, -180.0, 180.0),
        ] {
            if !(low.is_finite() && high.is_finite() && min <= low && low <= high && high <= max) {
                bail!("{field} = [{low}, {high}] must be an ordered range within [{min}, {max}]");
            }
        }

        let c = &self.conveyor;
        check("conveyor.speed_rad_s", c.speed_rad_s, true, "finite")?;
        check(
            "conveyor.ripple_fraction",
            c.ripple_fraction,
            (0.0..1.0).contains(&c.ripple_fraction),
            "in [0, 1)",
        )?;
        check(
            "conveyor.ripple_hz",
            c.ripple_hz,
            c.ripple_hz >= 0.0,
            ">= 0",
        )?;
        if c.counts_per_rev == 0 {
            bail!("conveyor.counts_per_rev = 0 is out of range: it must be > 0");
        }
        if !matches!(c.counter_bits, 16 | 32) {
            bail!(
                "conveyor.counter_bits = {} is out of range: it must be 16 or 32",
                c.counter_bits
            );
        }
        if let Some(stop) = c.stop {
            check(
                "conveyor.stop.after_s",
                stop.after_s,
                stop.after_s >= 0.0,
                ">= 0",
            )?;
            check(
                "conveyor.stop.deceleration_rad_s2",
                stop.deceleration_rad_s2,
                stop.deceleration_rad_s2 > 0.0,
                "> 0",
            )?;
        }

        self.validate_faults()?;

        let cam = &self.camera;
        if cam.frame_period_ms == 0 {
            bail!("camera.frame_period_ms = 0 is out of range: it must be > 0");
        }
        check(
            "camera.pixel_sigma_px",
            cam.pixel_sigma_px,
            cam.pixel_sigma_px >= 0.0,
            ">= 0",
        )?;
        probability("camera.dropout_probability", cam.dropout_probability)?;
        probability("camera.outlier_probability", cam.outlier_probability)?;
        check(
            "camera.latency_ms",
            cam.latency_ms,
            cam.latency_ms >= 0.0,
            ">= 0",
        )?;
        check(
            "camera.latency_jitter_ms",
            cam.latency_jitter_ms,
            cam.latency_jitter_ms >= 0.0 && cam.latency_jitter_ms <= cam.latency_ms,
            "in [0, latency_ms]",
        )?;
        let [low, high] = cam.tilt_deg;
        let max = crate::workcell::generator::CAMERA_MAX_TILT_DEG;
        if !(low.is_finite() && high.is_finite() && 0.0 <= low && low <= high && high <= max) {
            bail!("camera.tilt_deg = [{low}, {high}] is out of range: it must be low <= high within [0, {max}]");
        }

        let part = &self.part;
        if !(2..=8).contains(&part.feature_count) {
            bail!(
                "part.feature_count = {} is out of range: it must be 2 to 8",
                part.feature_count
            );
        }
        check(
            "part.height_m",
            part.height_m,
            (0.0..=0.3).contains(&part.height_m),
            "in [0, 0.3]",
        )?;
        check("part.mass_kg", part.mass_kg, part.mass_kg >= 0.0, ">= 0")?;

        let r = &self.robot;
        check(
            "robot.link_mass_error",
            r.link_mass_error,
            (0.0..1.0).contains(&r.link_mass_error),
            "in [0, 1)",
        )?;
        check(
            "robot.payload_kg",
            r.payload_kg,
            r.payload_kg >= 0.0,
            ">= 0",
        )?;
        check(
            "robot.joint_counts_per_motor_rev",
            r.joint_counts_per_motor_rev,
            r.joint_counts_per_motor_rev > 0.0,
            "> 0",
        )?;
        check(
            "robot.control_rate_hz",
            r.control_rate_hz,
            r.control_rate_hz > 0.0,
            "> 0",
        )?;
        if r.plant_substeps == 0 {
            bail!("robot.plant_substeps = 0 is out of range: it must be >= 1");
        }

        let g = &self.gripper;
        check(
            "gripper.horizontal_m",
            g.horizontal_m,
            g.horizontal_m > 0.0,
            "> 0",
        )?;
        check(
            "gripper.vertical_m",
            g.vertical_m,
            g.vertical_m > 0.0,
            "> 0",
        )?;
        check(
            "gripper.yaw_deg",
            g.yaw_deg,
            g.yaw_deg > 0.0 && g.yaw_deg <= 90.0,
            "in (0, 90]",
        )?;
        check(
            "gripper.relative_speed_m_s",
            g.relative_speed_m_s,
            g.relative_speed_m_s > 0.0,
            "> 0",
        )?;
        Ok(())
    }

    /// The gripper's tolerance in the world's units.
    pub fn grasp_tolerance(&self) -> crate::world::gripper::GraspTolerance {
        crate::world::gripper::GraspTolerance {
            horizontal_m: self.gripper.horizontal_m,
            vertical_m: self.gripper.vertical_m,
            yaw_rad: self.gripper.yaw_deg.to_radians(),
            relative_speed_m_s: self.gripper.relative_speed_m_s,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_embedded_default_has_the_five_experiments() {
        let file = PickScenarioFile::embedded_default().unwrap();
        let names: Vec<&str> = file.experiment.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "experiment-1",
                "experiment-2-4cm",
                "experiment-2-7cm",
                "turning",
                "turning-height-known"
            ]
        );
        let exp1 = file.experiment("experiment-1").unwrap();
        assert!(!exp1.disc_height_known && exp1.conveyor.stop.is_some());
        assert_eq!(exp1.part.height_m, 0.04);
        assert!(
            file.experiment("experiment-2-7cm")
                .unwrap()
                .disc_height_known
        );
        let turning = file.experiment("turning").unwrap();
        assert!(turning.conveyor.stop.is_none());
        assert_eq!(turning.conveyor.ripple_fraction, 0.05);
        assert!(file.experiment("nope").is_err());
    }

    #[test]
    fn the_default_prints_and_reads_back_unchanged() {
        let file = PickScenarioFile::embedded_default().unwrap();
        let text = file.to_toml_string().unwrap();
        assert_eq!(PickScenarioFile::parse(&text).unwrap(), file);
    }

    #[test]
    fn a_misspelt_field_is_named_with_its_line() {
        let text = DEFAULT_SCENARIO_TOML.replacen("ripple_hz = ", "ripple_hertz = ", 1);
        let err = format!("{:#}", PickScenarioFile::parse(&text).unwrap_err());
        assert!(err.contains("ripple_hertz"), "{err}");
        assert!(err.contains("line"), "{err}");
    }

    #[test]
    fn a_bad_value_is_named() {
        let text = DEFAULT_SCENARIO_TOML.replacen("counter_bits = 16", "counter_bits = 12", 1);
        assert_ne!(text, DEFAULT_SCENARIO_TOML);
        let err = format!("{:#}", PickScenarioFile::parse(&text).unwrap_err());
        assert!(err.contains("conveyor.counter_bits = 12"), "{err}");
        assert!(err.contains("experiment-1"), "{err}");

        let text = DEFAULT_SCENARIO_TOML.replacen(
            "dropout_probability = 0.05",
            "dropout_probability = 1.5",
            1,
        );
        let err = format!("{:#}", PickScenarioFile::parse(&text).unwrap_err());
        assert!(err.contains("camera.dropout_probability"), "{err}");

        // A wrong type is toml's error, with the field and line.
        let text = DEFAULT_SCENARIO_TOML.replacen("feature_count = 3", "feature_count = \"3\"", 1);
        let err = format!("{:#}", PickScenarioFile::parse(&text).unwrap_err());
        assert!(
            err.contains("feature_count") && err.contains("line"),
            "{err}"
        );
    }

    #[test]
    fn reads_a_file_from_disk_and_names_it_in_errors() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("pick.toml");
        std::fs::write(&path, DEFAULT_SCENARIO_TOML).unwrap();
        assert_eq!(
            PickScenarioFile::from_path(&path).unwrap().experiment.len(),
            5
        );
        std::fs::write(&path, "experiment = []\n").unwrap();
        let err = format!("{:#}", PickScenarioFile::from_path(&path).unwrap_err());
        assert!(
            err.contains("pick.toml") && err.contains("no [[experiment]]"),
            "{err}"
        );
    }
}
