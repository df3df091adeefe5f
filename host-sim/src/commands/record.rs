//! `host-sim record`: write a synthetic log and its truth file.

use std::path::PathBuf;

use anyhow::Context;

use crate::log::write_log_file;
use crate::recording::{simulate, truth_path_for, write_truth_file};
use crate::scenario::recording::{Scenario, SCENARIO_NAMES};

/// Record a synthetic observation log from a random workcell (plus LOG.truth.json beside it).
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scenario name: noise-free, paper, noisy, quarter-turn, non-planar, reverse or near-axis.
    #[arg(long, default_value = "paper")]
    pub scenario: String,
    /// Seed of the random workcell and noise (same seed, same log).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Show the end effector in exactly this many frames (default: the scenario's range);
    /// reproduces the `paper/effector-N` trials of `accuracy`.
    #[arg(long)]
    pub effector_frames: Option<usize>,
    /// Record this many frames over the scenario's conveyor travel instead of its
    /// own count (the paper scenario: 300 a revolution at 30 Hz; 1800 make a 60 s
    /// log); reproduces the `paper/frames-N` trials of `accuracy`.
    #[arg(long)]
    pub frames: Option<usize>,
    /// Where to write the log (JSON Lines); the truth goes to the same name with `.truth.json`.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let scenario = Scenario::named(&args.scenario)
        .with_context(|| format!("choose one of {}", SCENARIO_NAMES.join(", ")))?;
    let scenario = match args.effector_frames {
        Some(count) => scenario.with_effector_frames(count),
        None => scenario,
    };
    let scenario = match args.frames {
        Some(0) => anyhow::bail!("--frames must be at least 1"),
        Some(count) => scenario.with_frames(count),
        None => scenario,
    };
    let run = simulate(&scenario, args.seed)?;
    write_log_file(&args.output, &run.log)?;
    let truth_path = truth_path_for(&args.output);
    write_truth_file(&truth_path, &run.truth)?;
    let quality = &run.truth.result.quality;
    eprintln!(
        "recorded {} frames ({} with detections, {} showing the end effector, {} outliers) of scenario {} seed {} to {}; truth in {}",
        run.log.frames.len(),
        quality.frames_used,
        quality.effector_frames_used,
        quality.outliers_rejected,
        scenario.name,
        args.seed,
        args.output.display(),
        truth_path.display()
    );
    Ok(())
}
