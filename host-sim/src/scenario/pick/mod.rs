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

mod image;
mod settings;
mod validate;

pub use image::ImageSettings;

pub use settings::{
    CameraBump, CameraFaults, CameraSettings, CameraSource, CellSettings, ConveyorSettings,
    DriveSettings, FaultWindow, GripperSettings, LayoutKind, MissedCounts, PartSettings,
    RobotSettings, SpeedChange, StopSettings, WorldFaults,
};

/// The embedded default scenario file (`host-sim scenarios/default.toml`).
pub const DEFAULT_SCENARIO_TOML: &str = include_str!("../../../scenarios/default.toml");

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
    /// The tolerance of the user's measurement of the disc surface's height, m:
    /// with `disc_height_known` the controller is told the true height plus an
    /// error drawn uniformly within +-this (default 3 mm).
    #[serde(default = "default_disc_height_tolerance_m")]
    pub disc_height_tolerance_m: f64,
    /// Where the user wants picked parts: the part's grasp point on the bin,
    /// base frame, m. The world draws its layouts with the disc clear of it.
    #[serde(default = "default_drop_off_base_m")]
    pub drop_off_base_m: [f64; 3],
    /// Simulated seconds after which the run is abandoned as timed out.
    pub time_limit_s: f64,
    pub conveyor: ConveyorSettings,
    pub camera: CameraSettings,
    /// The rendered camera image (optional; defaults when absent). Only the
    /// renderer reads it: the controller's labelled points do not change.
    #[serde(default)]
    pub image: ImageSettings,
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

fn default_disc_height_tolerance_m() -> f64 {
    0.003
}

/// Beside the robot, 120 degrees round from its front, 0.55 m from the base
/// axis and 0.3 m above its foot.
fn default_drop_off_base_m() -> [f64; 3] {
    [-0.275, 0.476, 0.3]
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
        let file: Self = toml::from_str(text)?;
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
