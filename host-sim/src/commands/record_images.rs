//! `host-sim record-images`: the pick of one seeded workcell rendered and
//! written as a camera recording (docs/reference/recording.md), with
//! `truth.jsonl` and the ideal labelled log `ideal.jsonl` beside it for
//! scoring (see [`crate::camera_recording::simulate`]).

use std::path::PathBuf;

use anyhow::Result;

use crate::camera_recording::simulate::record_pick;
use crate::vision_check::trial_seed;

/// Options of `host-sim record-images`.
#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// Base seed: the workcell of trial `--trial` (as `host-sim vision-check`).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Which trial of the seed.
    #[arg(long, default_value_t = 0)]
    pub trial: usize,
    /// Frames to record at most.
    #[arg(long, default_value_t = 300)]
    pub frames: usize,
    /// Record every n-th triggered frame.
    #[arg(long, default_value_t = 1)]
    pub stride: usize,
    /// Which experiment of the scenario file to run.
    #[arg(long, default_value = "turning")]
    pub experiment: String,
    /// Scenario file (TOML); the embedded default when absent.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Bright distractor objects on the disc (overrides the scenario's `image.distractors`).
    #[arg(long)]
    pub distractors: Option<usize>,
    /// The recording's folder.
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(args: &Args) -> Result<()> {
    let mut experiment = super::load_experiment(args.scenario.as_deref(), &args.experiment)?;
    if let Some(n) = args.distractors {
        experiment.image.distractors = n;
        experiment.image.validate()?;
    }
    let seed = trial_seed(args.seed, args.trial);
    let recorded = record_pick(
        &experiment,
        seed,
        &args.out,
        args.frames,
        args.stride.max(1),
    )?;
    eprintln!(
        "{} frames of the {} pick (seed {seed}) in {}",
        recorded.frames,
        experiment.name,
        args.out.display()
    );
    Ok(())
}
