//! `host-sim`: the simulated workcell and the tools around the controller.
use clap::{Parser, Subcommand};
use host_sim::link;

/// Simulated self-calibrating workcell (PUMA 560, disc conveyor, one camera).
#[derive(Parser, Debug)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Handshake with the controller, exchange frames and check every reply.
    LinkCheck(link::cli::LinkCheckArgs),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::LinkCheck(args) => match link::cli::run(&args) {
            Ok(()) => std::process::ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("link-check failed: {e}");
                std::process::ExitCode::FAILURE
            }
        },
    }
}
