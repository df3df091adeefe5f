//! The conditions a user will have (issue 17), each at its worst setting
//! (`host-sim/scenarios/conditions.toml`): the pick must succeed in them as in
//! the default cell, not stop safely. 30 random workcells per condition, on a
//! seed the figures of docs/pick.md were not measured on; at the 99 % goal
//! three or more misses in 30 happen with probability 0.003, so the test
//! asks for at least 28 successes.

use std::path::PathBuf;

use host_sim::pick::montecarlo::{run_trials, TrialSummary};
use host_sim::scenario::pick::{PickExperiment, PickScenarioFile};

const TRIALS: usize = 30;
const MIN_SUCCESSES: usize = 28;
const SEED: u64 = 17;

fn conditions() -> PickScenarioFile {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenarios/conditions.toml");
    PickScenarioFile::from_path(&path).unwrap()
}

fn condition(name: &str) -> PickExperiment {
    conditions().experiment(name).unwrap().clone()
}

fn assert_picked(name: &str) {
    let experiment = condition(name);
    let progress = indicatif::ProgressBar::hidden();
    let trials: Vec<TrialSummary> = run_trials(&experiment, TRIALS, SEED, &progress);
    let failures: Vec<&TrialSummary> = trials.iter().filter(|t| !t.success).collect();
    let successes = trials.len() - failures.len();
    for trial in &trials {
        assert!(
            trial.max_speed_ratio < 1.0 && trial.max_torque_ratio <= 1.0,
            "{name}: {trial:?}"
        );
    }
    assert!(
        successes >= MIN_SUCCESSES,
        "{name}: {successes} of {TRIALS} picked; failures: {failures:#?}"
    );
}

/// The file holds each condition at (at least) its worst setting, so that
/// an edit cannot quietly make the conditions easier.
#[test]
fn the_conditions_are_at_their_worst_settings() {
    let file = conditions();
    let vision = file.experiment("vision-worst").unwrap();
    assert!(vision.camera.pixel_sigma_px >= 1.0);
    assert!(vision.camera.dropout_probability >= 0.10);
    assert!(vision.camera.outlier_probability >= 0.005);
    assert!(vision.camera.latency_ms >= 160.0);
    let disc = file.experiment("disc-fast").unwrap();
    assert!(disc.conveyor.speed_rad_s.abs() >= 1.0);
    assert!(disc.conveyor.ripple_fraction >= 0.10);
    let part = file.experiment("part-tall").unwrap();
    assert!(part.part.height_m >= 0.08);
    assert_eq!(part.part.feature_count, 8);
    let all = file.experiment("all-worst").unwrap();
    assert_eq!(all.camera, vision.camera);
    assert_eq!(all.conveyor, disc.conveyor);
    assert_eq!(all.part, part.part);
    // The gripper, the drives and the layouts are the default cell's:
    // nothing loosened.
    let turning = PickScenarioFile::default_experiment("turning").unwrap();
    for experiment in &file.experiment {
        assert_eq!(experiment.gripper, turning.gripper, "{}", experiment.name);
        assert_eq!(experiment.robot, turning.robot, "{}", experiment.name);
        assert_eq!(experiment.cell, turning.cell, "{}", experiment.name);
        assert!(!experiment.disc_height_known, "{}", experiment.name);
    }
}

#[test]
fn the_tallest_part_with_the_most_features_is_picked() {
    assert_picked("part-tall");
}

#[test]
fn the_camera_at_its_worst_still_picks() {
    assert_picked("vision-worst");
}

#[test]
fn the_fastest_disc_still_picks() {
    assert_picked("disc-fast");
}

#[test]
fn every_condition_at_its_worst_at_once_still_picks() {
    assert_picked("all-worst");
}
