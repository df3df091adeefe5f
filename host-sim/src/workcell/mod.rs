//! Synthetic workcells for testing the self-calibration: random geometry with
//! known truth, a pinhole camera, end-effector poses the PUMA 560 can reach,
//! named noise scenarios, and the recorder that turns them into observation logs.

pub mod camera;
pub mod effector;
pub mod generator;
pub mod geometry;
pub mod model;
pub mod record;
pub mod scenario;
pub mod truth;

pub use generator::{random_workcell, GenerationError, WorkcellParameters};
pub use model::Workcell;
pub use record::{simulate, SimulatedRun};
pub use scenario::{FeatureHeights, Scenario, UnknownScenario, SCENARIO_NAMES};
pub use truth::{read_truth_file, truth_path_for, write_truth_file, TruthFile};
pub mod command;
