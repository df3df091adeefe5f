//! Named recording scenarios: how many frames over how much of a revolution,
//! how noisy the detections are, how often the end effector shows, how the
//! part's feature heights are drawn and how far the camera is tilted.

use std::fmt;

use serde::{Deserialize, Serialize};

/// How the heights of the part's feature points above the disc are drawn.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum FeatureHeights {
    /// All features on the part's flat top at one unknown height in `[min_m, max_m]`
    /// (the paper's experiments: parts 4 cm and 7 cm high).
    FlatTop { min_m: f64, max_m: f64 },
    /// Features at clearly different heights: feature 0 near `min_m`, feature 1
    /// near `max_m` (at least `min_spread_m` apart), the others anywhere between.
    Spread {
        min_m: f64,
        max_m: f64,
        min_spread_m: f64,
    },
}

/// Everything that defines how a synthetic log is recorded (the workcell itself is random).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scenario {
    pub name: String,
    /// Number of camera frames in the log.
    pub frames: usize,
    /// Conveyor travel over the log in revolutions (negative: clockwise).
    pub revolutions: f64,
    pub frame_rate_hz: f64,
    /// Standard deviation of the Gaussian noise on each pixel coordinate.
    pub pixel_sigma_px: f64,
    /// Probability that a detection (centre, reference, the part as a whole, each
    /// effector pair) is missing from a frame.
    pub dropout_probability: f64,
    /// Probability that a detected point is a gross outlier (uniform over the image).
    pub outlier_probability: f64,
    /// Number of frames that show the end effector, drawn uniformly from this range.
    pub effector_frames_min: usize,
    pub effector_frames_max: usize,
    pub part_feature_count: usize,
    pub feature_heights: FeatureHeights,
    /// Tilt of the camera's optical axis from the downward vertical, degrees, drawn
    /// uniformly from `(low, high)`. The paper's setting (A4, Fig 1) is a camera
    /// beside the disc, looking at it at a slant: [`PAPER_CAMERA_TILT_DEG`]. Only
    /// the `near-axis` scenario puts the camera almost on the disc's axis, where the
    /// feature heights are poorly observable (see `world::generator`).
    #[serde(default = "paper_camera_tilt_deg")]
    pub camera_tilt_deg: (f64, f64),
    /// Where the disc may stand relative to the robot.
    #[serde(default)]
    pub disc_placement: DiscPlacement,
}

/// Ranges the disc's placement relative to the robot is drawn from (uniformly).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DiscPlacement {
    /// Distance of the disc centre from the robot's base Z axis, m.
    pub distance_from_base_axis_m: (f64, f64),
    /// Depth of the disc surface below the PUMA's shoulder axis (z = 0.67183 m), m.
    pub below_shoulder_m: (f64, f64),
    /// Direction of the disc centre about the base Z axis from +X, degrees.
    pub azimuth_deg: (f64, f64),
}

impl Default for DiscPlacement {
    /// The self-calibration scenarios' ranges: any direction, 0.6 to 1.0 m away,
    /// the surface 0 to 0.5 m below the shoulder (the near half of the disc in reach).
    fn default() -> Self {
        Self {
            distance_from_base_axis_m: (0.6, 1.0),
            below_shoulder_m: (0.0, 0.5),
            azimuth_deg: (-180.0, 180.0),
        }
    }
}

/// Camera tilt range of every scenario but `near-axis`, degrees: the issue's
/// "tilted up to 35 degrees", starting at 10 degrees so that the camera is off
/// the disc's axis (see `world::generator` for why).
pub const PAPER_CAMERA_TILT_DEG: (f64, f64) = (10.0, 35.0);

/// Camera tilt range of the `near-axis` scenario, degrees.
pub const NEAR_AXIS_CAMERA_TILT_DEG: (f64, f64) = (0.0, 10.0);

/// Largest camera tilt any scenario may ask for, degrees: beyond it the disc is
/// seen too obliquely for the workcell generator's rim-fill rule.
pub const CAMERA_MAX_TILT_DEG: f64 = 35.0;

/// A scenario without `camera_tilt_deg` (in a truth file) reads as the paper's range.
fn paper_camera_tilt_deg() -> (f64, f64) {
    PAPER_CAMERA_TILT_DEG
}

/// Scenario names accepted by [`Scenario::named`], in report order.
pub const SCENARIO_NAMES: [&str; 7] = [
    "noise-free",
    "paper",
    "noisy",
    "quarter-turn",
    "non-planar",
    "reverse",
    "near-axis",
];

/// Unknown scenario name.
#[derive(Debug, Clone, PartialEq)]
pub struct UnknownScenario(pub String);

impl fmt::Display for UnknownScenario {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "unknown scenario \"{}\" (known: {})",
            self.0,
            SCENARIO_NAMES.join(", ")
        )
    }
}

impl std::error::Error for UnknownScenario {}

impl Scenario {
    /// The paper's experiment (Section 5): 0.5 px noise, about 300 frames over one
    /// revolution, 5 % dropouts, the end effector seen in 5 to 20 frames, a flat-topped
    /// part 2 to 10 cm high, the camera tilted 10 to 35 degrees (off the disc's axis).
    pub fn paper() -> Self {
        Self {
            name: "paper".to_string(),
            frames: 300,
            revolutions: 1.0,
            frame_rate_hz: 30.0,
            pixel_sigma_px: 0.5,
            dropout_probability: 0.05,
            outlier_probability: 0.0,
            effector_frames_min: 5,
            effector_frames_max: 20,
            part_feature_count: 3,
            feature_heights: FeatureHeights::FlatTop {
                min_m: 0.02,
                max_m: 0.10,
            },
            camera_tilt_deg: PAPER_CAMERA_TILT_DEG,
            disc_placement: DiscPlacement::default(),
        }
    }

    pub fn named(name: &str) -> Result<Self, UnknownScenario> {
        let paper = Self::paper();
        let scenario = match name {
            "paper" => paper,
            "noise-free" => Self {
                pixel_sigma_px: 0.0,
                dropout_probability: 0.0,
                ..paper
            },
            "noisy" => Self {
                pixel_sigma_px: 1.0,
                dropout_probability: 0.10,
                outlier_probability: 0.01,
                ..paper
            },
            // Same frame count, but the conveyor only turns a quarter revolution:
            // the reference point's ellipse is seen along a quarter of its arc.
            "quarter-turn" => Self {
                revolutions: 0.25,
                ..paper
            },
            "non-planar" => Self {
                part_feature_count: 4,
                feature_heights: FeatureHeights::Spread {
                    min_m: 0.0,
                    max_m: 0.15,
                    min_spread_m: 0.08,
                },
                ..paper
            },
            // The contract lets the conveyor turn either way; estimators may not assume a sign.
            "reverse" => Self {
                revolutions: -1.0,
                ..paper
            },
            // The paper scenario with the camera almost above the disc's axis (tilt 0 to
            // 10 degrees): the degenerate geometry, kept measurable. Feature heights are
            // poorly observable there, so it has no part-position target; the estimate's
            // reported uncertainty must cover its error and `calibrate` warns.
            "near-axis" => Self {
                camera_tilt_deg: NEAR_AXIS_CAMERA_TILT_DEG,
                ..paper
            },
            other => return Err(UnknownScenario(other.to_string())),
        };
        Ok(Self {
            name: name.to_string(),
            ..scenario
        })
    }

    /// The same scenario with `count` camera frames over the same conveyor travel
    /// at the same frame rate (a longer log: 1800 frames at 30 Hz are 60 s). Beyond
    /// the host calibrator's 1024 stored frames the calibrator thins, the batch
    /// solve of [`crate::batch_ml`] does not.
    pub fn with_frames(self, count: usize) -> Self {
        Self {
            name: format!("{}/frames-{count}", self.name),
            frames: count,
            ..self
        }
    }

    /// The same scenario run `turns` times as long at the same frame rate:
    /// frames, conveyor travel and end-effector sightings all scale with the
    /// time (a cell that goes on calibrating while it works: the arm shows its
    /// marks each time it works over the disc). Named `paper/turns-N`, on the
    /// family's workcells.
    pub fn over_turns(self, turns: usize) -> Self {
        Self {
            name: format!("{}/turns-{turns}", self.name),
            frames: self.frames.saturating_mul(turns),
            revolutions: self.revolutions * turns as f64,
            effector_frames_min: self.effector_frames_min.saturating_mul(turns),
            effector_frames_max: self.effector_frames_max.saturating_mul(turns),
            ..self
        }
    }

    /// The same scenario with the end effector seen in exactly `count` frames.
    pub fn with_effector_frames(self, count: usize) -> Self {
        Self {
            name: format!("{}/effector-{count}", self.name),
            effector_frames_min: count,
            effector_frames_max: count,
            ..self
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_listed_name_resolves_and_unknown_names_are_refused() {
        for name in SCENARIO_NAMES {
            let scenario = Scenario::named(name);
            assert_eq!(scenario.map(|s| s.name), Ok(name.to_string()));
        }
        let err = Scenario::named("sideways").err();
        assert!(err.is_some_and(|e| e.to_string().contains("sideways")));
    }

    #[test]
    fn only_near_axis_puts_the_camera_within_10_degrees_of_vertical() {
        for name in SCENARIO_NAMES {
            let (low, high) = Scenario::named(name).map(|s| s.camera_tilt_deg).unwrap();
            if name == "near-axis" {
                assert_eq!((low, high), (0.0, 10.0));
            } else {
                assert_eq!((low, high), (10.0, 35.0), "{name}");
            }
        }
    }

    #[test]
    fn a_scenario_without_a_tilt_range_reads_as_the_paper_range() {
        let mut json = serde_json::to_value(Scenario::named("noisy").unwrap()).unwrap();
        json.as_object_mut().unwrap().remove("camera_tilt_deg");
        let read: Scenario = serde_json::from_value(json).unwrap();
        assert_eq!(read, Scenario::named("noisy").unwrap());
    }
}
