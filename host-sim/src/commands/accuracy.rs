//! `host-sim accuracy`: the seeded Monte-Carlo run, one command.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use shared::calibration::CalibrationConfig;

use crate::accuracy::harness::{plan_trials, run_trials, HarnessOptions};
use crate::accuracy::report::{markdown, write_outputs};
use crate::accuracy::summary::summarise;
use crate::calibration::CalibratorChoice;
use crate::scenario::{Scenario, SCENARIO_NAMES};

/// Monte-Carlo accuracy of the self-calibration over random workcells.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Random workcells per scenario.
    #[arg(long, default_value_t = 100)]
    pub trials: usize,
    /// Base seed; each trial's log is reproducible with `record --seed` (see trials.csv).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Scenarios to run (comma-separated); default all.
    #[arg(long, value_delimiter = ',', default_values_t = SCENARIO_NAMES.map(String::from))]
    pub scenarios: Vec<String>,
    /// Effector-frame counts of the paper scenario's sweep (comma-separated; the flag
    /// alone, with no value, runs no sweep).
    #[arg(long, value_delimiter = ',', num_args = 0.., default_values_t = [5_usize, 20, 100])]
    pub effector_sweep: Vec<usize>,
    /// Paper-scenario variants with this many frames over the same revolution
    /// (comma-separated; e.g. 1800, a 60 s log at 30 Hz, beyond the host calibrator's
    /// 1024 stored frames); named `paper/frames-N`, same workcells as `paper`.
    #[arg(long, value_delimiter = ',', num_args = 0..)]
    pub frame_counts: Vec<usize>,
    /// Paper-scenario variants calibrated over this many revolutions at the
    /// same frame rate (comma-separated; e.g. 1,2,4,8): frames, travel and
    /// sightings grow with the time; named `paper/turns-N`, same workcells as
    /// `paper`. The error against calibration time.
    #[arg(long, value_delimiter = ',', num_args = 0..)]
    pub turns: Vec<usize>,
    /// Experiment 2 of the paper: tell the estimator the true disc height in the base frame.
    #[arg(long)]
    pub disc_height_known: bool,
    /// Also run the full batch maximum-likelihood solve over every frame per trial
    /// (started from the calibrator's estimate) and report its errors beside the calibrator's.
    #[arg(long)]
    pub batch: bool,
    /// The calibrator the logs are streamed into: the host's (1024 frames,
    /// 256 sightings) or the pick controller's own (256 frames, 128
    /// sightings, as on the firmware); both fold what they have no room for.
    #[arg(long, value_enum, default_value_t = CalibratorChoice::Host)]
    pub calibrator: CalibratorChoice,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Folder for report.md, trials.csv and summary.json.
    #[arg(long, default_value = "accuracy-out")]
    pub out: PathBuf,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let mut scenarios = args
        .scenarios
        .iter()
        .map(|name| Scenario::named(name.trim()))
        .collect::<Result<Vec<_>, _>>()?;
    scenarios.extend(
        args.effector_sweep
            .iter()
            .map(|&count| Scenario::paper().with_effector_frames(count)),
    );
    if let Some(zero) = args.frame_counts.iter().find(|&&count| count == 0) {
        anyhow::bail!("--frame-counts: {zero} frames cannot be calibrated");
    }
    scenarios.extend(
        args.frame_counts
            .iter()
            .map(|&count| Scenario::paper().with_frames(count)),
    );
    if args.turns.contains(&0) {
        anyhow::bail!("--turns: 0 revolutions cannot be calibrated");
    }
    scenarios.extend(
        args.turns
            .iter()
            .map(|&turns| Scenario::paper().over_turns(turns)),
    );
    let plans = plan_trials(&scenarios, args.trials, args.seed);
    let options = HarnessOptions {
        calibration: CalibrationConfig::default(),
        disc_height_known: args.disc_height_known,
        batch: args.batch,
        calibrator: args.calibrator,
    };

    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(threads) = args.threads {
        pool = pool.num_threads(threads);
    }
    let pool = pool.build().context("starting the worker threads")?;
    let progress = ProgressBar::new(plans.len() as u64);
    if let Ok(style) =
        ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} trials, eta {eta}")
    {
        progress.set_style(style);
    }
    let started = Instant::now();
    let outcomes = pool.install(|| run_trials(&plans, &options, &progress));
    progress.finish_and_clear();

    let rows = summarise(&outcomes);
    let estimator = match args.calibrator {
        CalibratorChoice::Host => "shared::calibration::HostCalibrator",
        CalibratorChoice::Pick => "shared::app::pick::PickCalibrator",
    };
    let mut notes = vec![format!(
        "Estimator: `{estimator}` with {:?}.",
        options.calibration
    )];
    if args.batch {
        notes.push(
            "Batch: `host_sim::batch_ml::batch_estimate`, the full least-squares solve over every \
             frame and sighting of the log, started from the calibrator's estimate."
                .to_string(),
        );
    }
    if args.disc_height_known {
        notes.push(
            "Experiment 2 of the paper: the disc height in the base frame is given to the estimator."
                .to_string(),
        );
    }
    let report = markdown(&rows, &outcomes, args.trials, args.seed, &notes);
    write_outputs(&args.out, &report, &rows, &outcomes)?;
    println!("{report}");
    eprintln!(
        "{} trials in {:.1} s on {} threads; report.md, trials.csv, summary.json in {}",
        plans.len(),
        started.elapsed().as_secs_f64(),
        pool.current_num_threads(),
        args.out.display()
    );
    Ok(())
}
