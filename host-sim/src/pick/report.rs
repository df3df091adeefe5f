//! The pick's results in text: the CSV files of one run, the markdown results
//! table beside the paper's reported figures (Section 5, Figs 4 to 9) and a
//! one-line summary for the terminal. The PNG figures are in [`super::plots`].

use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use shared::protocol::PickPhase;

use super::plots;
use super::record::{CalibrationRecord, GraspRecord, PickResult, PickRun, TickRecord};

/// Writes every output of `run` into `dir/<experiment>/`: `timeseries.csv`,
/// `phases.csv`, `calibration.csv`, `grasp.csv` and the four PNG figures of
/// [`plots::write_run_plots`]. Returns the paths written, in that order.
pub fn write_run_outputs(run: &PickRun, dir: &Path) -> Result<Vec<PathBuf>> {
    let run_dir = dir.join(directory_name(&run.experiment));
    fs::create_dir_all(&run_dir)
        .with_context(|| format!("creating the output folder {}", run_dir.display()))?;
    let mut written = Vec::new();
    for (name, text) in [
        ("timeseries.csv", timeseries_csv(&run.records)),
        ("phases.csv", phases_csv(run)),
        ("calibration.csv", calibration_csv(&run.calibrations)),
        ("grasp.csv", grasp_csv(run)),
    ] {
        let path = run_dir.join(name);
        fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
        written.push(path);
    }
    written.extend(plots::write_run_plots(run, &run_dir)?);
    Ok(written)
}

/// A folder name from an experiment name: anything but ASCII letters, digits,
/// `-` and `_` becomes `_` so that a name can never climb out of `dir`.
pub fn directory_name(experiment: &str) -> String {
    let cleaned: String = experiment
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if cleaned.is_empty() {
        "run".to_owned()
    } else {
        cleaned
    }
}

/// The name a phase is written with (its variant name, e.g. `Intercept`).
pub fn phase_name(phase: PickPhase) -> String {
    format!("{phase:?}")
}

/// How a pick ended, in words.
pub fn result_name(result: &PickResult) -> String {
    match result {
        PickResult::Success => "success".to_owned(),
        PickResult::GraspMissed => "grasp missed".to_owned(),
        PickResult::Fault(cause) => format!("fault: {cause:?}"),
        PickResult::TimedOut(phase) => format!("timed out in {phase:?}"),
    }
}

/// The header of `timeseries.csv`: one column per [`TickRecord`] field, arrays
/// expanded with their axis or joint in the name.
pub fn timeseries_header() -> Vec<String> {
    let mut columns: Vec<String> = vec!["t_s".into(), "phase".into()];
    let xyz = ["x", "y", "z"];
    for prefix in ["part_true", "part_est"] {
        columns.extend(xyz.iter().map(|axis| format!("{prefix}_{axis}_m")));
        columns.push(format!("{prefix}_yaw_rad"));
    }
    columns.push("part_sigma_m".into());
    for prefix in ["tool_true", "tool_ref"] {
        columns.extend(xyz.iter().map(|axis| format!("{prefix}_{axis}_m")));
        columns.push(format!("{prefix}_yaw_rad"));
    }
    columns.extend(
        [
            "theta_true_rad",
            "theta_est_wrapped_rad",
            "omega_true_rad_s",
            "omega_est_rad_s",
        ]
        .map(String::from),
    );
    for (name, unit) in [("q", "rad"), ("qd", "rad_s"), ("tau", "nm")] {
        columns.extend((1..=6).map(|joint| format!("{name}{joint}_{unit}")));
    }
    columns
}

/// One row of `timeseries.csv`, in the order of [`timeseries_header`]; an
/// estimate the controller did not have yet is an empty cell.
pub fn timeseries_row(record: &TickRecord) -> Vec<String> {
    let mut cells = vec![number(record.t_s), phase_name(record.phase)];
    cells.extend(record.part_true_base_m.map(number));
    cells.push(number(record.part_true_yaw_rad));
    match record.part_est_base_m {
        Some(p) => cells.extend(p.map(number)),
        None => cells.extend([String::new(), String::new(), String::new()]),
    }
    cells.push(optional(record.part_est_yaw_rad));
    cells.push(number(record.part_sigma_m));
    cells.extend(record.tool_true_base_m.map(number));
    cells.push(number(record.tool_true_yaw_rad));
    cells.extend(record.tool_ref_base_m.map(number));
    cells.push(number(record.tool_ref_yaw_rad));
    cells.extend(
        [
            record.theta_true_rad,
            record.theta_est_wrapped_rad,
            record.omega_true_rad_s,
            record.omega_est_rad_s,
        ]
        .map(number),
    );
    cells.extend(record.q_rad.map(number));
    cells.extend(record.qd_rad_s.map(number));
    cells.extend(record.tau_nm.map(number));
    cells
}

fn timeseries_csv(records: &[TickRecord]) -> String {
    let mut text = csv_line(&timeseries_header());
    for record in records {
        text.push_str(&csv_line(&timeseries_row(record)));
    }
    text
}

/// `phases.csv`: each phase the controller reported, when it started, when it
/// ended (the next event, or the run's end) and how long it lasted.
fn phases_csv(run: &PickRun) -> String {
    let mut text = csv_line(&["phase", "start_s", "end_s", "duration_s"].map(String::from));
    let ends = run
        .phases
        .iter()
        .skip(1)
        .map(|next| next.t_s)
        .chain(std::iter::once(run.duration_s));
    for (event, end_s) in run.phases.iter().zip(ends) {
        text.push_str(&csv_line(&[
            phase_name(event.phase),
            number(event.t_s),
            number(end_s),
            number(end_s - event.t_s),
        ]));
    }
    text
}

/// `calibration.csv` in long form: one row per quantity of each calibration,
/// estimate beside truth where the simulation knows it (camera height, base
/// yaw, base translation), the estimator's 1-sigma where it reports one.
fn calibration_csv(calibrations: &[CalibrationRecord]) -> String {
    let header = [
        "calibration",
        "t_s",
        "quantity",
        "estimate",
        "truth",
        "error",
        "sigma",
    ]
    .map(String::from);
    let mut text = csv_line(&header);
    for (index, calibration) in calibrations.iter().enumerate() {
        let report = &calibration.report;
        let [bx, by, bz] = report.base_translation_m.map(f64::from);
        let [tx, ty, tz] = calibration.true_base_translation_m;
        let [px, py, pz] = report.part_rotating_m.map(f64::from);
        let sigma_base = Some(f64::from(report.sigma_base_m));
        let sigma_part = Some(f64::from(report.sigma_part_m));
        let rows: [(&str, f64, Option<f64>, Option<f64>); 13] = [
            (
                "camera_height_m",
                f64::from(report.camera_height_m),
                Some(calibration.true_camera_height_m),
                None,
            ),
            (
                "base_yaw_rad",
                f64::from(report.base_yaw_rad),
                Some(calibration.true_base_yaw_rad),
                Some(f64::from(report.sigma_base_yaw_rad)),
            ),
            ("base_x_m", bx, Some(tx), sigma_base),
            ("base_y_m", by, Some(ty), sigma_base),
            ("base_z_m", bz, Some(tz), sigma_base),
            (
                "camera_tilt_rad",
                f64::from(report.camera_tilt_rad),
                None,
                None,
            ),
            ("part_rotating_x_m", px, None, sigma_part),
            ("part_rotating_y_m", py, None, sigma_part),
            ("part_rotating_z_m", pz, None, sigma_part),
            (
                "part_yaw_rotating_rad",
                f64::from(report.part_yaw_rotating_rad),
                None,
                None,
            ),
            ("frames_used", f64::from(report.frames_used), None, None),
            (
                "effector_frames_used",
                f64::from(report.effector_frames_used),
                None,
                None,
            ),
            (
                "rms_reprojection_px",
                f64::from(report.rms_reprojection_px),
                None,
                None,
            ),
        ];
        for (quantity, estimate, truth, sigma) in rows {
            let error = truth.map(|truth| {
                if quantity == "base_yaw_rad" {
                    wrap_angle_rad(estimate - truth)
                } else {
                    estimate - truth
                }
            });
            text.push_str(&csv_line(&[
                index.to_string(),
                number(calibration.t_s),
                quantity.to_owned(),
                number(estimate),
                optional(truth),
                optional(error),
                optional(sigma),
            ]));
        }
    }
    text
}

/// `grasp.csv`: the gripper's and the estimate's errors at the instant the
/// gripper closed (no data row when it never closed), with the run's result.
fn grasp_csv(run: &PickRun) -> String {
    let header = [
        "t_s",
        "succeeded",
        "position_error_x_m",
        "position_error_y_m",
        "position_error_z_m",
        "position_error_norm_m",
        "yaw_error_rad",
        "relative_speed_m_s",
        "estimate_error_x_m",
        "estimate_error_y_m",
        "estimate_error_z_m",
        "estimate_yaw_error_rad",
        "result",
        "placed_error_m",
    ]
    .map(String::from);
    let mut text = csv_line(&header);
    if let Some(grasp) = &run.grasp {
        let mut cells = vec![number(grasp.t_s), grasp.succeeded.to_string()];
        cells.extend(grasp.position_error_m.map(number));
        cells.push(number(norm(grasp.position_error_m)));
        cells.push(number(grasp.yaw_error_rad));
        cells.push(number(grasp.relative_speed_m_s));
        match grasp.estimate_error_m {
            Some(e) => cells.extend(e.map(number)),
            None => cells.extend([String::new(), String::new(), String::new()]),
        }
        cells.push(optional(grasp.estimate_yaw_error_rad));
        cells.push(result_name(&run.result));
        cells.push(optional(run.placed_error_m));
        text.push_str(&csv_line(&cells));
    }
    text
}

/// What the paper reports for the experiment a run reproduces (Section 5):
/// experiment 1 (disc height unknown, Figs 4-5) "around 1 cm" in X and Y and
/// "less than 5 degrees"; experiment 2 with a 7 cm part (Figs 8-9) "within
/// 1 cm" and "less than 5 degrees"; experiment 2 with a 4 cm part (Figs 6-7)
/// has plots only. Matched on the scenario names `experiment-1`,
/// `experiment-2-4cm`, `experiment-2-7cm`.
pub fn paper_figure(experiment: &str) -> &'static str {
    if experiment.starts_with("experiment-1") {
        "X, Y ~10 mm; yaw < 5 deg (Figs 4-5)"
    } else if experiment.starts_with("experiment-2") && experiment.contains("7cm") {
        "X, Y <= 10 mm; yaw < 5 deg (Figs 8-9)"
    } else if experiment.starts_with("experiment-2") {
        "not reported (Figs 6-7 plots only)"
    } else {
        "not reported"
    }
}

/// The markdown results table: one row per run, the paper's figure beside our
/// part estimate error at grasp time (estimate minus truth, Eq 1), the
/// gripper's error against the part, the outcome and the times.
pub fn results_table(runs: &[PickRun]) -> String {
    let mut table = String::from(
        "| experiment | paper | est. X (mm) | est. Y (mm) | est. Z (mm) | est. yaw (deg) \
         | grasp error (mm) | result | calibrated after (s) | total (s) |\n\
         |---|---|---:|---:|---:|---:|---:|---|---:|---:|\n",
    );
    for run in runs {
        let estimate = run.grasp.as_ref().and_then(|g| g.estimate_error_m);
        let [ex, ey, ez] = match estimate {
            Some(e) => e.map(|v| Some(v * 1000.0)),
            None => [None; 3],
        };
        let yaw_deg = run
            .grasp
            .as_ref()
            .and_then(|g| g.estimate_yaw_error_rad)
            .map(|v| wrap_angle_rad(v).to_degrees());
        let grasp_mm = run
            .grasp
            .as_ref()
            .map(|g| norm(g.position_error_m) * 1000.0);
        let _ = writeln!(
            table,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            run.experiment.replace('|', "/"),
            paper_figure(&run.experiment),
            fixed(ex, 1),
            fixed(ey, 1),
            fixed(ez, 1),
            fixed(yaw_deg, 2),
            fixed(grasp_mm, 1),
            result_name(&run.result),
            fixed(run.calibrated_after_s, 1),
            fixed(Some(run.duration_s), 1),
        );
    }
    table
}

/// One line for the terminal after a run.
pub fn summary_line(run: &PickRun) -> String {
    let mut line = format!(
        "{} (seed {}): {} after {} s",
        run.experiment,
        run.seed,
        result_name(&run.result),
        fixed(Some(run.duration_s), 1)
    );
    match run.calibrated_after_s {
        Some(t) => {
            let _ = write!(line, ", calibrated at {} s", fixed(Some(t), 1));
        }
        None => line.push_str(", never calibrated"),
    }
    match &run.grasp {
        Some(grasp) => line.push_str(&grasp_summary(grasp)),
        None => line.push_str("; no grasp"),
    }
    line
}

fn grasp_summary(grasp: &GraspRecord) -> String {
    let mut text = String::from("; estimate error at grasp ");
    match grasp.estimate_error_m {
        Some([x, y, z]) => {
            let _ = write!(
                text,
                "X {} Y {} Z {} mm",
                fixed(Some(x * 1000.0), 1),
                fixed(Some(y * 1000.0), 1),
                fixed(Some(z * 1000.0), 1)
            );
        }
        None => text.push_str("n/a"),
    }
    if let Some(yaw) = grasp.estimate_yaw_error_rad {
        let _ = write!(
            text,
            ", yaw {} deg",
            fixed(Some(wrap_angle_rad(yaw).to_degrees()), 2)
        );
    }
    let _ = write!(
        text,
        "; grasp error {} mm",
        fixed(Some(norm(grasp.position_error_m) * 1000.0), 1)
    );
    text
}

/// `value` with `decimals` digits, `-` when absent or not finite.
fn fixed(value: Option<f64>, decimals: usize) -> String {
    match value {
        Some(v) if v.is_finite() => format!("{v:.decimals$}"),
        _ => "-".to_owned(),
    }
}

/// Shortest text that reads back to the same f64 (`NaN`, `inf` kept as such).
fn number(value: f64) -> String {
    format!("{value}")
}

fn optional(value: Option<f64>) -> String {
    value.map(number).unwrap_or_default()
}

fn csv_line(cells: &[String]) -> String {
    let mut line = cells.join(",");
    line.push('\n');
    line
}

fn norm(v: [f64; 3]) -> f64 {
    v.iter().map(|c| c * c).sum::<f64>().sqrt()
}

/// An angle difference brought into (-pi, pi], so that a yaw error near the
/// wrap reads as the small error it is.
pub(crate) fn wrap_angle_rad(angle: f64) -> f64 {
    shared::calibration::effector::wrap_angle(angle)
}

/// The link's figures of a run, when anything went wrong on it (a noisy line,
/// resends): what was damaged, what each side refused, and that the
/// controller's telemetry counted every refusal.
pub fn link_line(run: &PickRun) -> Option<String> {
    let link = &run.link;
    let noise = link
        .noise
        .filter(|n| n.to_controller.damaged_bytes() + n.to_host.damaged_bytes() > 0);
    if noise.is_none() && link.samples_resent == 0 && link.replies_refused == 0 {
        return None;
    }
    let mut line = format!(
        "link: {} samples sent again, {} stale commands, {} session resends; \
         the controller refused {} frames (telemetry), the host {}",
        link.samples_resent,
        link.stale_commands,
        link.session_resends,
        link.controller_frames_rejected,
        link.replies_refused
    );
    if let Some(n) = noise {
        let (up, down) = (n.to_controller, n.to_host);
        line.push_str(&format!(
            "; noise: {} of {} bytes damaged to the controller ({} of {} frames lost, {} refusals), \
             {} of {} to the host ({} of {} frames lost, {} refusals); forged frames: {}; \
             telemetry counted every refusal in {} of {} messages",
            up.damaged_bytes(),
            up.bytes,
            up.frames_sent - up.frames_delivered.min(up.frames_sent),
            up.frames_sent,
            up.frames_rejected,
            down.damaged_bytes(),
            down.bytes,
            down.frames_sent - down.frames_delivered.min(down.frames_sent),
            down.frames_sent,
            down.frames_rejected,
            up.forged + down.forged,
            n.telemetry.checked - n.telemetry.mismatched.min(n.telemetry.checked),
            n.telemetry.checked
        ));
    }
    Some(line)
}

/// A synthetic pick of `records` samples at 100 Hz, for the tests, the
/// benchmark of the figures and a look at the outputs without a simulation: the
/// part turns on the disc, the estimate (with a small bias and ripple) appears
/// at calibration, the tool closes in and grasps. Nothing here is a result of
/// the controller.
#[doc(hidden)]
pub fn synthetic_run(experiment: &str, records: usize) -> PickRun {
    use super::record::PhaseEvent;
    use crate::world::CellLayout;
    use shared::protocol::CalibrationReport;

    let period_s = 0.01;
    let duration_s = records as f64 * period_s;
    let phase_starts = [
        (0.0, PickPhase::SearchEffector),
        (0.2, PickPhase::CalibrateBase),
        (0.3, PickPhase::Locate),
        (0.4, PickPhase::Intercept),
        (0.55, PickPhase::Track),
        (0.65, PickPhase::Descend),
        (0.7, PickPhase::Grasp),
        (0.75, PickPhase::Lift),
        (0.85, PickPhase::Return),
    ];
    let phase_at = |fraction: f64| {
        phase_starts
            .iter()
            .take_while(|(start, _)| *start <= fraction)
            .last()
            .map_or(PickPhase::Idle, |&(_, phase)| phase)
    };
    let disc_centre = [0.6, -0.2, -0.3];
    let radius = 0.25;
    let omega = 0.5;
    let calibrated_after_s = 0.3 * duration_s;
    let grasp_t_s = 0.72 * duration_s;
    let records: Vec<TickRecord> = (0..records)
        .map(|i| {
            let t_s = i as f64 * period_s;
            let theta = omega * t_s;
            let part = [
                disc_centre[0] + radius * theta.cos(),
                disc_centre[1] + radius * theta.sin(),
                disc_centre[2] + 0.04,
            ];
            let calibrated = t_s >= calibrated_after_s;
            let ripple = (7.0 * t_s).sin();
            let estimate = calibrated.then(|| {
                [
                    part[0] + 0.004 + 0.002 * ripple,
                    part[1] - 0.003 + 0.002 * ripple,
                    part[2] + 0.001,
                ]
            });
            let fraction = t_s / duration_s.max(period_s);
            let approach = ((fraction - 0.4) / 0.3).clamp(0.0, 1.0);
            let ready = [0.4, 0.1, 0.2];
            let tool: [f64; 3] = core::array::from_fn(|k| {
                let target = part.get(k).copied().unwrap_or_default();
                let start = ready.get(k).copied().unwrap_or_default();
                start + (target - start) * approach
            });
            let q_rad = core::array::from_fn(|j| 0.1 * j as f64 + 0.2 * (t_s + j as f64).sin());
            TickRecord {
                t_s,
                phase: phase_at(fraction),
                part_true_base_m: part,
                part_true_yaw_rad: wrap_angle_rad(theta + 0.3),
                part_est_base_m: estimate,
                part_est_yaw_rad: calibrated.then(|| wrap_angle_rad(theta + 0.3 + 0.02 * ripple)),
                part_sigma_m: if calibrated { 0.003 } else { 0.0 },
                tool_true_base_m: tool,
                tool_true_yaw_rad: wrap_angle_rad(theta),
                tool_ref_base_m: tool.map(|c| c + 0.001 * ripple),
                tool_ref_yaw_rad: wrap_angle_rad(theta + 0.01),
                theta_true_rad: theta,
                theta_est_wrapped_rad: wrap_angle_rad(theta + 0.001),
                omega_true_rad_s: omega,
                omega_est_rad_s: omega * 1.001,
                q_rad,
                qd_rad_s: q_rad.map(|q| 0.5 * q),
                tau_nm: q_rad.map(|q| 10.0 * q),
            }
        })
        .collect();
    let phases = phase_starts
        .iter()
        .map(|&(fraction, phase)| PhaseEvent {
            t_s: fraction * duration_s,
            phase,
        })
        .collect();
    let calibration = CalibrationRecord {
        t_s: calibrated_after_s,
        report: CalibrationReport {
            time_us: (calibrated_after_s * 1e6) as u64,
            camera_height_m: 1.52,
            camera_tilt_rad: 0.01,
            base_yaw_rad: 0.105,
            base_translation_m: [0.601, -0.198, -0.302],
            part_rotating_m: [0.25, 0.0, 0.04],
            part_yaw_rotating_rad: 0.3,
            sigma_part_m: 0.003,
            sigma_base_m: 0.002,
            sigma_base_yaw_rad: 0.004,
            frames_used: 120,
            effector_frames_used: 30,
            rms_reprojection_px: 0.8,
        },
        true_camera_height_m: 1.5,
        true_base_yaw_rad: 0.1,
        true_base_translation_m: [0.6, -0.2, -0.3],
    };
    PickRun {
        experiment: experiment.to_owned(),
        seed: 7,
        layout: CellLayout {
            disc_centre_base_m: disc_centre,
            disc_radius_m: 0.4,
            camera_centre_base_m: [0.6, -0.2, 1.2],
            drop_off_base_m: [0.1, 0.5, 0.0],
        },
        records,
        phases,
        calibrations: vec![calibration],
        grasp: Some(GraspRecord {
            t_s: grasp_t_s,
            succeeded: true,
            position_error_m: [0.003, 0.004, 0.0],
            yaw_error_rad: 0.01,
            relative_speed_m_s: 0.002,
            estimate_error_m: Some([0.01234, -0.00456, 0.0021]),
            estimate_yaw_error_rad: Some(2.0_f64.to_radians()),
        }),
        result: PickResult::Success,
        placed_error_m: Some(0.004),
        calibrated_after_s: Some(calibrated_after_s),
        duration_s,
        max_speed_ratio: 0.6,
        max_torque_ratio: 0.7,
        min_tool_clearance_m: 0.02,
        end_joint_speed_rad_s: 0.0,
        link: Default::default(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(path: &Path) -> Vec<String> {
        fs::read_to_string(path)
            .expect("read csv")
            .lines()
            .map(str::to_owned)
            .collect()
    }

    /// Width and height from a PNG's IHDR chunk, after checking the signature.
    fn png_size(path: &Path) -> (u32, u32) {
        let bytes = fs::read(path).expect("read png");
        assert_eq!(
            bytes.get(..8),
            Some(&[0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a][..]),
            "{} is not a PNG",
            path.display()
        );
        assert_eq!(bytes.get(12..16), Some(&b"IHDR"[..]));
        let word = |at: usize| {
            let b: [u8; 4] = bytes.get(at..at + 4).expect("ihdr").try_into().expect("4");
            u32::from_be_bytes(b)
        };
        (word(16), word(20))
    }

    fn expected_files(dir: &Path) -> Vec<PathBuf> {
        [
            "timeseries.csv",
            "phases.csv",
            "calibration.csv",
            "grasp.csv",
            "part_pose.png",
            "part_pose_error.png",
            "tracking_error.png",
            "top_view.png",
        ]
        .iter()
        .map(|name| dir.join(name))
        .collect()
    }

    fn check_pngs(dir: &Path) {
        for (name, size) in [
            ("part_pose.png", plots::PART_POSE_SIZE),
            ("part_pose_error.png", plots::PART_POSE_ERROR_SIZE),
            ("tracking_error.png", plots::TRACKING_ERROR_SIZE),
            ("top_view.png", plots::TOP_VIEW_SIZE),
        ] {
            assert_eq!(png_size(&dir.join(name)), size, "{name}");
        }
    }

    #[test]
    fn writes_every_file_with_headers_and_row_counts() {
        let tmp = tempfile::tempdir().expect("tempdir");
        let run = synthetic_run("experiment-1", 400);
        let written = write_run_outputs(&run, tmp.path()).expect("write outputs");
        let dir = tmp.path().join("experiment-1");
        assert_eq!(written, expected_files(&dir));
        assert!(written.iter().all(|p| p.is_file()));

        let timeseries = lines(&dir.join("timeseries.csv"));
        assert_eq!(timeseries.len(), 401);
        let header: Vec<&str> = timeseries[0].split(',').collect();
        assert_eq!(header.len(), 41);
        assert_eq!(header, timeseries_header());
        for column in [
            "t_s",
            "phase",
            "part_true_x_m",
            "part_est_yaw_rad",
            "q6_rad",
            "tau1_nm",
        ] {
            assert!(header.contains(&column), "{column} missing");
        }
        assert!(timeseries.iter().all(|row| row.split(',').count() == 41));
        // Before calibration the estimate is an empty cell; the phase is named.
        let first: Vec<&str> = timeseries[1].split(',').collect();
        assert_eq!(first[1], "SearchEffector");
        assert_eq!(first[6], "");
        let last: Vec<&str> = timeseries[400].split(',').collect();
        assert_eq!(last[1], "Return");
        let est_x: f64 = last[6].parse().expect("estimate x");
        assert!((est_x - run.records[399].part_est_base_m.expect("est")[0]).abs() < 1e-15);

        let phases = lines(&dir.join("phases.csv"));
        assert_eq!(phases.len(), run.phases.len() + 1);
        assert_eq!(phases[0], "phase,start_s,end_s,duration_s");
        assert!(phases[1].starts_with("SearchEffector,0,"));

        let calibration = lines(&dir.join("calibration.csv"));
        assert_eq!(calibration.len(), 1 + 13);
        assert_eq!(
            calibration[0],
            "calibration,t_s,quantity,estimate,truth,error,sigma"
        );
        let height: Vec<&str> = calibration[1].split(',').collect();
        assert_eq!(height[2], "camera_height_m");
        let error: f64 = height[5].parse().expect("height error");
        assert!((error - 0.02).abs() < 1e-6, "height error {error}");

        let grasp = lines(&dir.join("grasp.csv"));
        assert_eq!(grasp.len(), 2);
        assert!(grasp[0].starts_with("t_s,succeeded,position_error_x_m"));
        assert_eq!(grasp[0].split(',').count(), grasp[1].split(',').count());
        assert!(grasp[1].contains(",true,") && grasp[1].contains(",success,"));

        check_pngs(&dir);
    }

    #[test]
    fn an_empty_run_writes_without_panicking() {
        let tmp = tempfile::tempdir().expect("tempdir");
        let mut run = synthetic_run("empty run", 0);
        run.phases.clear();
        run.calibrations.clear();
        run.grasp = None;
        run.result = PickResult::TimedOut(PickPhase::Idle);
        run.calibrated_after_s = None;
        let written = write_run_outputs(&run, tmp.path()).expect("write outputs");
        let dir = tmp.path().join("empty_run");
        assert_eq!(written, expected_files(&dir));
        assert_eq!(lines(&dir.join("timeseries.csv")).len(), 1);
        assert_eq!(lines(&dir.join("phases.csv")).len(), 1);
        assert_eq!(lines(&dir.join("calibration.csv")).len(), 1);
        assert_eq!(lines(&dir.join("grasp.csv")).len(), 1);
        check_pngs(&dir);
        let table = results_table(&[run]);
        assert!(table.contains(
            "| empty run | not reported | - | - | - | - | - | timed out in Idle | - | 0.0 |"
        ));
    }

    #[test]
    fn non_finite_samples_are_skipped_not_drawn() {
        let tmp = tempfile::tempdir().expect("tempdir");
        let mut run = synthetic_run("experiment-2-7cm", 300);
        for (i, record) in run.records.iter_mut().enumerate() {
            if i % 7 == 0 {
                record.part_true_base_m[0] = f64::NAN;
                record.part_est_yaw_rad = Some(f64::INFINITY);
                record.tool_true_base_m = [f64::NAN; 3];
                record.part_sigma_m = f64::NAN;
            }
        }
        run.layout.camera_centre_base_m = [f64::NAN; 3];
        run.duration_s = f64::NAN;
        write_run_outputs(&run, tmp.path()).expect("write outputs");
        check_pngs(&tmp.path().join("experiment-2-7cm"));
    }

    #[test]
    fn a_long_run_is_decimated_and_still_written() {
        let tmp = tempfile::tempdir().expect("tempdir");
        let run = synthetic_run("long", 3 * plots::MAX_POINTS + 17);
        write_run_outputs(&run, tmp.path()).expect("write outputs");
        assert_eq!(
            lines(&tmp.path().join("long").join("timeseries.csv")).len(),
            3 * plots::MAX_POINTS + 18
        );
        check_pngs(&tmp.path().join("long"));
    }

    #[test]
    fn results_table_rounds_and_names_the_paper_figure() {
        let runs = [
            synthetic_run("experiment-1", 200),
            synthetic_run("experiment-2-4cm", 200),
            synthetic_run("experiment-2-7cm", 200),
            synthetic_run("turning", 200),
        ];
        let table = results_table(&runs);
        let rows: Vec<&str> = table.lines().collect();
        assert_eq!(rows.len(), 2 + runs.len());
        assert!(rows[0].starts_with("| experiment | paper | est. X (mm)"));
        // estimate error [12.34, -4.56, 2.1] mm, yaw 2 deg, grasp |(3, 4, 0)| = 5 mm,
        // calibrated at 0.3 * 2 s, total 2 s.
        let ours = "| 12.3 | -4.6 | 2.1 | 2.00 | 5.0 | success | 0.6 | 2.0 |";
        assert_eq!(
            rows[2],
            format!("| experiment-1 | X, Y ~10 mm; yaw < 5 deg (Figs 4-5) {ours}")
        );
        assert_eq!(
            rows[3],
            format!("| experiment-2-4cm | not reported (Figs 6-7 plots only) {ours}")
        );
        assert_eq!(
            rows[4],
            format!("| experiment-2-7cm | X, Y <= 10 mm; yaw < 5 deg (Figs 8-9) {ours}")
        );
        assert_eq!(rows[5], format!("| turning | not reported {ours}"));
    }

    #[test]
    fn summary_line_reports_result_times_and_errors() {
        let run = synthetic_run("experiment-1", 200);
        assert_eq!(
            summary_line(&run),
            "experiment-1 (seed 7): success after 2.0 s, calibrated at 0.6 s; \
             estimate error at grasp X 12.3 Y -4.6 Z 2.1 mm, yaw 2.00 deg; grasp error 5.0 mm"
        );
        let mut failed = run;
        failed.grasp = None;
        failed.calibrated_after_s = None;
        failed.result = PickResult::Fault(shared::protocol::FaultCause::TrackingError);
        assert_eq!(
            summary_line(&failed),
            "experiment-1 (seed 7): fault: TrackingError after 2.0 s, never calibrated; no grasp"
        );
    }

    #[test]
    fn directory_names_cannot_leave_the_output_folder() {
        assert_eq!(directory_name("../etc"), "___etc");
        assert_eq!(directory_name(""), "run");
        assert_eq!(directory_name("experiment-2-7cm"), "experiment-2-7cm");
    }
}
