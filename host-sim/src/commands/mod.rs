//! The `host-sim` subcommands, one file each named like the subcommand, each
//! with its options (`Args`) and `run`. The work they do is in the domain
//! modules ([`crate::pick`], [`crate::recording`], [`crate::calibration`],
//! [`crate::accuracy`], [`crate::link`]).
//!
//! - [`run`]: `host-sim run` (and `host-sim` alone): the experiments and the moving pick.
//! - [`montecarlo`]: `host-sim montecarlo`: seeded picks over random workcells.
//! - [`faults`]: `host-sim faults`: the pick under injected faults.
//! - [`calibration_demo`]: `host-sim calibration-demo`: self-calibration alone.
//! - [`record`]: `host-sim record`: a synthetic log and its truth file.
//! - [`calibrate`]: `host-sim calibrate`: calibration of a log.
//! - [`accuracy`]: `host-sim accuracy`: Monte-Carlo accuracy of the self-calibration.
//! - [`link_check`]: `host-sim link-check`: handshake and checked exchange with the controller.
//! - [`homing`]: `host-sim homing`: seeded power-ons homed and scored against the drawn offsets.
//! - [`free_run`]: `host-sim free-run`: one pick with the plant running free against the emulated board.
//! - [`vision_campaign`]: `host-sim vision-campaign`: the vision front end over many rendered picks, scored.
//! - [`vision_check`]: `host-sim vision-check`: the mark detector on rendered frames against the truth.

pub mod accuracy;
pub mod calibrate;
pub mod calibration_demo;
pub mod faults;
pub mod free_run;
pub mod homing;
pub mod link_check;
pub mod montecarlo;
pub mod record;
pub mod record_images;
pub mod run;
pub mod vision_campaign;
pub mod vision_check;
pub mod vision_live;
pub mod vision_log;

/// The experiment `name` of the scenario file at `scenario` (the embedded
/// default when absent): what every campaign subcommand starts from.
pub(crate) fn load_experiment(
    scenario: Option<&std::path::Path>,
    name: &str,
) -> anyhow::Result<crate::scenario::pick::PickExperiment> {
    use crate::scenario::pick::PickScenarioFile;
    let file = match scenario {
        Some(path) => PickScenarioFile::from_path(path)?,
        None => PickScenarioFile::embedded_default()?,
    };
    Ok(file.experiment(name)?.clone())
}

/// A thread pool of `threads` (all cores when `None`) and a progress bar
/// over `trials` items named `what`, for the campaign subcommands.
pub(crate) fn campaign_pool(
    threads: Option<usize>,
    trials: usize,
    what: &str,
) -> anyhow::Result<(rayon::ThreadPool, indicatif::ProgressBar)> {
    use anyhow::Context;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.unwrap_or(0))
        .build()
        .context("thread pool")?;
    let progress = indicatif::ProgressBar::new(trials as u64);
    progress.set_style(
        indicatif::ProgressStyle::with_template(&format!(
            "{{bar:40}} {{pos}}/{{len}} {what}, {{elapsed}} elapsed, eta {{eta}}"
        ))
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    Ok((pool, progress))
}
