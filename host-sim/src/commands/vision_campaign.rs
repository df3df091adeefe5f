//! `host-sim vision-campaign`: the vision front end over many seeded picks
//! rendered in memory (no recording on disk), in parallel: mislabels,
//! labels right against marks visible, and how often the log from the
//! images calibrates against the ideal log of the same frames (see
//! [`crate::front_end::campaign`]).

use std::path::PathBuf;

use anyhow::Result;

use crate::front_end::campaign::{run_campaign, totals};

/// Options of `host-sim vision-campaign`.
#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// Base seed: trial K is the workcell `seed * 1_000_000 + K` (as `record-images`).
    #[arg(long, default_value_t = 4)]
    pub seed: u64,
    /// First trial.
    #[arg(long, default_value_t = 0)]
    pub first_trial: usize,
    /// Number of trials (picks).
    #[arg(long, default_value_t = 20)]
    pub trials: usize,
    /// Frames per pick at most.
    #[arg(long, default_value_t = 2000)]
    pub frames: usize,
    /// Bright distractor objects on the disc (overrides the scenario's `image.distractors`).
    #[arg(long)]
    pub distractors: Option<usize>,
    /// Which experiment of the scenario file to run.
    #[arg(long, default_value = "turning")]
    pub experiment: String,
    /// Scenario file (TOML); the embedded default when absent.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Also write every pick's outcome as JSON Lines here.
    #[arg(long)]
    pub picks_out: Option<PathBuf>,
}

pub fn run(args: &Args) -> Result<()> {
    let mut experiment = super::load_experiment(args.scenario.as_deref(), &args.experiment)?;
    if let Some(n) = args.distractors {
        experiment.image.distractors = n;
        experiment.image.validate()?;
    }
    let report = |outcome: &Result<crate::front_end::campaign::PickOutcome>| match outcome {
        Ok(o) => eprintln!(
            "trial {}: {} frames, {} labels, {} mislabelled, effector right {} of {} visible, \
             both marks in {} frames (ideal {}), calibrates {} (ideal {})",
            o.trial,
            o.frames,
            o.score.labels,
            o.score.mislabelled,
            o.score.right_by_class.get("effector").copied().unwrap_or(0),
            o.score.visible.get("effector").copied().unwrap_or(0),
            o.effector_frames,
            o.ideal_effector_frames,
            o.calibrates,
            o.ideal_calibrates
        ),
        Err(e) => eprintln!("a pick failed: {e:#}"),
    };
    let outcomes = run_campaign(
        &experiment,
        args.seed,
        args.first_trial,
        args.trials,
        args.frames,
        &report,
    );
    if let Some(path) = &args.picks_out {
        let mut text = String::new();
        for o in outcomes.iter().flatten() {
            text.push_str(&serde_json::to_string(o)?);
            text.push('\n');
        }
        std::fs::write(path, text)?;
    }
    let t = totals(&outcomes);
    let share = |class: &str| {
        format!(
            "{} / {}",
            t.right_by_class.get(class).copied().unwrap_or(0),
            t.visible.get(class).copied().unwrap_or(0)
        )
    };
    println!(
        "seed {}, trials {}..{}, {} distractors: {} picks ({} failed), {} frames, {} labels",
        args.seed,
        args.first_trial,
        args.first_trial + args.trials,
        experiment.image.distractors,
        t.picks,
        t.failed_picks,
        t.frames,
        t.labels
    );
    println!(
        "mislabelled {} (right mark, point displaced: {})",
        t.mislabelled, t.right_but_off
    );
    println!(
        "right / visible: disc centre {}, reference {}, part features {}, effector marks {}",
        share("disc_center"),
        share("reference"),
        share("part_feature"),
        share("effector")
    );
    println!(
        "frames with both effector marks: {} from the images, {} in the ideal logs",
        t.effector_frames, t.ideal_effector_frames
    );
    println!(
        "calibrates: the ideal log in {} picks, the image log in {} of them ({} more where the ideal does not)",
        t.ideal_calibrates, t.both_calibrate, t.only_images_calibrate
    );
    println!(
        "image against ideal calibration: camera height median {:.2} mm, worst {:.2} mm; \
         base translation median {:.2} mm, worst {:.2} mm; base yaw worst {:.3} deg",
        t.median_camera_height_m * 1e3,
        t.worst_camera_height_m * 1e3,
        t.median_base_translation_m * 1e3,
        t.worst_base_translation_m * 1e3,
        t.worst_base_yaw_rad.to_degrees()
    );
    for (trial, examples) in &t.mislabelled_picks {
        println!("mislabels in trial {trial}: {}", examples.join("; "));
    }
    Ok(())
}
