//! The Monte-Carlo harness: one trial = one random workcell recorded under a
//! scenario, calibrated by the refined estimator and by the paper's own
//! two-frame method (and, on request, by the full batch maximum-likelihood
//! solve of [`crate::batch_ml`]), each compared with the truth. Trials run in parallel
//! (rayon); every trial's seed is derived from the base seed, the scenario
//! family and the trial number, so results do not depend on thread scheduling.

use indicatif::ProgressBar;
use rayon::prelude::*;
use serde::Serialize;
use shared::calibration::{CalibrationConfig, CalibrationError};
use shared::observation::CalibrationResult;

use super::metrics::{compare, ErrorMetrics};
use crate::batch_ml::batch_estimate;
use crate::calibration::{calibrate_log_with, part_sigmas_m, Adoption, CalibratorChoice};
use crate::recording::simulate;
use crate::scenario::Scenario;

/// Which estimate of a trial.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// `SelfCalibrator::estimate`: the refined (maximum-likelihood) estimate.
    Refined,
    /// `SelfCalibrator::paper_estimate`: Eq 8 with two frames, Eq 15 with one pose.
    Paper,
    /// `batch_ml::batch_estimate`: the full batch solve over every frame, the
    /// maximum-likelihood limit of the same log (run with `accuracy --batch`).
    Batch,
}

impl Method {
    pub const ALL: [Method; 3] = [Method::Refined, Method::Paper, Method::Batch];

    pub fn name(self) -> &'static str {
        match self {
            Method::Refined => "refined",
            Method::Paper => "paper",
            Method::Batch => "batch",
        }
    }
}

/// One trial to run.
#[derive(Debug, Clone)]
pub struct TrialPlan {
    pub scenario: Scenario,
    pub trial: usize,
    /// Seed of `record --seed` that reproduces this trial's log.
    pub seed: u64,
}

/// What one trial gave.
#[derive(Debug, Clone)]
pub struct TrialOutcome {
    pub scenario: String,
    pub trial: usize,
    pub seed: u64,
    pub effector_frames: u32,
    /// Tilt of the camera's optical axis from the vertical: near 0 the feature
    /// heights are weakly observable (tilt and offset of the camera look alike).
    pub camera_tilt_deg: f64,
    /// Reported one-sigma of the refined part position (root-sum-square of the
    /// axes), mm; `None` when the refined estimate (or the trial) failed.
    pub refined_part_sigma_mm: Option<f64>,
    /// Errors per method, or why that method (or the trial) failed.
    pub refined: Result<ErrorMetrics, String>,
    pub paper: Result<ErrorMetrics, String>,
    /// The batch solve's errors; `None` when it was not asked for.
    pub batch: Option<Result<ErrorMetrics, String>>,
}

impl TrialOutcome {
    /// The errors of `method`, `None` when that method was not run.
    pub fn errors(&self, method: Method) -> Option<&Result<ErrorMetrics, String>> {
        match method {
            Method::Refined => Some(&self.refined),
            Method::Paper => Some(&self.paper),
            Method::Batch => self.batch.as_ref(),
        }
    }
}

/// How the trials are calibrated.
#[derive(Debug, Clone, Copy, Default)]
pub struct HarnessOptions {
    pub calibration: CalibrationConfig,
    /// Experiment 2 of the paper: give the estimator the true disc height in the base frame.
    pub disc_height_known: bool,
    /// Also run the batch maximum-likelihood solve, started from the refined estimate.
    pub batch: bool,
    /// Which calibrator the logs are streamed into (the host's or the pick's).
    pub calibrator: CalibratorChoice,
}

fn splitmix64(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

fn fnv1a(text: &str) -> u64 {
    text.bytes().fold(0xCBF2_9CE4_8422_2325, |hash, byte| {
        (hash ^ u64::from(byte)).wrapping_mul(0x0100_0000_01B3)
    })
}

/// Seed of trial `trial` of `scenario`. Variants of one scenario (`paper/effector-5`)
/// share the family's seeds, so they see the same workcells: paired comparisons.
pub fn trial_seed(base_seed: u64, scenario: &str, trial: usize) -> u64 {
    let family = scenario.split('/').next().unwrap_or(scenario);
    splitmix64(splitmix64(base_seed) ^ fnv1a(family) ^ splitmix64(trial as u64))
}

pub fn plan_trials(scenarios: &[Scenario], trials: usize, base_seed: u64) -> Vec<TrialPlan> {
    scenarios
        .iter()
        .flat_map(|scenario| {
            (0..trials).map(move |trial| TrialPlan {
                scenario: scenario.clone(),
                trial,
                seed: trial_seed(base_seed, &scenario.name, trial),
            })
        })
        .collect()
}

fn score(
    estimate: &Result<CalibrationResult, CalibrationError>,
    truth: &CalibrationResult,
) -> Result<ErrorMetrics, String> {
    match estimate {
        Ok(result) => compare(result, truth).map_err(|e| e.to_string()),
        Err(e) => Err(e.to_string()),
    }
}

pub fn run_trial(plan: &TrialPlan, options: &HarnessOptions) -> TrialOutcome {
    let failed = |message: String| TrialOutcome {
        scenario: plan.scenario.name.clone(),
        trial: plan.trial,
        seed: plan.seed,
        effector_frames: 0,
        camera_tilt_deg: f64::NAN,
        refined_part_sigma_mm: None,
        refined: Err(message.clone()),
        paper: Err(message.clone()),
        batch: options.batch.then_some(Err(message)),
    };
    let run = match simulate(&plan.scenario, plan.seed) {
        Ok(run) => run,
        Err(e) => return failed(e.to_string()),
    };
    let truth = &run.truth.result;
    let config = CalibrationConfig {
        disc_height_in_base_m: if options.disc_height_known {
            Some(truth.base_from_disc.translation_m[2])
        } else {
            options.calibration.disc_height_in_base_m
        },
        ..options.calibration
    };
    let calibration = calibrate_log_with(
        options.calibrator,
        Adoption::default(),
        &run.log,
        run.log.frames.len(),
        config,
    );
    match calibration {
        Ok(calibration) => TrialOutcome {
            batch: options.batch.then(|| match &calibration.refined {
                Ok(start) => batch_estimate(&run.log, &config, start)
                    .map_err(|e| format!("batch solve: {e}"))
                    .and_then(|batch| compare(&batch.result, truth).map_err(|e| e.to_string())),
                Err(e) => Err(format!("no start for the batch solve: {e}")),
            }),
            scenario: plan.scenario.name.clone(),
            trial: plan.trial,
            seed: plan.seed,
            effector_frames: truth.quality.effector_frames_used,
            camera_tilt_deg: run.truth.workcell.camera_tilt_deg,
            refined_part_sigma_mm: calibration
                .refined_uncertainty
                .as_ref()
                .map(|u| part_sigmas_m(u).1 * 1000.0),
            refined: score(&calibration.refined, truth),
            paper: score(&calibration.paper, truth),
        },
        Err(e) => TrialOutcome {
            effector_frames: truth.quality.effector_frames_used,
            camera_tilt_deg: run.truth.workcell.camera_tilt_deg,
            ..failed(format!("{e:#}"))
        },
    }
}

/// Runs every plan in parallel on the current rayon pool; outcomes come back in plan order.
pub fn run_trials(
    plans: &[TrialPlan],
    options: &HarnessOptions,
    progress: &ProgressBar,
) -> Vec<TrialOutcome> {
    plans
        .par_iter()
        .map(|plan| {
            let outcome = run_trial(plan, options);
            progress.inc(1);
            outcome
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trial_seeds_are_stable_distinct_and_shared_within_a_family() {
        let seed = trial_seed(1, "paper", 3);
        assert_eq!(seed, trial_seed(1, "paper", 3));
        assert_eq!(seed, trial_seed(1, "paper/effector-5", 3));
        assert_ne!(seed, trial_seed(1, "paper", 4));
        assert_ne!(seed, trial_seed(2, "paper", 3));
        assert_ne!(seed, trial_seed(1, "noisy", 3));
    }

    #[test]
    fn trials_come_back_in_plan_order_and_match_a_serial_run() {
        let scenarios = [
            Scenario::named("noise-free").expect("scenario"),
            Scenario::paper().with_effector_frames(5),
        ];
        let plans = plan_trials(&scenarios, 3, 9);
        assert_eq!(plans.len(), 6);
        let options = HarnessOptions::default();
        let parallel = run_trials(&plans, &options, &ProgressBar::hidden());
        for (plan, outcome) in plans.iter().zip(&parallel) {
            assert_eq!((plan.trial, plan.seed), (outcome.trial, outcome.seed));
            assert_eq!(plan.scenario.name, outcome.scenario);
            let serial = run_trial(plan, &options);
            assert_eq!(serial.refined, outcome.refined);
        }
        let sweep: Vec<u32> = parallel.iter().skip(3).map(|o| o.effector_frames).collect();
        assert_eq!(sweep, vec![5, 5, 5]);
    }
}
