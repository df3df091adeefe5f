//! `host-sim free-run`: one pick with the plant running free on the host's
//! clock against the emulated board built with `free-run`
//! (`scripts/qemu-free-run` starts it; the work is in [`crate::pick::free_run`]).

use std::time::Duration;

use anyhow::{bail, Result};

use crate::link::FramedLink;
use crate::pick::free_run::{run_free, FreeRunSettings};
use crate::pick::record::PickResult;

/// `host-sim free-run`: one pick with the plant running free against the
/// emulated board built with `free-run` (`scripts/qemu-free-run` starts it).
#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// The emulated board's UART0 socket.
    #[arg(long, default_value = "127.0.0.1:4321")]
    pub tcp: String,
    /// The experiment of the embedded default scenario.
    #[arg(long, default_value = "experiment-2-7cm")]
    pub experiment: String,
    /// The world's seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Plant seconds per wall-clock second (1: real time).
    #[arg(long, default_value_t = 1.0)]
    pub time_scale: f64,
}

/// Runs `host-sim free-run`: prints the outcome and what crossed the link.
pub fn run(args: &Args) -> Result<()> {
    let experiment = crate::scenario::pick::PickScenarioFile::embedded_default()?
        .experiment(&args.experiment)?
        .clone();
    let tcp = crate::link::TcpLink::connect(&args.tcp, Duration::from_secs(10))?;
    let mut link = FramedLink::new(tcp);
    if !(args.time_scale > 0.0 && args.time_scale <= 1.0) {
        bail!(
            "--time-scale {} is out of range: it must be above 0 and at most 1",
            args.time_scale
        );
    }
    let settings = FreeRunSettings {
        time_scale: args.time_scale,
        ..FreeRunSettings::default()
    };
    let run = run_free(&experiment, args.seed, &mut link, &settings)?;
    println!(
        "{} seed {}: {:?} after {:.1} s of plant time, {:.1} s of wall time",
        args.experiment, args.seed, run.result, run.duration_s, run.wall_s
    );
    for phase in &run.phases {
        println!("  {:7.2} s  {:?}", phase.t_s, phase.phase);
    }
    if let Some(grasp) = &run.grasp {
        println!(
            "grasp: succeeded {}, error {:?} m, yaw error {:.4} rad",
            grasp.succeeded, grasp.position_error_m, grasp.yaw_error_rad
        );
    }
    println!("{:?}", run.counts);
    if let Some(runtime) = &run.runtime {
        println!("{runtime:?}");
    }
    if run.result != PickResult::Success {
        bail!("the pick did not succeed: {:?}", run.result);
    }
    Ok(())
}
