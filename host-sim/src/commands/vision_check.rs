//! `host-sim vision-check`: the mark detector on rendered camera frames of
//! seeded picks, against the truth (see [`crate::vision_check`]): centroid
//! errors without and with noise, missed and spurious detections, the
//! perspective bias, the time per frame; with `--out`, the report, its JSON
//! and pictures of the frames with their detections.

use std::path::PathBuf;

use anyhow::{Context, Result};
use rayon::prelude::*;

use crate::vision_check::pictures::write_pictures;
use crate::vision_check::report::{markdown, summarise};
use crate::vision_check::{run_trial, trial_seed, CheckOptions, Tally};

/// Options of `host-sim vision-check`.
#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// Number of random workcells (one pick each).
    #[arg(long, default_value_t = 20)]
    pub trials: usize,
    /// Base seed: trial k runs the world seeded with `seed * 1_000_000 + k`
    /// (the same workcells as `host-sim montecarlo --seed`).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Which experiment of the scenario file to run.
    #[arg(long, default_value = "turning")]
    pub experiment: String,
    /// Scenario file (TOML); the embedded default when absent.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Render every n-th triggered frame (1: all).
    #[arg(long, default_value_t = 1)]
    pub frame_stride: usize,
    /// Render every n-th rendered frame again without motion and noise, for
    /// the perspective bias (0: never).
    #[arg(long, default_value_t = 4)]
    pub still_every: usize,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Folder for report.md, summary.json and the pictures of trial 0.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Frames in the picture sequence (5 per second at the default trigger rate).
    #[arg(long, default_value_t = 20)]
    pub sequence_frames: usize,
}

pub fn run(args: &Args) -> Result<()> {
    let experiment = super::load_experiment(args.scenario.as_deref(), &args.experiment)?;
    let (pool, progress) = super::campaign_pool(args.threads, args.trials, "picks")?;
    let started = std::time::Instant::now();
    let tallies: Vec<Result<Tally>> = pool.install(|| {
        (0..args.trials)
            .into_par_iter()
            .map(|trial| {
                let options = CheckOptions {
                    frame_stride: args.frame_stride.max(1),
                    still_every: args.still_every,
                    keep_frames: trial == 0 && args.out.is_some(),
                };
                let tally = run_trial(&experiment, trial_seed(args.seed, trial), &options);
                progress.inc(1);
                tally
            })
            .collect()
    });
    progress.finish_and_clear();
    let mut total = Tally::default();
    for tally in tallies {
        total.merge(tally?);
    }
    let elapsed = started.elapsed().as_secs_f64();
    let summary = summarise(&experiment.name, args.seed, &total);
    let mut report = markdown(&summary);
    report.push_str(&format!(
        "{} trials in {elapsed:.1} s (picks, rendering and detection)\n",
        args.trials
    ));
    print!("{report}");
    if let Some(out) = &args.out {
        std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
        std::fs::write(out.join("report.md"), &report)?;
        std::fs::write(
            out.join("summary.json"),
            serde_json::to_string_pretty(&summary)?,
        )?;
        let written = write_pictures(&total.kept, &out.join("frames"), args.sequence_frames)?;
        eprintln!(
            "wrote report.md, summary.json and {} pictures to {}",
            written.len(),
            out.display()
        );
    }
    Ok(())
}
