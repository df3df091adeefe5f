//! `host-sim`: the simulated workcell and the tools around the controller.
//!
//! Without a subcommand it runs the paper's experiments and the moving pick on
//! the embedded default scenario (see [`host_sim::pick::command`]).
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use host_sim::accuracy::command::{run_accuracy, AccuracyArgs};
use host_sim::calibrate_cmd::{run_calibrate, CalibrateArgs};
use host_sim::demo::{run_demo, DemoArgs};
use host_sim::link;
use host_sim::pick::command::{run_pick_command, PickArgs};
use host_sim::pick::faults::{run_fault_campaign, FaultCampaignArgs};
use host_sim::pick::montecarlo::{run_montecarlo, MonteCarloArgs};
use host_sim::workcell::command::{run_record, RecordArgs};

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
    Run(PickArgs),
    /// Seeded Monte Carlo of the pick over random workcells: success rate and error percentiles.
    Montecarlo(MonteCarloArgs),
    /// Seeded faulty picks (vision, encoder, conveyor, link and stall faults):
    /// the table of fault against outcome, and every safety invariant checked.
    Faults(FaultCampaignArgs),
    /// Self-calibration alone on one recorded workcell, against the paper's figures.
    CalibrationDemo(DemoArgs),
    /// Record a synthetic observation log (and LOG.truth.json) from a random workcell.
    Record(RecordArgs),
    /// Calibrate from a log: result JSON on stdout, summary (and errors with --truth) on stderr.
    Calibrate(CalibrateArgs),
    /// Seeded Monte-Carlo accuracy over random workcells: markdown on stdout, CSV/JSON in --out.
    Accuracy(AccuracyArgs),
    /// Handshake with the controller, exchange frames and check every reply.
    LinkCheck(link::cli::LinkCheckArgs),
    /// One pick with the plant running free on the host's clock against the
    /// emulated board built with `free-run` (see scripts/qemu-free-run).
    FreeRun(host_sim::pick::free_run::FreeRunArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let outcome = match &cli.command {
        None => run_pick_command(&PickArgs::default()),
        Some(Command::Run(args)) => run_pick_command(args),
        Some(Command::Montecarlo(args)) => run_montecarlo(args),
        Some(Command::Faults(args)) => run_fault_campaign(args),
        Some(Command::CalibrationDemo(args)) => run_demo(args),
        Some(Command::Record(args)) => run_record(args),
        Some(Command::Calibrate(args)) => run_calibrate(args),
        Some(Command::Accuracy(args)) => run_accuracy(args),
        Some(Command::FreeRun(args)) => host_sim::pick::free_run::run_free_command(args),
        Some(Command::LinkCheck(args)) => {
            link::cli::run(args).map_err(|e| anyhow::anyhow!("link-check failed: {e}"))
        }
    };
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error:#}");
            ExitCode::FAILURE
        }
    }
}
