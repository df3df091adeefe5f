//! `host-sim faults`: seeded faulty picks, the table of fault against outcome,
//! and every safety invariant checked (see [`crate::pick::faults`]); with
//! `--trial`, one trial replayed with plots.

use std::fmt::Write as _;
use std::fs;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use rayon::prelude::*;

use crate::pick::faults::{
    fault_table, inject, run_faulty, run_trial, trial_rng, violations, write_trials_csv, FaultKind,
    FaultTrial, AT_REST_RAD_S, STRIKE_CLEARANCE_M,
};
use crate::pick::invariants::{
    CAMERA_CLEARANCE_M, NEAR_PART_M, NEAR_PART_SPEED_M_S, SELF_CLEARANCE_M,
};
use crate::pick::montecarlo::trial_seed;
use crate::pick::outputs::write_run_outputs;
use crate::pick::report::{link_line, result_name};
use crate::scenario::pick::PickExperiment;

/// Options of `host-sim faults`.
#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// Number of faulty picks (the fault kinds take turns).
    #[arg(long, default_value_t = 1000)]
    pub trials: usize,
    /// Base seed: trial k runs the world seeded with `seed * 1_000_000 + k`.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Replay this one trial (with plots and CSV in --out) instead of the campaign.
    #[arg(long)]
    pub trial: Option<usize>,
    /// The experiment the faults are injected into (no conveyor stop: the disc turns).
    #[arg(long, default_value = "turning")]
    pub experiment: String,
    /// Scenario file (TOML); the embedded default when absent.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Folder for report.md, trials.csv and summary.json.
    #[arg(long, default_value = "faults-out")]
    pub out: PathBuf,
}

/// Replays one trial with plots and time series in `args.out`.
fn replay(args: &Args, experiment: &PickExperiment, trial: usize) -> Result<()> {
    let seed = trial_seed(args.seed, trial);
    let kind = FaultKind::of_trial(trial);
    let (faulty, fault) = inject(experiment, kind, &mut trial_rng(seed));
    println!("trial {trial} (seed {seed}): {} ({fault})", kind.name());
    let run = run_faulty(&faulty, kind, seed)?;
    write_run_outputs(&run, &args.out)?;
    if let Some(line) = link_line(&run) {
        println!("{line}");
    }
    let unsafe_list = violations(&run);
    println!(
        "result: {}; worst speed {:.2} and applied torque {:.3} of their limits; lowest gripper over the disc {:.1} mm; joint range margin {:.1} deg; camera {:.0} mm, self {:.0} mm clear; {:.0} mm/s near the part; {}",
        result_name(&run.result),
        run.max_speed_ratio,
        run.max_torque_ratio,
        run.min_tool_clearance_m * 1e3,
        run.safety.joint_limit_margin_deg,
        run.safety.camera_clearance_mm,
        run.safety.self_clearance_mm,
        run.safety.near_part_speed_mm_s,
        if unsafe_list.is_empty() {
            "safe".to_owned()
        } else {
            format!("UNSAFE: {}", unsafe_list.join("; "))
        }
    );
    println!("(plots and time series in {})", args.out.display());
    Ok(())
}

pub fn run(args: &Args) -> Result<()> {
    let experiment = super::load_experiment(args.scenario.as_deref(), &args.experiment)?;
    if experiment.conveyor.stop.is_some() {
        bail!(
            "experiment {} stops its conveyor; the fault campaign needs one that keeps turning (e.g. turning)",
            experiment.name
        );
    }
    if let Some(trial) = args.trial {
        return replay(args, &experiment, trial);
    }
    let (pool, progress) = super::campaign_pool(args.threads, args.trials, "faulty picks")?;
    let started = std::time::Instant::now();
    let mut trials: Vec<FaultTrial> = pool.install(|| {
        (0..args.trials)
            .into_par_iter()
            .map(|trial| {
                let result = run_trial(&experiment, args.seed, trial);
                progress.inc(1);
                result
            })
            .collect()
    });
    progress.finish_and_clear();
    trials.sort_by_key(|t| t.trial);
    let elapsed = started.elapsed().as_secs_f64();
    let unsafe_runs: Vec<&FaultTrial> =
        trials.iter().filter(|t| !t.violations.is_empty()).collect();
    let mut report = format!(
        "# Faulty picks: {}, {} trials (seed {})\n\n{}\n",
        experiment.name,
        trials.len(),
        args.seed,
        fault_table(&trials)
    );
    let _ = writeln!(
        report,
        "Unsafe or unreported ends: {} of {} (a stop must leave every joint under {AT_REST_RAD_S} rad/s; joints within their ranges and speeds; the gripper {:.0} mm above the disc; the arm {:.0} mm clear of the camera and {:.0} mm of itself; the gripper under {:.0} mm/s within {:.0} mm of the part; the applied torque within its limit).",
        unsafe_runs.len(),
        trials.len(),
        STRIKE_CLEARANCE_M * 1e3,
        CAMERA_CLEARANCE_M * 1e3,
        SELF_CLEARANCE_M * 1e3,
        NEAR_PART_SPEED_M_S * 1e3,
        NEAR_PART_M * 1e3
    );
    for t in unsafe_runs.iter().take(20) {
        let _ = writeln!(
            report,
            "- trial {} (replay: `host-sim faults --seed {} --trial {}`): {} ({}): {}",
            t.trial,
            args.seed,
            t.trial,
            t.kind.name(),
            t.fault,
            t.violations.join("; ")
        );
    }
    let _ = writeln!(
        report,
        "\n{} picks in {elapsed:.1} s on {} threads.",
        trials.len(),
        pool.current_num_threads()
    );
    fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    fs::write(args.out.join("report.md"), &report).context("writing report.md")?;
    write_trials_csv(&args.out.join("trials.csv"), &trials)?;
    let json = serde_json::to_string_pretty(&trials).context("summary.json")?;
    fs::write(args.out.join("summary.json"), json).context("writing summary.json")?;
    println!("{report}");
    println!("(written to {})", args.out.display());
    Ok(())
}
