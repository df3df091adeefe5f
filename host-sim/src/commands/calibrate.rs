//! `host-sim calibrate LOG.jsonl`: stream a log into the self-calibration
//! (`shared::calibration`), print the contract's calibration-result JSON on
//! stdout and a short human summary (and, with `--truth`, the errors) on stderr.
//! With `--batch`, the whole log is held and the full batch maximum-likelihood
//! solve ([`crate::batch_ml`]) runs from the calibrator's estimate: its result
//! is printed instead, the calibrator's beside it on stderr.
//! `--calibrator pick --frames N` replays a pick's own log through the
//! controller's calibrator as the controller's final estimate saw it (see
//! `crate::pick::own_log`).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{anyhow, Context};
use serde::Serialize;
use shared::calibration::{CalibrationConfig, EstimateUncertainty};
use shared::observation::CalibrationResult;

use crate::accuracy::metrics::{compare, ErrorMetrics, METRIC_COLUMNS};
use crate::batch_ml::batch_estimate;
use crate::batch_ml::covariance::norm;
use crate::calibration::{
    calibrate_frames_with, calibrate_log, part_height_warning, Adoption, CalibratorChoice,
};
use crate::log::{open_log, read_log_file};
use crate::recording::read_truth_result;

/// Calibrate camera, part and robot base from an observation log.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The observation log (JSON Lines, contract version 1).
    pub log: PathBuf,
    /// A ground-truth file (from `record`, or a pick's own log's truth or
    /// `controller_estimate.json`): also print the errors of the estimate
    /// against it.
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// The calibrator: the host's (1024 frames, 256 sightings) or the pick
    /// controller's own (256 frames, 128 sightings, thinned as on the
    /// firmware; frames it refuses are passed over, as the controller does).
    #[arg(long, value_enum, default_value_t = CalibratorChoice::Host)]
    pub calibrator: CalibratorChoice,
    /// Adopt the calibrator's estimate after these many frames (comma-separated)
    /// instead of by the host's rule (when its stores fill, then each time the
    /// frames double): a pick's own log's `controller.adopted_after_frames`,
    /// so that the replay folds what the controller folded.
    #[arg(long, value_delimiter = ',')]
    pub adopt_after_frames: Option<Vec<u32>>,
    /// Use only the log's first N frames (a pick's own log goes on past its
    /// final estimate: `controller.log_frames` of its controller_estimate.json).
    #[arg(long)]
    pub frames: Option<usize>,
    /// Print the paper's own two-frame estimate instead of the refined one.
    #[arg(long, conflicts_with = "batch")]
    pub paper: bool,
    /// The maximum-likelihood limit: a full batch solve over every frame and every
    /// end-effector sighting (unbounded memory), started from the calibrator's estimate.
    #[arg(long)]
    pub batch: bool,
    /// Experiment 2 of the paper: the disc surface's known height in the base frame (m).
    #[arg(long)]
    pub disc_height_in_base_m: Option<f64>,
    /// Pixel noise standard deviation assumed by the estimator.
    #[arg(long, default_value_t = 0.5)]
    pub pixel_sigma: f64,
}

/// What `calibrate` prints on stdout: the contract's result, plus (for the refined
/// estimate) its one-sigma uncertainties under `uncertainty_1sigma`.
#[derive(Serialize)]
struct PrintedResult<'a> {
    #[serde(flatten)]
    result: &'a CalibrationResult,
    #[serde(skip_serializing_if = "Option::is_none")]
    uncertainty_1sigma: Option<EstimateUncertainty>,
}

fn summary(label: &str, result: &CalibrationResult) -> String {
    let [x, y, z] = result.base_from_disc.translation_m;
    let [px, py, pz] = result.part.position_m;
    format!(
        "{label}: camera {:.4} m above the disc; part at ({px:.4}, {py:.4}, {pz:.4}) m, yaw {:.3} deg; \
         disc centre in base ({x:.4}, {y:.4}, {z:.4}) m, yaw {:.3} deg; {} frames ({} with the effector), \
         rms {:.3} px, {} outliers rejected",
        result.camera.height_m,
        result.part.yaw_rad.to_degrees(),
        result.base_from_disc.yaw_rad.to_degrees(),
        result.quality.frames_used,
        result.quality.effector_frames_used,
        result.quality.rms_reprojection_px,
        result.quality.outliers_rejected,
    )
}

fn error_lines(label: &str, errors: &ErrorMetrics) -> String {
    let cells: Vec<String> = METRIC_COLUMNS
        .iter()
        .map(|c| format!("{} {:.4} {}", c.name, (c.value)(errors), c.unit))
        .collect();
    format!("{label} errors: {}", cells.join(", "))
}

fn print_result(
    result: &CalibrationResult,
    uncertainty: Option<EstimateUncertainty>,
) -> anyhow::Result<()> {
    let mut stdout = std::io::stdout().lock();
    let printed_result = PrintedResult {
        result,
        uncertainty_1sigma: uncertainty,
    };
    serde_json::to_writer_pretty(&mut stdout, &printed_result).context("writing the result")?;
    writeln!(stdout).context("writing the result")
}

/// `--batch`: the calibrator's estimate as the start, then the batch solve.
fn run_batch(
    args: &Args,
    config: CalibrationConfig,
    truth: Option<&CalibrationResult>,
) -> anyhow::Result<()> {
    let log = read_log_file(&args.log)?;
    let calibration =
        calibrate_log(&log, config).with_context(|| format!("in log {}", args.log.display()))?;
    // `shared`'s CalibrationError is not a `std::error::Error` yet: formatted here.
    let start = calibration.refined.as_ref().map_err(|e| {
        anyhow!(
            "calibration of {} failed, so the batch solve has no start: {e}",
            args.log.display()
        )
    })?;
    let started = Instant::now();
    let batch = batch_estimate(&log, &config, start).with_context(|| batch_context(&args.log))?;
    let elapsed_s = started.elapsed().as_secs_f64();
    print_result(&batch.result, Some(batch.uncertainty))?;

    eprintln!(
        "{}",
        summary("batch maximum-likelihood estimate", &batch.result)
    );
    let u = &batch.uncertainty;
    eprintln!(
        "batch: {} of {} image points kept, {} unknowns, {} iterations in {} gate rounds{}, {:.3} s; \
         measured pixel sigma {:.3} px; Cramer-Rao 1-sigma: part position {:.3} mm, base translation {:.3} mm, \
         camera height {:.3} mm, base yaw {:.4} deg",
        batch.observations_kept,
        batch.observations,
        batch.parameters,
        batch.iterations,
        batch.gate_rounds,
        if batch.gate_settled { "" } else { " (the gate did not settle)" },
        elapsed_s,
        batch.measured_sigma_px,
        norm(u.part_position_m) * 1000.0,
        norm(u.base_translation_m) * 1000.0,
        u.camera_height_m * 1000.0,
        u.base_yaw_rad.to_degrees()
    );
    eprintln!("{}", summary("calibrator (refined) estimate", start));
    if let Some(truth) = truth {
        eprintln!("{}", error_lines("batch", &compare(&batch.result, truth)?));
        eprintln!("{}", error_lines("calibrator", &compare(start, truth)?));
    }
    Ok(())
}

fn batch_context(log: &Path) -> String {
    format!("batch solve of log {}", log.display())
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let config = CalibrationConfig {
        disc_height_in_base_m: args.disc_height_in_base_m,
        pixel_sigma: args.pixel_sigma,
        ..CalibrationConfig::default()
    };
    let truth = args.truth.as_deref().map(read_truth_result).transpose()?;
    if args.batch {
        return run_batch(args, config, truth.as_ref());
    }
    let reader = open_log(&args.log)?;
    let header = *reader.header();
    let frames = reader.numbered().take(args.frames.unwrap_or(usize::MAX));
    let adoption = args
        .adopt_after_frames
        .clone()
        .map_or_else(Adoption::default, Adoption::AfterFrames);
    let calibration = calibrate_frames_with(args.calibrator, adoption, &header, frames, config)
        .with_context(|| format!("in log {}", args.log.display()))?;

    let (printed, printed_label) = if args.paper {
        (
            &calibration.paper,
            "paper estimate (Eq 8 two frames, Eq 15 one pose)",
        )
    } else {
        (&calibration.refined, "refined estimate")
    };
    // `shared`'s CalibrationError is not a `std::error::Error` yet: formatted here.
    let result = printed
        .as_ref()
        .map_err(|e| anyhow!("calibration of {} failed: {e}", args.log.display()))?;
    print_result(
        result,
        if args.paper {
            None
        } else {
            calibration.refined_uncertainty
        },
    )?;

    eprintln!("{}", summary(printed_label, result));
    if let (Some(u), false) = (&calibration.refined_uncertainty, args.paper) {
        eprintln!(
            "refined 1-sigma: camera height {:.3} mm, part position {:.3} mm, base translation {:.3} mm, base yaw {:.4} deg",
            u.camera_height_m * 1000.0,
            norm(u.part_position_m) * 1000.0,
            norm(u.base_translation_m) * 1000.0,
            u.base_yaw_rad.to_degrees()
        );
    }
    if let Some(warning) = calibration
        .refined_uncertainty
        .as_ref()
        .and_then(part_height_warning)
    {
        eprintln!("{warning}");
    }
    for (label, other) in [
        ("refined", &calibration.refined),
        ("paper", &calibration.paper),
    ] {
        match (other, &truth) {
            (Err(e), _) => eprintln!("{label} estimate failed: {e}"),
            (Ok(estimate), Some(truth)) => {
                eprintln!("{}", error_lines(label, &compare(estimate, truth)?));
            }
            (Ok(_), None) => {}
        }
    }
    Ok(())
}
