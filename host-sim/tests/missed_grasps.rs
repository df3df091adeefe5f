//! Monte Carlo cells (`host-sim run --experiment turning --seed
//! S000000+K` replays trial K of seed S) whose grasp the pick used to miss. A missed
//! grasp is a failure to fix, not a stop to count (issue 17); each test failed
//! on the code before its fix.

use host_sim::pick::montecarlo::trial_seed;
use host_sim::pick::record::{PickResult, PickRun};
use host_sim::pick::runner::run_pick_in_process;
use host_sim::scenario::pick::{PickExperiment, PickScenarioFile};
use shared::protocol::PickPhase;

fn turning() -> PickExperiment {
    PickScenarioFile::default_experiment("turning").unwrap()
}

fn pick(seed: u64, trial: usize) -> PickRun {
    run_pick_in_process(&turning(), trial_seed(seed, trial)).unwrap()
}

/// The gripper's part-relative speed at the close, mm/s.
fn closing_speed_mm_s(run: &PickRun) -> f64 {
    run.grasp
        .as_ref()
        .map_or(f64::NAN, |g| 1e3 * g.relative_speed_m_s)
}

/// Seed 1 trials 135 and 440, seed 2 trial 960: joint 3 (with joint 2 in
/// trial 960) turned round where the descent ended, stuck on its Coulomb
/// friction (the drawn drive's, off the nominal model's) and slipped just as
/// the gripper closed, at 28, 24 and 24 mm/s against the part (the gripper
/// takes 20). The gripper now closes once the grasp point has held within
/// `close_tolerance_m` of its reference for `close_hold_s`, waiting up to
/// the settle the plan's grasp window holds for plus the track's spare time.
#[test]
fn the_gripper_waits_out_a_stuck_joints_slip_before_closing() {
    for (seed, trial) in [(1, 135), (1, 440), (2, 960)] {
        let run = pick(seed, trial);
        assert_eq!(run.result, PickResult::Success, "seed {seed} trial {trial}");
        let speed = closing_speed_mm_s(&run);
        assert!(speed <= 15.0, "seed {seed} trial {trial}: {speed} mm/s");
    }
}

/// Trial 308: the search saw the marks from high up only, so every
/// calibration pose lay below the height known to be clear and each was
/// skipped: the base came from the search's 21 sightings alone, 6.2 mm off,
/// and the grasp missed by 7.6 mm. A pose below the known-clear height is
/// now shown at that height, and the marks seen there clear the next one.
#[test]
fn calibration_poses_below_the_known_clear_height_are_shown_higher_not_skipped() {
    let run = pick(1, 308);
    assert!(
        run.phases
            .iter()
            .any(|p| p.phase == PickPhase::CalibrateBase),
        "no calibration pose was shown"
    );
    assert_eq!(run.result, PickResult::Success, "{:?}", run.result);
    let error = run
        .grasp
        .as_ref()
        .and_then(|g| g.estimate_error_m)
        .map_or(f64::NAN, |e| e[0].hypot(e[1]));
    assert!(error <= 3.0e-3, "{} mm", 1e3 * error);
}
