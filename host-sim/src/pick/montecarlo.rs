//! The pick's Monte Carlo (`host-sim montecarlo`): many seeded picks over
//! random workcells, in parallel, with the success rate and the percentiles of
//! the errors that matter for a grasp. Every trial's seed is in `trials.csv`,
//! and `host-sim run --experiment NAME --seed SEED` replays it with plots.

use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use indicatif::ProgressBar;
use rayon::prelude::*;
use serde::Serialize;

use super::ml_limit::{limit_of, LimitErrors};
use super::own_log::{run_pick_logged, write_pick_log, InProcessOptions};
use super::record::{PickResult, PickRun};
use super::report::result_name;
use super::runner::run_pick_in_process;
use crate::scenario::pick::PickExperiment;
use crate::world::dimensions::SHOULDER_HEIGHT_M;

/// One trial, flattened for the CSV and the statistics.
#[derive(Debug, Clone, Serialize)]
pub struct TrialSummary {
    pub trial: usize,
    pub seed: u64,
    pub result: String,
    pub success: bool,
    /// The controller's fused part estimate minus the truth at the grasp, mm and degrees.
    pub estimate_error_x_mm: f64,
    pub estimate_error_y_mm: f64,
    pub estimate_error_z_mm: f64,
    pub estimate_error_mm: f64,
    pub estimate_yaw_error_deg: f64,
    /// The gripper's grasp point minus the part's when it closed.
    pub grasp_error_mm: f64,
    pub grasp_yaw_error_deg: f64,
    pub grasp_relative_speed_mm_s: f64,
    pub calibrated_after_s: f64,
    pub duration_s: f64,
    pub max_speed_ratio: f64,
    pub max_torque_ratio: f64,
    pub min_tool_clearance_mm: f64,
    /// The layout (truth, for the report only): the disc centre's direction
    /// from the robot's front, its distance from the base axis, its surface
    /// below the shoulder axis.
    pub disc_azimuth_deg: f64,
    pub disc_distance_m: f64,
    pub disc_below_shoulder_m: f64,
    /// With `--ml-limit` (NaN without): the part in the base frame (worst over
    /// a revolution) and the part's yaw, the controller's final estimate and
    /// the full batch solve of the same frames, each against the truth.
    pub final_part_in_base_mm: f64,
    pub limit_part_in_base_mm: f64,
    pub final_part_yaw_deg: f64,
    pub limit_part_yaw_deg: f64,
    /// With `--ml-limit` (NaN without): the same batch solve with the
    /// robot-to-camera link known, the floor of the disc's frames alone
    /// ([`super::ml_limit`]).
    pub known_link_part_in_base_mm: f64,
    pub known_link_part_yaw_deg: f64,
    /// The last estimate's own 1-sigma of the part in the base frame
    /// (`CalibrationReport::sigma_grasp_*`), mm and degrees, and how many
    /// estimates the pick made (preliminary included).
    pub sigma_grasp_horizontal_mm: f64,
    pub sigma_grasp_vertical_mm: f64,
    pub sigma_grasp_yaw_deg: f64,
    pub estimates: usize,
    /// The last estimate's folding counts (`CalibrationReport`): frames
    /// folded, and folds discarded (a camera that creeps, or folds taken at
    /// a wrong estimate).
    pub frames_folded: u32,
    pub folds_discarded: u32,
    /// With `camera.source = "images"` (0 otherwise): frames the in-loop
    /// front end labelled, the labels it sent and those that named the
    /// wrong mark (scored against the truth).
    pub vision_frames: u64,
    pub vision_labels: u64,
    pub vision_wrong_labels: u64,
}

fn summarise(trial: usize, seed: u64, run: &PickRun) -> TrialSummary {
    let nan = f64::NAN;
    let grasp = run.grasp.as_ref();
    let estimate = grasp.and_then(|g| g.estimate_error_m);
    let [ex, ey, ez] = estimate.unwrap_or([nan; 3]);
    let norm3 = |[x, y, z]: [f64; 3]| (x * x + y * y + z * z).sqrt();
    let disc = run.layout.disc_centre_base_m;
    let last = run.calibrations.last().map(|c| &c.report);
    let sigma = |read: fn(&shared::protocol::CalibrationReport) -> f32, scale: f64| {
        last.map_or(nan, |report| f64::from(read(report)) * scale)
    };
    TrialSummary {
        trial,
        seed,
        result: result_name(&run.result),
        success: run.result == PickResult::Success,
        estimate_error_x_mm: ex * 1e3,
        estimate_error_y_mm: ey * 1e3,
        estimate_error_z_mm: ez * 1e3,
        estimate_error_mm: estimate.map_or(nan, norm3) * 1e3,
        estimate_yaw_error_deg: grasp
            .and_then(|g| g.estimate_yaw_error_rad)
            .map_or(nan, f64::to_degrees),
        grasp_error_mm: grasp.map_or(nan, |g| norm3(g.position_error_m) * 1e3),
        grasp_yaw_error_deg: grasp.map_or(nan, |g| g.yaw_error_rad.to_degrees()),
        grasp_relative_speed_mm_s: grasp.map_or(nan, |g| g.relative_speed_m_s * 1e3),
        calibrated_after_s: run.calibrated_after_s.unwrap_or(nan),
        duration_s: run.duration_s,
        max_speed_ratio: run.max_speed_ratio,
        max_torque_ratio: run.max_torque_ratio,
        min_tool_clearance_mm: run.min_tool_clearance_m * 1e3,
        disc_azimuth_deg: disc[1].atan2(disc[0]).to_degrees(),
        disc_distance_m: disc[0].hypot(disc[1]),
        disc_below_shoulder_m: SHOULDER_HEIGHT_M - disc[2],
        final_part_in_base_mm: nan,
        limit_part_in_base_mm: nan,
        final_part_yaw_deg: nan,
        limit_part_yaw_deg: nan,
        known_link_part_in_base_mm: nan,
        known_link_part_yaw_deg: nan,
        sigma_grasp_horizontal_mm: sigma(|r| r.sigma_grasp_horizontal_m, 1e3),
        sigma_grasp_vertical_mm: sigma(|r| r.sigma_grasp_vertical_m, 1e3),
        sigma_grasp_yaw_deg: sigma(|r| r.sigma_grasp_yaw_rad, 180.0 / std::f64::consts::PI),
        estimates: run.calibrations.len(),
        frames_folded: last.map_or(0, |report| report.frames_folded),
        folds_discarded: last.map_or(0, |report| u32::from(report.folds_discarded)),
        vision_frames: run.vision.map_or(0, |v| v.frames),
        vision_labels: run.vision.map_or(0, |v| v.labels),
        vision_wrong_labels: run.vision.map_or(0, |v| v.wrong_labels),
    }
}

/// The trial's world seed.
pub fn trial_seed(base: u64, trial: usize) -> u64 {
    base.wrapping_mul(1_000_000).wrapping_add(trial as u64)
}

/// Trials whose own observation log is written (see [`super::own_log`]).
#[derive(Debug, Clone, PartialEq)]
pub struct TrialLogs {
    /// Each logged trial's files go to `dir`/trial-NNNN/.
    pub dir: PathBuf,
    /// The trials' indices.
    pub trials: Vec<usize>,
}

impl TrialLogs {
    /// The folder of trial `trial`'s log.
    pub fn trial_dir(&self, trial: usize) -> PathBuf {
        self.dir.join(format!("trial-{trial:04}"))
    }
}

/// What a trial records beside its pick.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TrialRecording {
    /// Trials whose own log is written.
    pub logs: Option<TrialLogs>,
    /// Every trial's final estimate against the maximum-likelihood limit of
    /// its data ([`super::ml_limit`]).
    pub ml_limit: bool,
}

/// One pick of a trial, its own log written when `recording` asks for it
/// (the same run: the recording link runs the controller the same way), its
/// limit measured when asked.
fn run_trial(
    experiment: &PickExperiment,
    trial: usize,
    seed: u64,
    recording: &TrialRecording,
) -> Result<(PickRun, Option<LimitErrors>)> {
    let logs = recording
        .logs
        .as_ref()
        .filter(|logs| logs.trials.contains(&trial));
    if logs.is_none() && !recording.ml_limit {
        return Ok((run_pick_in_process(experiment, seed)?, None));
    }
    let logged = run_pick_logged(experiment, seed, InProcessOptions::default())?;
    if let Some(logs) = logs {
        write_pick_log(&logs.trial_dir(trial), &logged)?;
    }
    // A pick without a final estimate has no limit to compare with.
    let limit = recording.ml_limit.then(|| limit_of(&logged).ok()).flatten();
    Ok((logged.run, limit))
}

/// Runs `trials` picks of `experiment` in parallel (a failed simulation counts as
/// a trial whose result names the error).
pub fn run_trials(
    experiment: &PickExperiment,
    trials: usize,
    base_seed: u64,
    progress: &ProgressBar,
) -> Vec<TrialSummary> {
    run_trials_recording(
        experiment,
        trials,
        base_seed,
        progress,
        &TrialRecording::default(),
    )
}

/// [`run_trials`], recording what `recording` asks for.
pub fn run_trials_recording(
    experiment: &PickExperiment,
    trials: usize,
    base_seed: u64,
    progress: &ProgressBar,
    recording: &TrialRecording,
) -> Vec<TrialSummary> {
    let mut summaries: Vec<TrialSummary> = (0..trials)
        .into_par_iter()
        .map(|trial| {
            let seed = trial_seed(base_seed, trial);
            let summary = match run_trial(experiment, trial, seed, recording) {
                Ok((run, limit)) => with_limit(summarise(trial, seed, &run), limit.as_ref()),
                Err(error) => TrialSummary {
                    result: format!("error: {error:#}"),
                    ..summarise(trial, seed, &PickRun::empty(&experiment.name, seed))
                },
            };
            progress.inc(1);
            summary
        })
        .collect();
    summaries.sort_by_key(|s| s.trial);
    summaries
}

fn with_limit(summary: TrialSummary, limit: Option<&LimitErrors>) -> TrialSummary {
    match limit {
        Some(limit) => TrialSummary {
            final_part_in_base_mm: limit.controller.part_in_base_mm,
            limit_part_in_base_mm: limit.limit.part_in_base_mm,
            final_part_yaw_deg: limit.controller.part_yaw_deg,
            limit_part_yaw_deg: limit.limit.part_yaw_deg,
            known_link_part_in_base_mm: limit.known_link.part_in_base_mm,
            known_link_part_yaw_deg: limit.known_link.part_yaw_deg,
            ..summary
        },
        None => summary,
    }
}

/// A quantity's (final estimate, limit, limit with the link known) of a trial.
type LimitColumns = fn(&TrialSummary) -> (f64, f64, f64);

/// The controller's final estimate against the maximum-likelihood limit of
/// the same frames (`--ml-limit`): median and 95th percentile of each, the
/// ratio of the 95th percentiles and the median of the per-trial ratios;
/// beside them the floor of the disc's frames alone (the robot-to-camera link
/// known). Empty when no trial measured it.
pub fn limit_table(summaries: &[TrialSummary]) -> String {
    let measured: Vec<&TrialSummary> = summaries
        .iter()
        .filter(|s| s.limit_part_in_base_mm.is_finite())
        .collect();
    if measured.is_empty() {
        return String::new();
    }
    let mut text = format!(
        "\nThe final estimate against the maximum-likelihood limit of the same frames \
         (the full batch solve, `host_sim::batch_ml`), {} trials; median / 95th percentile:\n\n\
         | quantity | final estimate | limit | 95th ratio | paired ratio (median) | link known (disc frames' floor) |\n|---|---|---|---|---|---|\n",
        measured.len()
    );
    let rows: [(&str, LimitColumns); 2] = [
        ("part in the base frame, worst over a turn (mm)", |s| {
            (
                s.final_part_in_base_mm,
                s.limit_part_in_base_mm,
                s.known_link_part_in_base_mm,
            )
        }),
        ("part yaw (deg)", |s| {
            (
                s.final_part_yaw_deg,
                s.limit_part_yaw_deg,
                s.known_link_part_yaw_deg,
            )
        }),
    ];
    for (name, pick) in rows {
        let columns: Vec<(f64, f64, f64)> = measured.iter().map(|s| pick(s)).collect();
        let controller: Vec<f64> = columns.iter().map(|c| c.0).collect();
        let limit: Vec<f64> = columns.iter().map(|c| c.1).collect();
        let known_link: Vec<f64> = columns.iter().map(|c| c.2).collect();
        let ratios: Vec<f64> = controller
            .iter()
            .zip(&limit)
            .filter(|(_, l)| **l > 0.0)
            .map(|(c, l)| c / l)
            .collect();
        let p95 = |v: &[f64]| percentile(v, 95.0);
        let _ = writeln!(
            text,
            "| {name} | {:.3} / {:.3} | {:.3} / {:.3} | {:.2} | {:.2} | {:.3} / {:.3} |",
            percentile(&controller, 50.0),
            p95(&controller),
            percentile(&limit, 50.0),
            p95(&limit),
            p95(&controller) / p95(&limit),
            percentile(&ratios, 50.0),
            percentile(&known_link, 50.0),
            p95(&known_link)
        );
    }
    text
}

/// The `p`-th percentile (nearest rank) of the finite values; NaN when none.
pub fn percentile(values: &[f64], p: f64) -> f64 {
    let mut finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if finite.is_empty() {
        return f64::NAN;
    }
    finite.sort_by(f64::total_cmp);
    let rank = ((p / 100.0) * finite.len() as f64).ceil() as usize;
    finite[rank.clamp(1, finite.len()) - 1]
}

/// One column of the statistics table.
type Metric = fn(&TrialSummary) -> f64;

/// The markdown report of a Monte Carlo run.
pub fn montecarlo_table(experiment: &str, summaries: &[TrialSummary]) -> String {
    let n = summaries.len();
    let successes = summaries.iter().filter(|s| s.success).count();
    let mut out = String::new();
    let _ = writeln!(
        out,
        "# Pick Monte Carlo: {experiment}, {n} random workcells\n\n\
         Success: {successes} of {n} ({:.1} %).\n",
        100.0 * successes as f64 / n.max(1) as f64
    );
    let mut outcomes: Vec<(String, usize)> = Vec::new();
    for s in summaries {
        match outcomes.iter_mut().find(|(name, _)| *name == s.result) {
            Some((_, count)) => *count += 1,
            None => outcomes.push((s.result.clone(), 1)),
        }
    }
    outcomes.sort_by_key(|(_, count)| std::cmp::Reverse(*count));
    let vision_frames: u64 = summaries.iter().map(|s| s.vision_frames).sum();
    if vision_frames > 0 {
        let labels: u64 = summaries.iter().map(|s| s.vision_labels).sum();
        let wrong: u64 = summaries.iter().map(|s| s.vision_wrong_labels).sum();
        let trials = summaries
            .iter()
            .filter(|s| s.vision_wrong_labels > 0)
            .count();
        let _ = writeln!(
            out,
            "Through images: {vision_frames} frames labelled in the loop, {labels} labels sent, \
             {wrong} wrong (in {trials} trials).\n"
        );
    }
    let _ = writeln!(out, "| outcome | trials |\n|---|---|");
    for (name, count) in &outcomes {
        let _ = writeln!(out, "| {name} | {count} |");
    }
    let _ = writeln!(
        out,
        "\n| quantity (at the grasp unless said) | median | 95th percentile | 99th percentile | max |\n|---|---|---|---|---|"
    );
    let rows: [(&str, Metric); 12] = [
        ("part estimate error, 3-D (mm)", |s| s.estimate_error_mm),
        ("part estimate error, |x| (mm)", |s| {
            s.estimate_error_x_mm.abs()
        }),
        ("part estimate error, |y| (mm)", |s| {
            s.estimate_error_y_mm.abs()
        }),
        ("part estimate error, |z| (mm)", |s| {
            s.estimate_error_z_mm.abs()
        }),
        ("part estimate yaw error (deg)", |s| {
            s.estimate_yaw_error_deg
        }),
        ("gripper to part, 3-D (mm)", |s| s.grasp_error_mm),
        ("gripper to part yaw (deg)", |s| s.grasp_yaw_error_deg),
        ("gripper to part speed (mm/s)", |s| {
            s.grasp_relative_speed_mm_s
        }),
        ("time to a calibrated cell (s)", |s| s.calibrated_after_s),
        ("time to done (s)", |s| s.duration_s),
        ("joint speed / limit, worst", |s| s.max_speed_ratio),
        ("applied torque / limit, worst", |s| s.max_torque_ratio),
    ];
    for (name, value) in rows {
        let values: Vec<f64> = summaries.iter().map(value).collect();
        let _ = writeln!(
            out,
            "| {name} | {:.3} | {:.3} | {:.3} | {:.3} |",
            percentile(&values, 50.0),
            percentile(&values, 95.0),
            percentile(&values, 99.0),
            percentile(&values, 100.0)
        );
    }
    let clearance: Vec<f64> = summaries.iter().map(|s| s.min_tool_clearance_mm).collect();
    let lowest = clearance
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(f64::INFINITY, f64::min);
    let _ = writeln!(
        out,
        "\nLowest grasp-point height above the disc surface while not holding the part: {lowest:.1} mm (the grasp point descends to the part's top, 40 or 70 mm)."
    );
    out.push_str(&azimuth_table(summaries));
    out
}

/// Success by the disc centre's direction from the robot's front, in 30-degree bins.
pub fn azimuth_table(summaries: &[TrialSummary]) -> String {
    let mut out = String::from(
        "\n| disc azimuth (deg) | trials | successes | success | other outcomes |\n|---|---|---|---|---|\n",
    );
    for bin in 0..12 {
        let low = -180.0 + 30.0 * f64::from(bin);
        let high = low + 30.0;
        let in_bin: Vec<&TrialSummary> = summaries
            .iter()
            .filter(|s| {
                s.disc_azimuth_deg >= low
                    && (s.disc_azimuth_deg < high || (bin == 11 && s.disc_azimuth_deg <= high))
            })
            .collect();
        let successes = in_bin.iter().filter(|s| s.success).count();
        let mut others: Vec<(String, usize)> = Vec::new();
        for s in in_bin.iter().filter(|s| !s.success) {
            match others.iter_mut().find(|(name, _)| *name == s.result) {
                Some((_, count)) => *count += 1,
                None => others.push((s.result.clone(), 1)),
            }
        }
        let others: Vec<String> = others.iter().map(|(n, c)| format!("{n} {c}")).collect();
        let rate = if in_bin.is_empty() {
            "-".to_string()
        } else {
            format!("{:.1} %", 100.0 * successes as f64 / in_bin.len() as f64)
        };
        let _ = writeln!(
            out,
            "| {low:.0} to {high:.0} | {} | {successes} | {rate} | {} |",
            in_bin.len(),
            others.join(", ")
        );
    }
    out
}

/// Writes `trials.csv`: one line per trial.
pub fn write_trials_csv(path: &Path, summaries: &[TrialSummary]) -> Result<()> {
    let mut text = String::from(
        "trial,seed,result,success,estimate_error_x_mm,estimate_error_y_mm,estimate_error_z_mm,estimate_error_mm,estimate_yaw_error_deg,grasp_error_mm,grasp_yaw_error_deg,grasp_relative_speed_mm_s,calibrated_after_s,duration_s,max_speed_ratio,max_torque_ratio,min_tool_clearance_mm,disc_azimuth_deg,disc_distance_m,disc_below_shoulder_m,final_part_in_base_mm,limit_part_in_base_mm,final_part_yaw_deg,limit_part_yaw_deg,known_link_part_in_base_mm,known_link_part_yaw_deg,sigma_grasp_horizontal_mm,sigma_grasp_vertical_mm,sigma_grasp_yaw_deg,estimates,frames_folded,folds_discarded,vision_frames,vision_labels,vision_wrong_labels\n",
    );
    for s in summaries {
        let _ = writeln!(
            text,
            "{},{},\"{}\",{},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.3},{:.3},{:.4},{:.4},{:.2},{:.2},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{},{},{},{},{},{}",
            s.trial,
            s.seed,
            s.result.replace('"', "'"),
            s.success,
            s.estimate_error_x_mm,
            s.estimate_error_y_mm,
            s.estimate_error_z_mm,
            s.estimate_error_mm,
            s.estimate_yaw_error_deg,
            s.grasp_error_mm,
            s.grasp_yaw_error_deg,
            s.grasp_relative_speed_mm_s,
            s.calibrated_after_s,
            s.duration_s,
            s.max_speed_ratio,
            s.max_torque_ratio,
            s.min_tool_clearance_mm,
            s.disc_azimuth_deg,
            s.disc_distance_m,
            s.disc_below_shoulder_m,
            s.final_part_in_base_mm,
            s.limit_part_in_base_mm,
            s.final_part_yaw_deg,
            s.limit_part_yaw_deg,
            s.known_link_part_in_base_mm,
            s.known_link_part_yaw_deg,
            s.sigma_grasp_horizontal_mm,
            s.sigma_grasp_vertical_mm,
            s.sigma_grasp_yaw_deg,
            s.estimates,
            s.frames_folded,
            s.folds_discarded,
            s.vision_frames,
            s.vision_labels,
            s.vision_wrong_labels
        );
    }
    fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}
