//! The full pick end to end: the simulated world against the controller
//! application over the serial protocol (in process), on the embedded default
//! scenario and on injected faults.

use host_sim::pick::montecarlo::{run_trials, TrialSummary};
use host_sim::pick::record::{LinkRecord, PickResult, PickRun};
use host_sim::pick::runner::run_pick_in_process;
use host_sim::scenario::pick::{LayoutKind, PickExperiment, PickScenarioFile};
use shared::protocol::{FaultCause, PickPhase};

fn experiment(name: &str) -> PickExperiment {
    PickScenarioFile::default_experiment(name).unwrap()
}

/// Limits every run must respect, whatever its outcome.
fn assert_safe(run: &PickRun) {
    assert!(
        run.max_speed_ratio < 1.0,
        "joint speed limit: {}",
        run.max_speed_ratio
    );
    assert!(
        run.max_torque_ratio <= 1.0,
        "torque limit: {}",
        run.max_torque_ratio
    );
    assert!(
        run.min_tool_clearance_m.is_nan() || run.min_tool_clearance_m >= 0.0,
        "the gripper went below the disc surface: {} m",
        run.min_tool_clearance_m
    );
}

#[test]
fn the_paper_experiments_and_the_moving_pick_succeed() {
    for name in [
        "experiment-1",
        "experiment-2-4cm",
        "experiment-2-7cm",
        "turning",
    ] {
        let run = run_pick_in_process(&experiment(name), 1).unwrap();
        assert_eq!(run.result, PickResult::Success, "{name}");
        // A clean link: nothing sent twice, refused or stale.
        assert_eq!(run.link, LinkRecord::default(), "{name}");
        assert_safe(&run);
        let grasp = run.grasp.unwrap();
        let [x, y, z] = grasp.estimate_error_m.unwrap();
        // The paper reports about 10 mm and 5 degrees; the gripper takes 5 mm
        // horizontally and 10 mm vertically (the experiments told the disc's
        // height to 3 mm put 4 to 5 mm of it in the height).
        let horizontal = x.hypot(y);
        assert!(
            horizontal < 0.004 && z.abs() < 0.008,
            "{name}: estimate error {x}, {y}, {z} m"
        );
        assert!(
            grasp.estimate_yaw_error_rad.unwrap() < 1.5f64.to_radians(),
            "{name}"
        );
        let [x, y, z] = grasp.position_error_m;
        assert!(
            x.hypot(y) < 0.004 && z.abs() < 0.008,
            "{name}: grasp error {x}, {y}, {z} m"
        );
        assert!(run.calibrated_after_s.unwrap() < 60.0, "{name}");
        assert!(
            run.placed_error_m.unwrap() < 0.01,
            "{name}: placed off the drop-off"
        );
        // Telemetry covered the run and the controller ended at rest, done.
        assert!(run.records.len() > 1000, "{name}");
        assert_eq!(run.phases.last().map(|p| p.phase), Some(PickPhase::Done));
        let last = run.records.last().unwrap();
        assert!(
            last.qd_rad_s.iter().all(|v| v.abs() < 0.01),
            "{name}: still moving"
        );
    }
}

#[test]
fn a_pick_is_deterministic() {
    let turning = experiment("turning");
    let first = run_pick_in_process(&turning, 5).unwrap();
    let second = run_pick_in_process(&turning, 5).unwrap();
    assert_eq!(first, second);
}

#[test]
fn the_search_halts_once_the_marks_have_crossed_the_view() {
    // Seed 7's disc lies the way the search turns first, 1.3 rad round. The
    // search sweeps on until the marks, seen 6 times, have left the view for
    // 1 s, halts and comes back over them: 5.3 s, joint 1 down to -1.7 rad.
    // (Before, it went on to the range's end, -2.69 rad, swept the whole range
    // and came back: 22 s.)
    let run = run_pick_in_process(&experiment("turning"), 7).unwrap();
    assert_eq!(run.result, PickResult::Success, "{:?}", run.phases);
    assert_safe(&run);
    // The search ends where the next phase begins (`Estimating`, or
    // `CalibrateBase` when the first estimate landed on the way back).
    let search_end = run
        .phases
        .iter()
        .skip_while(|p| p.phase != PickPhase::SearchEffector)
        .find(|p| p.phase != PickPhase::SearchEffector)
        .map(|p| p.t_s)
        .unwrap();
    let start = run.phases.first().map(|p| p.t_s).unwrap();
    assert!(
        search_end - start < 8.0,
        "searched for {} s",
        search_end - start
    );
    let lowest_q1 = run
        .records
        .iter()
        .filter(|r| r.t_s < search_end)
        .map(|r| r.q_rad[0])
        .fold(f64::INFINITY, f64::min);
    assert!(lowest_q1 > -2.2, "joint 1 went to {lowest_q1} rad");
}

#[test]
fn seeded_random_workcells_are_picked() {
    let turning = experiment("turning");
    let progress = indicatif::ProgressBar::hidden();
    let trials: Vec<TrialSummary> = run_trials(&turning, 12, 7, &progress);
    let successes = trials.iter().filter(|t| t.success).count();
    assert!(successes >= 11, "{successes} of 12: {trials:#?}");
    for trial in &trials {
        assert!(
            trial.max_speed_ratio < 1.0 && trial.max_torque_ratio <= 1.0,
            "{trial:?}"
        );
    }
}

fn with_camera_fault(
    mut experiment: PickExperiment,
    blackout_after_s: Option<f64>,
    hidden: bool,
) -> PickExperiment {
    experiment.camera.faults.blackout_after_s = blackout_after_s;
    experiment.camera.faults.effector_hidden = hidden;
    experiment
}

/// The controller stopped with `cause`, decelerated to rest within its stop
/// time, and held still until the end of the run. A stop raised where a move
/// had just come to its end (a search's last sweep) is over in the period it
/// starts: no `Stopping` phase is reported then.
fn assert_controlled_stop(run: &PickRun, cause: FaultCause) {
    assert_eq!(run.result, PickResult::Fault(cause));
    assert_safe(run);
    let faulted = run
        .phases
        .iter()
        .find(|p| p.phase == PickPhase::Faulted)
        .unwrap();
    let stopping_t_s = run
        .phases
        .iter()
        .find(|p| p.phase == PickPhase::Stopping)
        .map_or(faulted.t_s, |p| p.t_s);
    assert!(
        faulted.t_s - stopping_t_s < 1.0,
        "stop took {} s",
        faulted.t_s - stopping_t_s
    );
    if stopping_t_s == faulted.t_s {
        // No stop ran: the arm was at rest when the fault came.
        let at_fault = run.records.iter().find(|r| r.t_s >= faulted.t_s).unwrap();
        assert!(
            at_fault.qd_rad_s.iter().all(|v| v.abs() < 0.02),
            "moving at the fault: {:?}",
            at_fault.qd_rad_s
        );
    }
    let held: Vec<_> = run
        .records
        .iter()
        .filter(|r| r.t_s > faulted.t_s + 0.2)
        .collect();
    assert!(!held.is_empty());
    for record in held {
        assert!(
            record.qd_rad_s.iter().all(|v| v.abs() < 0.02),
            "not holding at {}",
            record.t_s
        );
    }
}

#[test]
fn vision_going_stale_stops_the_arm() {
    // The camera dies while the arm is calibrating: stale after 2 s, then a controlled stop.
    let run = run_pick_in_process(
        &with_camera_fault(experiment("turning"), Some(25.0), false),
        1,
    )
    .unwrap();
    assert_controlled_stop(&run, FaultCause::VisionStale);
    let stopping = run
        .phases
        .iter()
        .find(|p| p.phase == PickPhase::Stopping)
        .unwrap();
    // The last frame was exposed at most a frame period (0.2 s) before 25 s
    // and arrived at least 60 ms after: stale 2 s later, from 26.86 s.
    assert!(
        (26.85..28.0).contains(&stopping.t_s),
        "stale detected at {}",
        stopping.t_s
    );
    assert!(run.grasp.is_none());
}

#[test]
fn marks_never_seen_is_a_calibration_fault_not_a_guess() {
    let run = run_pick_in_process(
        &with_camera_fault(experiment("experiment-1"), None, true),
        2,
    )
    .unwrap();
    assert_controlled_stop(&run, FaultCause::EffectorNotSeen);
    assert!(
        run.calibrations.is_empty(),
        "no calibration may be reported"
    );
}

/// The turning pick on the first layout drawn from these ranges (any layout,
/// not only those the arm can serve), disc surface 0.6 m below the shoulder.
fn far_layout(distance_m: [f64; 2]) -> PickExperiment {
    let mut far = experiment("turning");
    far.cell.disc_distance_m = distance_m;
    far.cell.disc_below_shoulder_m = [0.6, 0.62];
    far.cell.layouts = LayoutKind::Any;
    far.time_limit_s = 150.0;
    far
}

#[test]
fn a_part_out_of_reach_is_refused_with_a_controlled_stop() {
    // The disc's centre 1.0 m from the base axis, low: the arm sees its marks
    // over the disc's near side and estimates the cell from there, but the part (0.1 to
    // 0.36 m from the disc's centre) rides a circle that never comes within
    // the 0.69 m the arm reaches down there. The controller finds that from
    // its calibration and stops at once, saying so (no 40 s of planning).
    let run = run_pick_in_process(&far_layout([1.0, 1.05]), 3).unwrap();
    assert_controlled_stop(&run, FaultCause::PartOutOfReach);
    assert!(
        run.grasp.is_none(),
        "never closed the gripper on an unreachable part"
    );
    // It estimated (preliminary, then final: one phase when no calibration
    // pose lies within the heights the camera has confirmed), then stopped
    // on the final estimate, within the two estimates' budgets.
    let estimates: Vec<f64> = run
        .phases
        .iter()
        .filter(|p| p.phase == PickPhase::Estimating)
        .map(|p| p.t_s)
        .collect();
    let last_estimate = *estimates.last().unwrap();
    let stopped = run
        .phases
        .iter()
        .find(|p| p.phase == PickPhase::Stopping)
        .unwrap()
        .t_s;
    assert!(
        stopped - last_estimate < 2.5,
        "stopped {stopped} s, last estimate from {last_estimate} s"
    );
}

#[test]
fn a_disc_beyond_every_sweep_is_never_seen_and_said_so() {
    // The disc's near rim 0.7 m from the base axis: at the travel height the
    // arm reaches 0.78 m out. With the gripper's marks on the flange's x
    // axis no sweep brought them into the view of a camera framing that
    // disc, and the controller stopped with `EffectorNotSeen`; across the
    // wrist (y, docs/vision.md) a sweep of the search brings them into view
    // (seed 3), the controller sees the gripper, and stops because the disc
    // is out of the arm's reach. Either way: a controlled
    // stop that names the layout's problem, and no grasp.
    let run = run_pick_in_process(&far_layout([1.15, 1.2]), 3).unwrap();
    match run.result {
        PickResult::Fault(FaultCause::EffectorNotSeen) => {
            assert_controlled_stop(&run, FaultCause::EffectorNotSeen);
            assert!(run.calibrations.is_empty());
        }
        _ => assert_controlled_stop(&run, FaultCause::DiscOutOfReach),
    }
    assert!(run.grasp.is_none());
}

#[test]
fn layouts_the_arm_cannot_serve_stop_with_why() {
    // Layouts the world's check refuses (host-sim/src/world/serve.rs), drawn
    // from the default ranges: each run ends in success (the check is
    // sufficient, not necessary) or in a controlled stop whose cause names
    // the layout's problem, never in a missed grasp or an unsafe motion.
    let mut unservable = experiment("turning");
    unservable.cell.layouts = LayoutKind::Unservable;
    let mut stops = 0;
    for seed in 0..6 {
        let run = run_pick_in_process(&unservable, 100 + seed).unwrap();
        assert_safe(&run);
        match run.result {
            PickResult::Success => {}
            PickResult::Fault(
                cause @ (FaultCause::PartOutOfReach
                | FaultCause::DiscOutOfReach
                | FaultCause::EffectorNotSeen
                | FaultCause::PartUnreachable),
            ) => {
                stops += 1;
                assert_controlled_stop(&run, cause);
                assert!(run.grasp.is_none(), "seed {seed}: a grasp was tried");
            }
            ref other => panic!("seed {seed}: {other:?}"),
        }
    }
    assert!(stops >= 2, "only {stops} of 6 unservable layouts stopped");
}
