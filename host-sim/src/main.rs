//! `host-sim`: the simulated workcell and the tools around the controller.
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use host_sim::accuracy::command::{run_accuracy, AccuracyArgs};
use host_sim::calibrate_cmd::{run_calibrate, CalibrateArgs};
use host_sim::workcell::command::{run_record, RecordArgs};

/// Simulated self-calibrating workcell (PUMA 560, disc conveyor, one camera).
#[derive(Parser, Debug)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Record a synthetic observation log (and LOG.truth.json) from a random workcell.
    Record(RecordArgs),
    /// Calibrate from a log: result JSON on stdout, summary (and errors with --truth) on stderr.
    Calibrate(CalibrateArgs),
    /// Seeded Monte-Carlo accuracy over random workcells: markdown on stdout, CSV/JSON in --out.
    Accuracy(AccuracyArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let outcome = match &cli.command {
        Command::Record(args) => run_record(args),
        Command::Calibrate(args) => run_calibrate(args),
        Command::Accuracy(args) => run_accuracy(args),
    };
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error:#}");
            ExitCode::FAILURE
        }
    }
}
