//! The pick's results in text: the markdown results table beside the paper's
//! reported figures (Section 5, Figs 4 to 9), a one-line summary for the
//! terminal, the link's figures, and the names and number formats the CSV
//! files and the PNG figures share.

use std::fmt::Write as _;

use shared::protocol::PickPhase;

use super::record::{GraspRecord, PickResult, PickRun};

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

pub(crate) fn norm(v: [f64; 3]) -> f64 {
    v.iter().map(|c| c * c).sum::<f64>().sqrt()
}

/// An angle difference brought into (-pi, pi], so that a yaw error near the
/// wrap reads as the small error it is.
pub(crate) fn wrap_angle_rad(angle: f64) -> f64 {
    shared::angle::wrap_pi(angle)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pick::synthetic::synthetic_run;

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
}
