//! The scenarios the simulation runs, below the world that realises them.
//!
//! - [`recording`]: named scenarios for recording synthetic observation logs
//!   (noise, frames, effector sightings, feature heights, camera tilt).
//! - [`pick`]: pick scenario files (TOML): the experiments of the full pick.

pub mod pick;
pub mod recording;

pub use pick::{PickExperiment, PickScenarioFile};
pub use recording::{FeatureHeights, Scenario, UnknownScenario, SCENARIO_NAMES};
