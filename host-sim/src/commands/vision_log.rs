//! `host-sim vision-log`: the offline vision front end. Reads a camera
//! recording, detects and labels each frame's marks and writes the
//! observation log that `host-sim calibrate` reads; with `--score`, compares
//! the labels with the recording's `truth.jsonl` (a simulated recording's;
//! the front end itself never reads it); with `--pictures`, draws what it
//! saw ([`crate::front_end::pictures`]).

use std::path::PathBuf;

use anyhow::{Context, Result};

use crate::camera_recording::simulate::read_truth;
use crate::camera_recording::Recording;
use crate::front_end::pictures::{describe, write_pictures, PictureOptions};
use crate::front_end::run as run_front_end;
use crate::front_end::score::{score, Judge};
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
    /// Score the labels against the recording's truth.jsonl (simulated
    /// recordings); with `--pictures`, wrong labels are boxed in red.
    #[arg(long)]
    pub score: bool,
    /// Write pictures of a stretch of frames with their blobs and labels
    /// into this folder (PNG each, and labels.gif).
    #[arg(long)]
    pub pictures: Option<PathBuf>,
    /// Frames in the pictures' stretch (25: 5 s at 5 Hz).
    #[arg(long, default_value_t = 25, requires = "pictures")]
    pub picture_frames: usize,
    /// The stretch's first frame (from 0, of the frames read); default: the
    /// stretch with the most wrong labels (with --score), then the most labels.
    #[arg(long, requires = "pictures")]
    pub first_frame: Option<usize>,
    /// Enlargement of the pictures.
    #[arg(long, default_value_t = 3, requires = "pictures")]
    pub picture_scale: usize,
    /// Write the PNGs with the animation's palette (32 greys and the
    /// labels' colours): a fifth of the size, for pages.
    #[arg(long, requires = "pictures")]
    pub indexed_pictures: bool,
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
    let truth = if args.score {
        let truth = read_truth(&args.recording)?;
        let tally = score(&outcome.frames, &truth);
        eprintln!("{}", serde_json::to_string_pretty(&tally)?);
        Some(truth)
    } else {
        None
    };
    if let Some(folder) = &args.pictures {
        let judge = truth.as_deref().map(|t| Judge::new(&outcome.frames, t));
        let options = PictureOptions {
            folder: folder.clone(),
            frames: args.picture_frames.max(1),
            first_frame: args.first_frame,
            scale: args.picture_scale.clamp(1, 8),
            indexed: args.indexed_pictures,
        };
        let written = write_pictures(&recording, &outcome, judge.as_ref(), &options)?;
        eprintln!("{}", describe(&written, folder));
    }
    Ok(())
}
