//! Homing at power-on against the simulated arm: counters that start at a
//! drawn offset, noisy potentiometers, index pulses. Every joint's offset
//! must be found to the count over 1,000 seeded power-ons; each broken
//! channel stops homing with its cause, the arm held; and the pick
//! succeeds after homing.

use host_sim::homing::{run_homing_trial, HomingTrial};
use host_sim::pick::record::PickResult;
use host_sim::pick::runner::run_pick_in_process;
use host_sim::scenario::pick::{PickExperiment, PickScenarioFile};
use host_sim::world::homing_sensors::HomingFault;
use shared::app::power_on_homing::{puma_homing_specs, SEARCH_SPEED_RAD_S};
use shared::protocol::{FaultCause, PickPhase};

/// How far from the ready posture the arm may stand at power-on in these
/// trials, rad per joint.
const POWER_ON_SPREAD_RAD: f64 = 0.3;

fn experiment(name: &str) -> PickExperiment {
    PickScenarioFile::embedded_default()
        .and_then(|file| file.experiment(name).cloned())
        .unwrap_or_else(|e| panic!("{e:#}"))
}

fn anywhere(mut experiment: PickExperiment) -> PickExperiment {
    experiment.robot.homing.power_on_spread_rad = POWER_ON_SPREAD_RAD;
    experiment
}

fn trial(experiment: &PickExperiment, seed: u64) -> HomingTrial {
    run_homing_trial(experiment, seed).unwrap_or_else(|e| panic!("{e:#}"))
}

#[test]
fn a_thousand_power_ons_home_every_joint_to_the_count() {
    let experiment = anywhere(experiment("experiment-1"));
    let mut worst_speed: f64 = 0.0;
    let mut worst_excursion: f64 = 0.0;
    let mut longest: f64 = 0.0;
    let mut back = 0;
    for seed in 0..1000 {
        let t = trial(&experiment, seed);
        assert!(t.exact(), "seed {seed}: {t:?}");
        back += usize::from(t.back_on_power_on_counts);
        worst_speed = worst_speed.max(t.max_joint_speed_rad_s);
        worst_excursion = worst_excursion.max(t.max_excursion_rad);
        longest = longest.max(t.duration_s);
    }
    eprintln!(
        "1000 of 1000 exact; worst joint speed {worst_speed:.3} rad/s, \
         excursion {worst_excursion:.3} rad, longest homing {longest:.2} s; \
         {back} back on their power-on counts"
    );
    // Slow and short: about the search speed, and within the search span
    // (1.5 index pitches, 0.18 rad at most) of where the arm stood.
    assert!(
        worst_speed < 2.0 * f64::from(SEARCH_SPEED_RAD_S),
        "{worst_speed}"
    );
    assert!(worst_excursion < 0.2, "{worst_excursion}");
}

fn broken(fault: HomingFault) -> PickExperiment {
    let mut experiment = experiment("experiment-1");
    experiment.faults.homing = Some(fault);
    experiment
}

#[test]
fn a_dead_index_channel_stops_homing_with_its_cause() {
    let t = trial(&broken(HomingFault::DeadIndex { joint: 2 }), 4);
    let error = t.error.clone().unwrap_or_default();
    assert!(t.homed_offsets.is_none(), "{t:?}");
    assert!(error.contains("joint 3: no index pulse"), "{error}");
}

#[test]
fn a_potentiometer_reading_no_number_stops_homing_with_its_cause() {
    let t = trial(&broken(HomingFault::PotNotANumber { joint: 4 }), 4);
    let error = t.error.clone().unwrap_or_default();
    assert!(t.homed_offsets.is_none(), "{t:?}");
    assert!(
        error.contains("joint 5: potentiometer reads no number"),
        "{error}"
    );
    // Stopped at once: the arm never moved off its power-on posture.
    assert!(t.max_excursion_rad < 0.01, "{t:?}");
}

#[test]
fn a_potentiometer_off_by_half_a_pitch_disagrees_with_the_encoder() {
    let pitch = puma_homing_specs(&[10_000.0; 6])[1].grid.pitch_rad;
    let fault = HomingFault::PotOffset {
        joint: 1,
        offset_rad: 0.5 * f64::from(pitch),
    };
    for seed in 0..5 {
        let t = trial(&broken(fault), seed);
        let error = t.error.clone().unwrap_or_default();
        assert!(t.homed_offsets.is_none(), "{t:?}");
        assert!(
            error.contains("joint 2: at the index the potentiometer"),
            "seed {seed}: {error}"
        );
    }
}

#[test]
fn a_homing_fault_reaches_the_host_as_the_picks_fault_and_nothing_moves() {
    let cases = [
        (
            HomingFault::DeadIndex { joint: 0 },
            FaultCause::HomingIndexNotSeen,
        ),
        (
            HomingFault::PotNotANumber { joint: 3 },
            FaultCause::HomingPotentiometer,
        ),
    ];
    for (fault, cause) in cases {
        let run = run_pick_in_process(&broken(fault), 2).unwrap_or_else(|e| panic!("{e:#}"));
        assert_eq!(run.result, PickResult::Fault(cause), "{fault:?}");
        // The pick never started: no phase but the fault.
        assert!(
            run.phases.iter().all(|p| p.phase == PickPhase::Faulted),
            "{:?}",
            run.phases
        );
        assert!(run.grasp.is_none());
    }
}

#[test]
fn the_pick_succeeds_after_homing() {
    // The default experiments home first (their counters start anywhere);
    // here the arm also stands anywhere near its ready posture.
    let experiment = experiment("experiment-1");
    assert!(experiment.robot.homing.counters_start_anywhere);
    let experiment = PickExperiment {
        robot: host_sim::scenario::pick::RobotSettings {
            homing: host_sim::world::homing_sensors::HomingSensorSettings {
                power_on_spread_rad: 0.1,
                ..experiment.robot.homing
            },
            ..experiment.robot
        },
        ..experiment
    };
    for seed in 1..=5 {
        let run = run_pick_in_process(&experiment, seed).unwrap_or_else(|e| panic!("{e:#}"));
        assert_eq!(run.result, PickResult::Success, "seed {seed}");
    }
}
