//! `host-sim run` (and `host-sim` alone): the paper's experiments and the moving
//! pick, end to end, with the results table on the terminal and plots plus CSV
//! in an output folder.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};

use crate::link::{
    BoardTiming, ByteLink, FramedLink, InProcessLink, NoiseConfig, NoisyLink, SerialPortLink,
    TcpLink,
};
use crate::pick::outputs::write_run_outputs;
use crate::pick::own_log::{
    in_process_board, run_pick_logged_watched, write_pick_log, InProcessOptions, PickLogFiles,
};
use crate::pick::record::PickRun;
use crate::pick::report::{link_line, results_table, summary_line};
use crate::pick::runner::run_pick_watched;
use crate::pick::watch::{NoWatcher, PickWatcher};
use crate::scenario::pick::{CameraSource, PickExperiment, PickScenarioFile};

/// Options of the default run.
#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// Scenario file (TOML); the embedded default when absent (see --print-scenario).
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Experiments to run (comma-separated names); all of the file's by default.
    #[arg(long, value_delimiter = ',')]
    pub experiment: Vec<String>,
    /// Seed of the random workcell (camera, disc, part and robot base poses, noise).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Folder for the plots (PNG) and time series (CSV), one subfolder per experiment.
    #[arg(long, default_value = "pick-out")]
    pub out: PathBuf,
    /// Skip the plots and CSV files.
    #[arg(long)]
    pub no_plots: bool,
    /// The controller: `in-process` (default), `in-process:stm32f407` (the
    /// same with each job's result as late as a 168 MHz Cortex-M4F would
    /// deliver it), `tcp:HOST:PORT` (the emulated firmware's UART) or
    /// `serial:PATH[@BAUD]` (a board built for lock step).
    #[arg(long, default_value = "in-process")]
    pub link: String,
    /// Damage this fraction of the link's bytes, both ways (flip a bit, drop
    /// the byte or insert one; e.g. 1e-3): lost frames are sent again, and the
    /// run's link figures are printed.
    #[arg(long, default_value_t = 0.0, value_parser = parse_rate)]
    pub link_noise: f64,
    /// Seed of the link noise.
    #[arg(long, default_value_t = 1)]
    pub link_noise_seed: u64,
    /// Print the embedded default scenario file and exit.
    #[arg(long)]
    pub print_scenario: bool,
    /// Write the pick's own observation log (what the controller's
    /// calibrator was fed), its truth and the controller's final estimate to
    /// DIR/<experiment>/ (in-process links only).
    #[arg(long)]
    pub log_dir: Option<PathBuf>,
    /// What the controller's camera frames are made from: `images` renders
    /// each frame and labels it with the project's detector and identifier
    /// (the scenario's `camera.source` when absent).
    #[arg(long, value_enum)]
    pub camera_source: Option<CameraSource>,
    /// Write a Rerun recording of each experiment's pick (the 3-D cell, the
    /// camera's frames with their labels, the estimate against the truth)
    /// to this file (`FILE-<experiment>.rrd` when several run); open it
    /// with `rerun FILE.rrd`.
    #[cfg(feature = "rerun")]
    #[arg(long, value_name = "FILE.rrd")]
    pub rerun: Option<PathBuf>,
}

fn parse_rate(text: &str) -> Result<f64, String> {
    let rate: f64 = text.parse().map_err(|e| format!("not a number: {e}"))?;
    if (0.0..=0.5).contains(&rate) {
        Ok(rate)
    } else {
        Err(format!("{rate} is not a byte error rate in [0, 0.5]"))
    }
}

impl Default for Args {
    fn default() -> Self {
        Self {
            scenario: None,
            experiment: Vec::new(),
            seed: 1,
            out: PathBuf::from("pick-out"),
            no_plots: false,
            link: "in-process".to_string(),
            link_noise: 0.0,
            link_noise_seed: 1,
            print_scenario: false,
            log_dir: None,
            camera_source: None,
            #[cfg(feature = "rerun")]
            rerun: None,
        }
    }
}

/// The pick against the in-process controller, its own log written to
/// `dir`/<experiment>.
fn run_logged(
    experiment: &PickExperiment,
    seed: u64,
    args: &Args,
    dir: &Path,
    watcher: &mut dyn PickWatcher,
) -> Result<(PickRun, PickLogFiles)> {
    let Some(board) = in_process_board(&args.link) else {
        bail!(
            "--log-dir needs an in-process controller (--link in-process or in-process:stm32f407), not {}",
            args.link
        );
    };
    let noise = (args.link_noise > 0.0).then_some(NoiseConfig {
        byte_error_rate: args.link_noise,
        seed: args.link_noise_seed,
    });
    let logged =
        run_pick_logged_watched(experiment, seed, InProcessOptions { board, noise }, watcher)?;
    let files = write_pick_log(&dir.join(&experiment.name), &logged)?;
    Ok((logged.run, files))
}

/// The terminal's line about a pick's own log.
pub fn log_line(files: &PickLogFiles) -> String {
    match &files.controller_estimate {
        Some(estimate) => format!(
            "observation log: {} ({} frames), truth {}, controller estimate {}{}",
            files.observations.display(),
            files.frames,
            files.truth.display(),
            estimate.display(),
            match files.matches_controller {
                Some(true) => "",
                Some(false) => " (WARNING: differs from the controller's own)",
                None => " (refused by the controller)",
            }
        ),
        None => format!(
            "observation log: {} ({} frames), truth {}; no final estimate to write",
            files.observations.display(),
            files.frames,
            files.truth.display()
        ),
    }
}

fn run_on_link(
    experiment: &PickExperiment,
    seed: u64,
    args: &Args,
    watcher: &mut dyn PickWatcher,
) -> Result<PickRun> {
    fn go<L: ByteLink>(
        experiment: &PickExperiment,
        seed: u64,
        link: L,
        args: &Args,
        watcher: &mut dyn PickWatcher,
    ) -> Result<PickRun> {
        if args.link_noise > 0.0 {
            let noise = NoiseConfig {
                byte_error_rate: args.link_noise,
                seed: args.link_noise_seed,
            };
            run_pick_watched(
                experiment,
                seed,
                &mut FramedLink::new(NoisyLink::new(link, noise)),
                watcher,
            )
        } else {
            run_pick_watched(experiment, seed, &mut FramedLink::new(link), watcher)
        }
    }
    let link = args.link.as_str();
    if link == "in-process" {
        go(experiment, seed, InProcessLink::new(), args, watcher)
    } else if link == "in-process:stm32f407" {
        let board = InProcessLink::with_board_timing(BoardTiming::stm32f407());
        go(experiment, seed, board, args, watcher)
    } else if let Some(addr) = link.strip_prefix("tcp:") {
        go(
            experiment,
            seed,
            TcpLink::connect(addr, Duration::from_secs(5))?,
            args,
            watcher,
        )
    } else if let Some(spec) = link.strip_prefix("serial:") {
        let (path, baud) = match spec.split_once('@') {
            Some((path, baud)) => (
                path,
                baud.parse()
                    .with_context(|| format!("serial baud rate {baud:?} in --link {link}"))?,
            ),
            None => (spec, 115_200),
        };
        go(
            experiment,
            seed,
            SerialPortLink::open(path, baud)?,
            args,
            watcher,
        )
    } else {
        bail!(
            "unknown --link {link}: use in-process, in-process:stm32f407, tcp:HOST:PORT or serial:PATH[@BAUD]"
        )
    }
}

/// The experiments the arguments select, in the file's order.
fn selected(file: &PickScenarioFile, names: &[String]) -> Result<Vec<PickExperiment>> {
    if names.is_empty() {
        return Ok(file.experiment.clone());
    }
    names
        .iter()
        .map(|name| file.experiment(name).cloned())
        .collect()
}

pub fn run(args: &Args) -> Result<()> {
    if args.print_scenario {
        print!(
            "{}",
            PickScenarioFile::embedded_default()?.to_toml_string()?
        );
        return Ok(());
    }
    let file = match &args.scenario {
        Some(path) => PickScenarioFile::from_path(path)?,
        None => PickScenarioFile::embedded_default()?,
    };
    let mut experiments = selected(&file, &args.experiment)?;
    if let Some(source) = args.camera_source {
        for experiment in &mut experiments {
            experiment.camera.source = source;
        }
    }
    println!(
        "Simulated workcell (seed {}): PUMA 560, 0.9 m disc, one 256x256 camera; camera, disc and robot base poses unknown to the controller.\n\
         Controller: {} link; the world runs in lock step at the controller's rate.\n",
        args.seed, args.link
    );
    let mut runs = Vec::new();
    for experiment in &experiments {
        let started = Instant::now();
        #[cfg(feature = "rerun")]
        let mut view = match &args.rerun {
            Some(path) => Some(crate::rerun_view::RerunView::create(
                &crate::rerun_view::recording_path(path, &experiment.name, experiments.len()),
                experiment,
                args.seed,
            )?),
            None => None,
        };
        #[cfg(feature = "rerun")]
        let watcher: &mut dyn PickWatcher = match view.as_mut() {
            Some(view) => view,
            None => &mut NoWatcher,
        };
        #[cfg(not(feature = "rerun"))]
        let watcher = &mut NoWatcher;
        let (run, log_files) = match &args.log_dir {
            Some(dir) => {
                let (run, files) = run_logged(experiment, args.seed, args, dir, watcher)
                    .with_context(|| format!("experiment {}", experiment.name))?;
                (run, Some(files))
            }
            None => (
                run_on_link(experiment, args.seed, args, watcher)
                    .with_context(|| format!("experiment {}", experiment.name))?,
                None,
            ),
        };
        println!(
            "{}  [{:.1} s simulated in {:.1} s]",
            summary_line(&run),
            run.duration_s,
            started.elapsed().as_secs_f64()
        );
        if let Some(line) = link_line(&run) {
            println!("  {line}");
        }
        if let Some(files) = &log_files {
            println!("  {}", log_line(files));
        }
        #[cfg(feature = "rerun")]
        if let Some(view) = view {
            let (path, bytes) = view.finish()?;
            println!(
                "  Rerun recording: {} ({:.1} MB; open with `rerun {}`)",
                path.display(),
                bytes as f64 * 1e-6,
                path.display()
            );
        }
        if !args.no_plots {
            let written = write_run_outputs(&run, &args.out)
                .with_context(|| format!("writing outputs of {}", experiment.name))?;
            if let Some(first) = written.first() {
                let folder = first.parent().map_or(args.out.clone(), PathBuf::from);
                println!(
                    "  plots and CSV: {} ({} files)",
                    folder.display(),
                    written.len()
                );
            }
        }
        runs.push(run);
    }
    println!("\n{}", results_table(&runs));
    Ok(())
}
