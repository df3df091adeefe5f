//! `host-sim`: the simulated workcell and the tools around the controller.
use clap::Parser;

/// Simulated self-calibrating workcell (PUMA 560, disc conveyor, one camera).
#[derive(Parser, Debug)]
#[command(version, about)]
struct Cli {}

fn main() {
    let _cli = Cli::parse();
}
