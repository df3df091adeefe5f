//! The pick's own observation log (`host-sim run --log-dir DIR`, and
//! `host-sim montecarlo --log-trials K,.. --log-dir DIR`): exactly the frames
//! the controller's worker pushed into its calibrator, in order, as the
//! contract's JSON Lines, so that any offline calibrator runs on the data the
//! controller saw. Beside it go the truth and the controller's final estimate:
//!
//! - `observations.jsonl`: the header the controller built its calibrator
//!   from (from the cell configuration it was told) and every frame;
//! - `observations.truth.json`: the drawn workcell ([`truth`]);
//! - `controller_estimate.json`: the final estimate job's result and how
//!   many of the log's frames it was made from ([`estimate_file`]).
//!
//! The frames are taken from the in-process link's [`WorkerTap`], so only
//! the in-process controller (with or without a board's timing) can be logged.

pub mod estimate_file;
pub mod truth;

use std::fs::{self, File};
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use shared::observation::CalibrationResult;

use self::estimate_file::{
    write_estimate_file, ControllerEstimateFile, EstimateProvenance, PICK_CALIBRATOR_NAME,
};
use self::truth::{pick_truth, PickTruthFile};
use super::record::PickRun;
use super::runner::run_pick_watched;
use super::watch::{Both, EachPeriod, NoWatcher, PickWatcher};
use crate::link::{BoardTiming, FramedLink, InProcessLink, NoiseConfig, NoisyLink, WorkerLog};
use crate::log::LogWriter;
use crate::recording::{truth_path_for, write_truth_file_of};
use crate::scenario::pick::PickExperiment;
use crate::world::conveyor::Conveyor;
use crate::world::workcell::Workcell;

/// The log's name in its folder.
pub const OBSERVATIONS_FILE: &str = "observations.jsonl";
/// The controller's estimate's name in its folder.
pub const CONTROLLER_ESTIMATE_FILE: &str = "controller_estimate.json";

/// A pick with what its worker was given and the world it ran in.
#[derive(Debug, Clone)]
pub struct LoggedPick {
    pub run: PickRun,
    /// The last configured session's worker.
    pub worker: WorkerLog,
    /// The drawn workcell (truth).
    pub workcell: Workcell,
    /// The world's disc angle at the pick's first sample (the log's angle
    /// 0), rad.
    pub disc_angle_at_start_rad: f64,
    /// The simulated camera's pixel noise, px.
    pub pixel_sigma_px: f64,
}

/// How the in-process controller is run.
#[derive(Debug, Clone, Copy, Default)]
pub struct InProcessOptions {
    /// Each job's result as late as this board would deliver it.
    pub board: Option<BoardTiming>,
    /// Bytes damaged on the link.
    pub noise: Option<NoiseConfig>,
}

/// One pick of `experiment` (seed `seed`) against the in-process
/// controller, recording what its worker was given.
pub fn run_pick_logged(
    experiment: &PickExperiment,
    seed: u64,
    options: InProcessOptions,
) -> Result<LoggedPick> {
    run_pick_logged_watched(experiment, seed, options, &mut NoWatcher)
}

/// [`run_pick_logged`], with `watcher` shown the run too.
pub fn run_pick_logged_watched(
    experiment: &PickExperiment,
    seed: u64,
    options: InProcessOptions,
    watcher: &mut dyn PickWatcher,
) -> Result<LoggedPick> {
    let link = match options.board {
        Some(timing) => InProcessLink::with_board_timing(timing),
        None => InProcessLink::new(),
    }
    .recording_worker();
    let mut world_seen: Option<(Workcell, f64)> = None;
    // The conveyor as the run left it (a stop commanded late changes no
    // earlier angle).
    let mut conveyor: Option<Conveyor> = None;
    let mut observe = |world: &crate::world::World, _: &shared::protocol::ActuatorCommand| {
        if world_seen.is_none() {
            world_seen = Some((
                world.workcell().clone(),
                world.experiment().camera.pixel_sigma_px,
            ));
        }
        conveyor = Some(world.conveyor().clone());
        Ok(())
    };
    let (run, tap) = match options.noise {
        Some(noise) => {
            let mut link = FramedLink::new(NoisyLink::new(link, noise));
            let mut both = Both(&mut EachPeriod(&mut observe), watcher);
            let run = run_pick_watched(experiment, seed, &mut link, &mut both)?;
            (run, link.inner_mut().inner_mut().take_worker_tap())
        }
        None => {
            let mut link = FramedLink::new(link);
            let mut both = Both(&mut EachPeriod(&mut observe), watcher);
            let run = run_pick_watched(experiment, seed, &mut link, &mut both)?;
            (run, link.inner_mut().take_worker_tap())
        }
    };
    let Some(worker) = tap.and_then(|mut tap| tap.take_log()) else {
        bail!("the controller was never configured: its worker was given nothing");
    };
    let (Some((workcell, pixel_sigma_px)), Some(conveyor)) = (world_seen, conveyor) else {
        bail!("the run ended before its first control period");
    };
    let disc_angle_at_start_rad = worker
        .pick_start_us
        .map_or(0.0, |us| conveyor.theta(us as f64 * 1e-6));
    Ok(LoggedPick {
        run,
        worker,
        workcell,
        disc_angle_at_start_rad,
        pixel_sigma_px,
    })
}

/// What [`write_pick_log`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct PickLogFiles {
    pub observations: PathBuf,
    pub truth: PathBuf,
    /// `None` when no final estimate job ran or its calibration failed.
    pub controller_estimate: Option<PathBuf>,
    /// Frames written.
    pub frames: usize,
    /// The controller's own estimate of the final job matched the one
    /// written in every field it carries (`None`: it refused it, or none).
    pub matches_controller: Option<bool>,
}

/// Writes the worker's frames as the contract's log; returns the indices
/// (into `worker.frames`) of the frames the writer refused.
fn write_observations(path: &Path, worker: &WorkerLog) -> Result<Vec<usize>> {
    let file = File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let mut writer = LogWriter::new(BufWriter::new(file), &worker.header)
        .with_context(|| format!("writing {}", path.display()))?;
    let mut refused = Vec::new();
    for (index, frame) in worker.frames.iter().enumerate() {
        if writer.write_frame(frame).is_err() {
            refused.push(index);
        }
    }
    writer
        .finish()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(refused)
}

/// The controller's final estimate with its provenance, if a final estimate
/// job ran and its calibration succeeded; `not_logged` are the frames the log
/// writer refused.
pub fn controller_estimate(
    logged: &LoggedPick,
    not_logged: &[usize],
) -> Option<ControllerEstimateFile> {
    let worker = &logged.worker;
    let job = worker.final_estimate()?;
    let (result, sigma) = job.twin.as_ref().ok()?;
    let before = |index: &usize| *index < job.frames_before;
    let outcome = match &job.outcome {
        Some(Ok(_)) => "accepted".to_string(),
        Some(Err(cause)) => format!("refused: {cause:?}"),
        None => "no result".to_string(),
    };
    Some(ControllerEstimateFile {
        result: result.clone(),
        uncertainty_1sigma: *sigma,
        controller: EstimateProvenance {
            experiment: logged.run.experiment.clone(),
            seed: logged.run.seed,
            calibrator: PICK_CALIBRATOR_NAME.to_string(),
            config: worker.config,
            log_frames: job.frames_before - not_logged.iter().filter(|i| before(i)).count(),
            frames_refused: worker
                .refused
                .iter()
                .filter(|i| before(i) && !not_logged.contains(i))
                .count(),
            adopted_after_frames: worker
                .adopted_after_frames
                .iter()
                .filter(|&&point| point < job.frames_before)
                .map(|&point| point - not_logged.iter().filter(|&&i| i < point).count())
                .collect(),
            frames_not_logged: not_logged.len(),
            time_us: job.time_us,
            outcome,
            matches_controller: job.matches_controller,
        },
    })
}

/// The truth of `logged`.
pub fn truth_of(logged: &LoggedPick) -> PickTruthFile {
    pick_truth(
        &logged.workcell,
        logged.disc_angle_at_start_rad,
        &logged.worker.frames,
        logged.pixel_sigma_px,
        &logged.run.experiment,
        logged.run.seed,
    )
}

/// Writes the pick's log, its truth and the controller's estimate into `dir`
/// (created).
pub fn write_pick_log(dir: &Path, logged: &LoggedPick) -> Result<PickLogFiles> {
    fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let observations = dir.join(OBSERVATIONS_FILE);
    let not_logged = write_observations(&observations, &logged.worker)?;
    let truth = truth_path_for(&observations);
    write_truth_file_of(&truth, &truth_of(logged))?;
    let estimate = controller_estimate(logged, &not_logged);
    let controller_estimate = match &estimate {
        Some(file) => {
            let path = dir.join(CONTROLLER_ESTIMATE_FILE);
            write_estimate_file(&path, file)?;
            Some(path)
        }
        None => None,
    };
    Ok(PickLogFiles {
        observations,
        truth,
        controller_estimate,
        frames: logged.worker.frames.len() - not_logged.len(),
        matches_controller: estimate.and_then(|file| file.controller.matches_controller),
    })
}

/// Largest difference, in metres, between two estimates' part position and
/// `base_from_disc` translation, and in radians between their part and base
/// yaws: how far a replay is from the controller's estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EstimateGap {
    pub part_position_m: f64,
    pub base_translation_m: f64,
    pub camera_position_m: f64,
    pub yaw_rad: f64,
}

fn largest_gap(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .fold(0.0_f64, |worst, (x, y)| worst.max((x - y).abs()))
}

impl EstimateGap {
    /// The gap between `a` and `b`, per axis.
    pub fn between(a: &CalibrationResult, b: &CalibrationResult) -> Self {
        let yaw =
            crate::geometry::angle_distance(a.base_from_disc.yaw_rad, b.base_from_disc.yaw_rad)
                .max(crate::geometry::angle_distance(
                    a.part.yaw_rad,
                    b.part.yaw_rad,
                ));
        Self {
            part_position_m: largest_gap(&a.part.position_m, &b.part.position_m),
            base_translation_m: largest_gap(
                &a.base_from_disc.translation_m,
                &b.base_from_disc.translation_m,
            ),
            camera_position_m: largest_gap(
                &a.camera.disc_from_camera.translation_m,
                &b.camera.disc_from_camera.translation_m,
            ),
            yaw_rad: yaw,
        }
    }

    /// The largest of the position gaps, m.
    pub fn largest_m(&self) -> f64 {
        self.part_position_m
            .max(self.base_translation_m)
            .max(self.camera_position_m)
    }
}

/// Whether `link` names an in-process controller this module can log, and
/// its board timing.
pub fn in_process_board(link: &str) -> Option<Option<BoardTiming>> {
    match link {
        "in-process" => Some(None),
        "in-process:stm32f407" => Some(Some(BoardTiming::stm32f407())),
        _ => None,
    }
}
