//! `host-sim calibration-demo`: self-calibration alone on one simulated
//! workcell, against the paper's figures and the paper's own method (the full
//! pick is `host-sim run`, the default).
//!
//! 1. Opens a protocol session with the controller application in process (the
//!    same `shared::app` code the firmware runs) and reads its status.
//! 2. Draws a random workcell in the paper's setting (camera pose, robot base and
//!    part unknown to the controller), records what the camera and the robot's
//!    encoders report over one revolution of the disc.
//! 3. Self-calibrates from that: camera by virtual rotation, part with heights
//!    (Eqs 3 to 8), robot base against the disc (Eqs 10 to 15), refined by bundle
//!    adjustment; and, for comparison, by the paper's own two-frame method.
//! 4. Prints the errors against the truth beside the paper's reported figures,
//!    and a warning on stderr when the part's height is poorly observable (a
//!    camera nearly above the disc's axis, e.g. `--scenario near-axis`).

use std::time::{Duration, Instant};

use anyhow::{anyhow, Context, Result};
use shared::calibration::CalibrationConfig;

use crate::accuracy::metrics::{compare, ErrorMetrics};
use crate::calibration::{calibrate_log, part_height_warning};
use crate::link::check::Session;
use crate::link::InProcessLink;
use crate::recording::simulate;
use crate::scenario::Scenario;

/// Options of `host-sim calibration-demo`.
#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// Which random workcell (seed of the generator).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Sensor scenario (noise-free, paper, noisy, quarter-turn, non-planar, reverse, near-axis).
    #[arg(long, default_value = "paper")]
    pub scenario: String,
}

impl Default for Args {
    fn default() -> Self {
        Self {
            seed: 1,
            scenario: "paper".to_string(),
        }
    }
}

pub fn run(args: &Args) -> Result<()> {
    let mut session = Session::open(InProcessLink::new(), Duration::from_secs(1))
        .context("in-process controller link")?;
    let status = session.status().context("controller status")?;
    println!(
        "controller: {} (firmware {}, protocol v{}, {} Hz control), mode {:?}",
        session.handshake.board_name,
        session.handshake.firmware_version,
        session.handshake.protocol_version,
        session.handshake.control_rate_hz,
        status.mode
    );

    let scenario = Scenario::named(&args.scenario)?;
    let run = simulate(&scenario, args.seed)
        .with_context(|| format!("recording scenario {} (seed {})", scenario.name, args.seed))?;
    let frames = run.log.frames.len();
    let watched_s = run.log.frames.last().map_or(0.0, |f| f.t_s);
    println!(
        "workcell (seed {}): camera {:.2} m above the disc, tilted {:.1} deg; disc centre {:.2} m from the robot's axis; \
         {frames} camera frames over {watched_s:.0} s, scenario {}",
        args.seed,
        run.truth.result.camera.height_m,
        run.truth.workcell.camera_tilt_deg,
        run.truth.workcell.disc_distance_from_base_axis_m,
        args.scenario,
    );

    let started = Instant::now();
    let calibration =
        calibrate_log(&run.log, CalibrationConfig::default()).context("self-calibration")?;
    let elapsed = started.elapsed();
    let warning = calibration
        .refined_uncertainty
        .as_ref()
        .and_then(part_height_warning);
    // `shared`'s CalibrationError is not a `std::error::Error` yet: formatted here.
    let refined = calibration
        .refined
        .map_err(|e| anyhow!("self-calibration failed: {e}"))?;
    let refined_errors = compare(&refined, &run.truth.result)?;
    let paper_errors = match &calibration.paper {
        Ok(result) => Some(compare(result, &run.truth.result)?),
        Err(_) => None,
    };
    println!(
        "self-calibrated from {} frames ({} showing the end effector) in {:.1} ms; rms reprojection {:.2} px\n",
        refined.quality.frames_used,
        refined.quality.effector_frames_used,
        elapsed.as_secs_f64() * 1e3,
        refined.quality.rms_reprojection_px
    );
    if let Some(warning) = &warning {
        eprintln!("{warning}\n");
    }
    print_table(&refined_errors, paper_errors.as_ref());
    println!(
        "\nThe full pick (fusion, interception and computed-torque tracking of the moving part) is `host-sim run`;\n\
         see README for `host-sim accuracy`, `record`, `calibrate` and `link-check`."
    );
    Ok(())
}

fn print_table(refined: &ErrorMetrics, paper_method: Option<&ErrorMetrics>) {
    let paper = |f: fn(&ErrorMetrics) -> f64| {
        paper_method.map_or("failed".to_string(), |m| format!("{:.2}", f(m)))
    };
    println!(
        "| error | paper (Section 5, measured) | paper's method, simulated | this controller |"
    );
    println!("|---|---|---|---|");
    println!(
        "| part position (mm) | about 10 per axis | {} | {:.2} |",
        paper(|m| m.part_position_mm),
        refined.part_position_mm
    );
    println!(
        "| part yaw (deg) | under 5 | {} | {:.3} |",
        paper(|m| m.part_yaw_deg),
        refined.part_yaw_deg
    );
    println!(
        "| camera height (mm) | not reported | {} | {:.2} |",
        paper(|m| m.camera_height_mm),
        refined.camera_height_mm
    );
    println!(
        "| robot base translation (mm) | not reported | {} | {:.2} |",
        paper(|m| m.base_translation_mm),
        refined.base_translation_mm
    );
    println!(
        "| robot base yaw (deg) | not reported | {} | {:.3} |",
        paper(|m| m.base_yaw_deg),
        refined.base_yaw_deg
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_run_completes() {
        run(&Args::default()).unwrap();
    }

    #[test]
    fn an_unknown_scenario_is_an_error() {
        let args = Args {
            scenario: "nope".into(),
            ..Args::default()
        };
        assert!(run(&args).is_err());
    }
}
