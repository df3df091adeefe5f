//! `host-sim vision-log`: the offline vision front end. Reads a camera
//! recording, detects and labels each frame's marks and writes the
//! observation log that `host-sim calibrate` reads; with `--score`, compares
//! the labels with the recording's `truth.jsonl` (a simulated recording's;
//! the front end itself never reads it).

use std::path::PathBuf;

use anyhow::{Context, Result};

use crate::camera_recording::simulate::read_truth;
use crate::camera_recording::Recording;
use crate::front_end::{run as run_front_end, score::score};
use crate::log::write_log_file;

/// Options of `host-sim vision-log`.
#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// The recording's folder (recording.json, frames.csv, the PNG frames).
    #[arg(long)]
    pub recording: PathBuf,
    /// The observation log to write (JSON Lines).
    #[arg(long)]
    pub out: PathBuf,
    /// Skip frames whose image is missing, undecodable or of the wrong size
    /// (counted) instead of stopping at the first.
    #[arg(long)]
    pub skip_bad_frames: bool,
    /// Score the labels against the recording's truth.jsonl (simulated recordings).
    #[arg(long)]
    pub score: bool,
}

pub fn run(args: &Args) -> Result<()> {
    let recording = Recording::open(&args.recording)
        .with_context(|| format!("recording {}", args.recording.display()))?;
    let outcome = run_front_end(&recording, args.skip_bad_frames)
        .with_context(|| format!("recording {}", args.recording.display()))?;
    write_log_file(&args.out, &outcome.log)?;
    let log = &outcome.log;
    let count = |f: &dyn Fn(&shared::observation::ObservationFrame) -> bool| {
        log.frames.iter().filter(|x| f(x)).count()
    };
    eprintln!(
        "{} frames ({} skipped, {} refused by the detector): centre in {}, reference in {}, \
         the whole part in {}, both effector marks in {}; {} ambiguous blobs left unlabelled",
        log.frames.len(),
        outcome.skipped_images,
        outcome.refused_frames,
        count(&|f| f.center_px.is_some()),
        count(&|f| f.reference_px.is_some()),
        count(&|f| f.part_px.is_some()),
        count(&|f| f.effector.is_some()),
        outcome.ambiguous,
    );
    if args.score {
        let truth = read_truth(&args.recording)?;
        let tally = score(&outcome.frames, &truth);
        eprintln!("{}", serde_json::to_string_pretty(&tally)?);
    }
    Ok(())
}
