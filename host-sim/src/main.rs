//! `host-sim`: the simulated workcell and the tools around the controller.
//!
//! Without a subcommand it runs the paper's experiments and the moving pick on
//! the embedded default scenario (see [`host_sim::commands::run`]).
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use host_sim::commands::{
    accuracy, calibrate, calibration_demo, faults, free_run, homing, link_check, montecarlo,
    record, record_images, run, vision_campaign, vision_check, vision_live, vision_log,
};

/// Simulated self-calibrating workcell (PUMA 560, disc conveyor, one camera).
#[derive(Parser, Debug)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// The paper's experiments and the moving pick, end to end (also what `host-sim`
    /// without a subcommand does): results table, plots and CSV.
    Run(run::Args),
    /// Seeded Monte Carlo of the pick over random workcells: success rate and error percentiles.
    Montecarlo(montecarlo::Args),
    /// Seeded faulty picks (vision, encoder, conveyor, link and stall faults):
    /// the table of fault against outcome, and every safety invariant checked.
    Faults(faults::Args),
    /// Seeded power-ons homed (potentiometers, index pulses) and scored
    /// against the drawn counter offsets.
    Homing(homing::Args),
    /// Self-calibration alone on one recorded workcell, against the paper's figures.
    CalibrationDemo(calibration_demo::Args),
    /// Record a synthetic observation log (and LOG.truth.json) from a random workcell.
    Record(record::Args),
    /// Calibrate from a log: result JSON on stdout, summary (and errors with --truth) on stderr.
    Calibrate(calibrate::Args),
    /// Seeded Monte-Carlo accuracy over random workcells: markdown on stdout, CSV/JSON in --out.
    Accuracy(accuracy::Args),
    /// Handshake with the controller, exchange frames and check every reply.
    LinkCheck(link_check::Args),
    /// One pick with the plant running free on the host's clock against the
    /// emulated board built with `free-run` (see scripts/qemu-free-run).
    FreeRun(free_run::Args),
    /// The mark detector on rendered camera frames of seeded picks, against the truth:
    /// centroid errors, missed and spurious marks, perspective bias, pictures with --out.
    VisionCheck(vision_check::Args),
    /// Render the pick of one seeded workcell as a camera recording (PNG frames,
    /// frames.csv, recording.json) with its truth and ideal log beside it.
    RecordImages(record_images::Args),
    /// The vision front end: a camera recording in, the observation log out
    /// (detection, identification, undistortion); --score against its truth.
    VisionLog(vision_log::Args),
    /// Grab frames from a V4L2 camera into a recording folder (built with the
    /// `v4l2` feature); with --latches (the encoder values) a complete recording.
    VisionLive(vision_live::Args),
    /// The vision front end over many seeded picks rendered in memory, in parallel:
    /// mislabels, labels against visible marks, calibration against the ideal logs.
    VisionCampaign(vision_campaign::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let outcome = match &cli.command {
        None => run::run(&run::Args::default()),
        Some(Command::Run(args)) => run::run(args),
        Some(Command::Montecarlo(args)) => montecarlo::run(args),
        Some(Command::Faults(args)) => faults::run(args),
        Some(Command::Homing(args)) => homing::run(args),
        Some(Command::CalibrationDemo(args)) => calibration_demo::run(args),
        Some(Command::Record(args)) => record::run(args),
        Some(Command::Calibrate(args)) => calibrate::run(args),
        Some(Command::Accuracy(args)) => accuracy::run(args),
        Some(Command::LinkCheck(args)) => link_check::run(args),
        Some(Command::FreeRun(args)) => free_run::run(args),
        Some(Command::VisionCheck(args)) => vision_check::run(args),
        Some(Command::RecordImages(args)) => record_images::run(args),
        Some(Command::VisionLog(args)) => vision_log::run(args),
        Some(Command::VisionLive(args)) => vision_live::run(args),
        Some(Command::VisionCampaign(args)) => vision_campaign::run(args),
    };
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error:#}");
            ExitCode::FAILURE
        }
    }
}
