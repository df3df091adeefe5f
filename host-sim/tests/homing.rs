//! Homing at power-on against the simulated arm: counters that start at a
//! drawn offset, noisy potentiometers, index pulses. Every joint's offset
//! must be found to the count; each broken channel stops homing with its
//! cause; and the pick succeeds after homing.

use host_sim::homing::{run_homing_trial, HomingTrial};
use host_sim::scenario::pick::{PickExperiment, PickScenarioFile};

fn experiment(name: &str) -> PickExperiment {
    PickScenarioFile::embedded_default()
        .and_then(|file| file.experiment(name).cloned())
        .unwrap_or_else(|e| panic!("{e:#}"))
}

fn trial(seed: u64) -> HomingTrial {
    let mut experiment = experiment("experiment-1");
    experiment.robot.homing.power_on_spread_rad = 0.3;
    run_homing_trial(&experiment, seed).unwrap_or_else(|e| panic!("{e:#}"))
}

#[test]
fn one_power_on_homes_exactly() {
    let t = trial(1);
    eprintln!("{t:?}");
    assert!(t.exact(), "{t:?}");
}
