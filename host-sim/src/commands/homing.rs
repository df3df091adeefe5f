//! `host-sim homing`: seeded power-ons (counter offsets, potentiometer
//! biases, where the arm stands all drawn), each homed by the controller
//! linked into this process and scored against the drawn offsets: how many
//! joints came out exact, how long homing took, how fast and how far the
//! arm moved. See [`crate::homing`].

use std::fmt::Write as _;
use std::fs;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use rayon::prelude::*;

use crate::homing::{run_homing_trial, HomingTrial};

/// Options of `host-sim homing`.
#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// Number of power-ons.
    #[arg(long, default_value_t = 1000)]
    pub trials: u64,
    /// Base seed: trial k draws the world seeded with `seed * 1_000_000 + k`.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The experiment whose cell is powered on.
    #[arg(long, default_value = "experiment-1")]
    pub experiment: String,
    /// Scenario file (TOML); the embedded default when absent.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Where the arm stands at power-on: the ready posture with each joint
    /// moved within +-this, rad (overrides the scenario's).
    #[arg(long, default_value_t = 0.3)]
    pub spread_rad: f64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Folder for trials.csv (none when absent).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

fn summary(args: &Args, trials: &[HomingTrial]) -> String {
    let n = trials.len();
    let exact = trials.iter().filter(|t| t.exact()).count();
    let failed: Vec<&HomingTrial> = trials.iter().filter(|t| t.error.is_some()).collect();
    let worst = |f: &dyn Fn(&HomingTrial) -> f64| trials.iter().map(f).fold(0.0_f64, f64::max);
    let mean_s = trials.iter().map(|t| t.duration_s).sum::<f64>() / n.max(1) as f64;
    let mut text = String::new();
    let _ = writeln!(
        text,
        "{n} power-ons of {} (seed {}, arm within {} rad of ready): {exact} of {n} homed with every joint's offset exact to the count",
        args.experiment, args.seed, args.spread_rad
    );
    let _ = writeln!(
        text,
        "homing took {mean_s:.2} s on average, {:.2} s at most; fastest joint {:.3} rad/s; farthest from where it stood {:.3} rad; back to it within {:.4} rad",
        worst(&|t| t.duration_s),
        worst(&|t| t.max_joint_speed_rad_s),
        worst(&|t| t.max_excursion_rad),
        worst(&|t| t.end_offset_rad),
    );
    for t in failed.iter().take(10) {
        let _ = writeln!(
            text,
            "seed {}: {}",
            t.seed,
            t.error.as_deref().unwrap_or("")
        );
    }
    text
}

fn write_csv(trials: &[HomingTrial], path: &std::path::Path) -> Result<()> {
    let mut csv = String::from(
        "seed,exact,duration_s,max_joint_speed_rad_s,max_excursion_rad,end_offset_rad,error\n",
    );
    for t in trials {
        let _ = writeln!(
            csv,
            "{},{},{:.4},{:.5},{:.5},{:.6},{}",
            t.seed,
            t.exact(),
            t.duration_s,
            t.max_joint_speed_rad_s,
            t.max_excursion_rad,
            t.end_offset_rad,
            t.error.as_deref().unwrap_or("").replace(',', ";")
        );
    }
    fs::write(path, csv).with_context(|| format!("writing {}", path.display()))
}

pub fn run(args: &Args) -> Result<()> {
    let mut experiment = super::load_experiment(args.scenario.as_deref(), &args.experiment)?;
    if !(args.spread_rad.is_finite() && args.spread_rad >= 0.0) {
        bail!("--spread-rad must be a finite number >= 0");
    }
    experiment.robot.homing.power_on_spread_rad = args.spread_rad;
    let (pool, progress) = super::campaign_pool(args.threads, args.trials as usize, "power-ons")?;
    let trials: Vec<HomingTrial> = pool.install(|| {
        (0..args.trials)
            .into_par_iter()
            .map(|k| {
                let seed = args.seed.wrapping_mul(1_000_000).wrapping_add(k);
                let trial = run_homing_trial(&experiment, seed);
                progress.inc(1);
                trial
            })
            .collect::<Result<Vec<_>>>()
    })?;
    progress.finish_and_clear();
    print!("{}", summary(args, &trials));
    if let Some(out) = &args.out {
        fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
        write_csv(&trials, &out.join("trials.csv"))?;
        println!("(written to {})", out.display());
    }
    let exact = trials.iter().filter(|t| t.exact()).count();
    if exact != trials.len() {
        bail!(
            "{} of {} power-ons not homed exactly",
            trials.len() - exact,
            trials.len()
        );
    }
    Ok(())
}
