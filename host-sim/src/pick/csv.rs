//! The CSV files of one pick: `timeseries.csv` (truth beside the controller's
//! telemetry), `phases.csv`, `calibration.csv` (estimate beside truth) and
//! `grasp.csv` (the errors at the instant the gripper closed).

use super::record::{CalibrationRecord, PickRun, TickRecord};
use super::report::{norm, phase_name, result_name, wrap_angle_rad};

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

pub(crate) fn timeseries_csv(records: &[TickRecord]) -> String {
    let mut text = csv_line(&timeseries_header());
    for record in records {
        text.push_str(&csv_line(&timeseries_row(record)));
    }
    text
}

/// `phases.csv`: each phase the controller reported, when it started, when it
/// ended (the next event, or the run's end) and how long it lasted.
pub(crate) fn phases_csv(run: &PickRun) -> String {
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
pub(crate) fn calibration_csv(calibrations: &[CalibrationRecord]) -> String {
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
        let rows: [(&str, f64, Option<f64>, Option<f64>); 19] = [
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
            ("points_gated", f64::from(report.points_gated), None, None),
            ("frames_folded", f64::from(report.frames_folded), None, None),
            (
                "folds_discarded",
                f64::from(report.folds_discarded),
                None,
                None,
            ),
            (
                "sigma_grasp_horizontal_m",
                f64::from(report.sigma_grasp_horizontal_m),
                None,
                None,
            ),
            (
                "sigma_grasp_vertical_m",
                f64::from(report.sigma_grasp_vertical_m),
                None,
                None,
            ),
            (
                "sigma_grasp_yaw_rad",
                f64::from(report.sigma_grasp_yaw_rad),
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
pub(crate) fn grasp_csv(run: &PickRun) -> String {
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
