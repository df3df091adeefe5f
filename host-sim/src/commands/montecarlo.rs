//! `host-sim montecarlo`: many seeded picks over random workcells, in parallel,
//! with the success rate and the percentiles of the errors that matter for a
//! grasp (see [`crate::pick::montecarlo`]).

use std::fmt::Write as _;
use std::fs;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};

use crate::pick::montecarlo::{
    limit_table, montecarlo_table, run_trials_recording, write_trials_csv, TrialLogs,
    TrialRecording,
};
use crate::scenario::pick::CameraSource;

/// Options of `host-sim montecarlo`.
#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// Number of random workcells.
    #[arg(long, default_value_t = 1000)]
    pub trials: usize,
    /// Base seed: trial k runs the world seeded with `seed * 1_000_000 + k`.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Which experiment of the scenario file to repeat.
    #[arg(long, default_value = "turning")]
    pub experiment: String,
    /// Scenario file (TOML); the embedded default when absent.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Folder for report.md, trials.csv and summary.json.
    #[arg(long, default_value = "montecarlo-out")]
    pub out: PathBuf,
    /// Trials (comma-separated indices, e.g. 3,17) whose own observation log,
    /// truth and controller estimate are written to --log-dir/trial-NNNN/.
    #[arg(long, value_delimiter = ',')]
    pub log_trials: Vec<usize>,
    /// Folder of the logged trials (needed with --log-trials).
    #[arg(long)]
    pub log_dir: Option<PathBuf>,
    /// Also solve each trial's data up to its final estimate in full batch
    /// (every frame and sighting: the maximum-likelihood limit) and report
    /// the final estimate against it.
    #[arg(long)]
    pub ml_limit: bool,
    /// What the controller's camera frames are made from: `images` renders
    /// each frame and labels it with the project's detector and identifier
    /// (the scenario's `camera.source` when absent).
    #[arg(long, value_enum)]
    pub camera_source: Option<CameraSource>,
}

pub fn run(args: &Args) -> Result<()> {
    let mut experiment = super::load_experiment(args.scenario.as_deref(), &args.experiment)?;
    if let Some(source) = args.camera_source {
        experiment.camera.source = source;
    }
    let (pool, progress) = super::campaign_pool(args.threads, args.trials, "picks")?;
    let started = std::time::Instant::now();
    if let Some(trial) = args.log_trials.iter().find(|&&k| k >= args.trials) {
        bail!(
            "--log-trials {trial} is not one of the {} trials",
            args.trials
        );
    }
    let logs = match (&args.log_dir, args.log_trials.is_empty()) {
        (Some(dir), false) => Some(TrialLogs {
            dir: dir.clone(),
            trials: args.log_trials.clone(),
        }),
        (None, false) => bail!("--log-trials needs --log-dir"),
        (_, true) => None,
    };
    let recording = TrialRecording {
        logs: logs.clone(),
        ml_limit: args.ml_limit,
    };
    let summaries = pool.install(|| {
        run_trials_recording(&experiment, args.trials, args.seed, &progress, &recording)
    });
    progress.finish_and_clear();
    let elapsed = started.elapsed().as_secs_f64();
    let mut report = montecarlo_table(&experiment.name, &summaries);
    report.push_str(&limit_table(&summaries));
    let _ = writeln!(
        report,
        "\n{} picks in {elapsed:.1} s on {} threads (seed {}); every trial's seed is in trials.csv.",
        summaries.len(),
        pool.current_num_threads(),
        args.seed
    );
    fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    fs::write(args.out.join("report.md"), &report).context("writing report.md")?;
    write_trials_csv(&args.out.join("trials.csv"), &summaries)?;
    let json = serde_json::to_string_pretty(&summaries).context("summary.json")?;
    fs::write(args.out.join("summary.json"), json).context("writing summary.json")?;
    println!("{report}");
    println!("(written to {})", args.out.display());
    if let Some(logs) = &logs {
        println!(
            "(observation logs of trials {:?} in {})",
            logs.trials,
            logs.dir.display()
        );
    }
    Ok(())
}
