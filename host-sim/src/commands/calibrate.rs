//! `host-sim calibrate LOG.jsonl`: stream a log into the self-calibration
//! (`shared::calibration`), print the contract's calibration-result JSON on
//! stdout and a short human summary (and, with `--truth`, the errors) on stderr.
//! `--calibrator pick --frames N` replays a pick's own log through the
//! controller's calibrator as the controller's final estimate saw it (see
//! `crate::pick::own_log`).

use std::io::Write;
use std::path::PathBuf;

use anyhow::{anyhow, Context};
use serde::Serialize;
use shared::calibration::{CalibrationConfig, EstimateUncertainty};
use shared::observation::CalibrationResult;

use crate::accuracy::metrics::{compare, ErrorMetrics, METRIC_COLUMNS};
use crate::calibration::{calibrate_frames_with, part_height_warning, CalibratorChoice};
use crate::log::open_log;
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
    /// Use only the log's first N frames (a pick's own log goes on past its
    /// final estimate: `controller.log_frames` of its controller_estimate.json).
    #[arg(long)]
    pub frames: Option<usize>,
    /// Print the paper's own two-frame estimate instead of the refined one.
    #[arg(long)]
    pub paper: bool,
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

pub fn run(args: &Args) -> anyhow::Result<()> {
    let config = CalibrationConfig {
        disc_height_in_base_m: args.disc_height_in_base_m,
        pixel_sigma: args.pixel_sigma,
        ..CalibrationConfig::default()
    };
    let truth = args.truth.as_deref().map(read_truth_result).transpose()?;
    let reader = open_log(&args.log)?;
    let header = *reader.header();
    let frames = reader.numbered().take(args.frames.unwrap_or(usize::MAX));
    let calibration = calibrate_frames_with(args.calibrator, &header, frames, config)
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
    let mut stdout = std::io::stdout().lock();
    let printed_result = PrintedResult {
        result,
        uncertainty_1sigma: if args.paper {
            None
        } else {
            calibration.refined_uncertainty
        },
    };
    serde_json::to_writer_pretty(&mut stdout, &printed_result).context("writing the result")?;
    writeln!(stdout).context("writing the result")?;

    eprintln!("{}", summary(printed_label, result));
    if let (Some(u), false) = (&calibration.refined_uncertainty, args.paper) {
        let norm = |v: [f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt() * 1000.0;
        eprintln!(
            "refined 1-sigma: camera height {:.3} mm, part position {:.3} mm, base translation {:.3} mm, base yaw {:.4} deg",
            u.camera_height_m * 1000.0,
            norm(u.part_position_m),
            norm(u.base_translation_m),
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
