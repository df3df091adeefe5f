//! The accuracy run's outputs: the markdown report (the summaries against the
//! targets, the effector-count sweep, the tilt breakdown, the uncertainty
//! coverage), a per-trial CSV and the JSON summary.

use std::fmt::Write as _;
use std::fs;
use std::path::Path;

use anyhow::Context;

use super::harness::{Method, TrialOutcome};
use super::metrics::{ErrorMetrics, METRIC_COLUMNS};
use super::stats::{median, percentile};
use super::summary::{finite, target_met, MetricSummary, SummaryRow, TARGETS};
use crate::calibration::PART_SIGMA_WARNING_M;

fn cell(value: Option<f64>) -> String {
    match value {
        Some(v) if v < 0.01 => format!("{v:.2e}"),
        Some(v) if v < 100.0 => format!("{v:.3}"),
        Some(v) => format!("{v:.1}"),
        None => "fail".to_string(),
    }
}

fn median_p95(summary: Option<&MetricSummary>) -> String {
    summary.map_or("-".to_string(), |m| {
        format!("{} / {}", cell(m.median), cell(m.p95))
    })
}

/// Effector-sweep rows are scenarios named `FAMILY/effector-N`.
fn effector_count(scenario: &str) -> Option<usize> {
    scenario.split_once("/effector-")?.1.parse().ok()
}

/// Camera-tilt bins of the tilt breakdown, degrees.
const TILT_BINS_DEG: [(f64, f64); 3] = [(0.0, 10.0), (10.0, 20.0), (20.0, 35.0 + 1e-9)];

/// The part's errors (refined) by camera tilt, over the trials of `scenarios`
/// (which should share one noise model); empty bins are left out.
fn tilt_breakdown(out: &mut String, outcomes: &[TrialOutcome], scenarios: &[&str]) {
    let of_scenarios: Vec<&TrialOutcome> = outcomes
        .iter()
        .filter(|o| scenarios.contains(&o.scenario.as_str()))
        .collect();
    if of_scenarios.is_empty() {
        return;
    }
    let _ = writeln!(
        out,
        "\n## {}: refined part errors by camera tilt\n\nNear a vertical view the camera's tilt and \
         offset look alike, so feature heights (and with them the part position) are weakly observable.\n",
        scenarios.join(" + ")
    );
    let _ = writeln!(
        out,
        "| camera tilt | trials | feature_mm | part_position_mm | camera_height_mm |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|");
    for (low, high) in TILT_BINS_DEG {
        let in_bin: Vec<&Result<ErrorMetrics, String>> = of_scenarios
            .iter()
            .filter(|o| (low..high).contains(&o.camera_tilt_deg))
            .map(|o| &o.refined)
            .collect();
        if in_bin.is_empty() {
            continue;
        }
        let summary = |value: fn(&ErrorMetrics) -> f64| {
            let values: Vec<f64> = in_bin
                .iter()
                .map(|r| r.as_ref().map_or(f64::INFINITY, value))
                .collect();
            format!(
                "{} / {}",
                cell(finite(median(&values))),
                cell(finite(percentile(&values, 0.95)))
            )
        };
        let _ = writeln!(
            out,
            "| {low:.0} to {:.0} deg | {} | {} | {} | {} |",
            high.floor(),
            in_bin.len(),
            summary(|m| m.feature_mm),
            summary(|m| m.part_position_mm),
            summary(|m| m.camera_height_mm)
        );
    }
}

/// Whether the refined estimate's reported part-position sigma covers its actual
/// error, per scenario: the error in sigmas, and how often `calibrate` would warn.
fn uncertainty_coverage(out: &mut String, outcomes: &[TrialOutcome], rows: &[SummaryRow]) {
    let _ = writeln!(
        out,
        "\n## Refined part position: reported 1-sigma against the actual error\n\n\
         `near-axis` (camera tilted 0 to 10 degrees, the paper scenario's noise) has no 2 mm target: \
         there the feature heights are poorly observable, and what is required is that the reported \
         sigma covers the error and that `calibrate` warns (sigma above {:.0} mm). `noise-free` is left \
         out: its errors are the solver's convergence tolerance, not the effect of noise.\n",
        PART_SIGMA_WARNING_M * 1000.0
    );
    let _ = writeln!(
        out,
        "| scenario | trials | part_position_mm | reported sigma (mm) | error / sigma | error > 3 sigma | warned |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|");
    for row in rows.iter().filter(|r| {
        r.method == Method::Refined
            && effector_count(&r.scenario).is_none()
            && r.scenario != "noise-free"
    }) {
        let of_scenario: Vec<&TrialOutcome> = outcomes
            .iter()
            .filter(|o| o.scenario == row.scenario)
            .collect();
        let pairs: Vec<(f64, f64)> = of_scenario
            .iter()
            .filter_map(|o| {
                let error = o.refined.as_ref().ok()?.part_position_mm;
                Some((error, o.refined_part_sigma_mm?))
            })
            .collect();
        let spread = |values: Vec<f64>| {
            format!(
                "{} / {}",
                cell(finite(median(&values))),
                cell(finite(percentile(&values, 0.95)))
            )
        };
        let ratios: Vec<f64> = pairs.iter().map(|(e, s)| e / s).collect();
        let beyond_3_sigma = ratios.iter().filter(|r| r.is_nan() || **r > 3.0).count();
        let warned = pairs
            .iter()
            .filter(|(_, s)| !s.is_finite() || *s > PART_SIGMA_WARNING_M * 1000.0)
            .count();
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} |",
            row.scenario,
            of_scenario.len(),
            spread(pairs.iter().map(|(e, _)| *e).collect()),
            spread(pairs.iter().map(|(_, s)| *s).collect()),
            spread(ratios),
            beyond_3_sigma,
            warned
        );
    }
}

/// Metrics of the maximum-likelihood comparison.
const LIMIT_METRICS: [&str; 6] = [
    "part_position_mm",
    "part_yaw_deg",
    "camera_height_mm",
    "base_translation_mm",
    "base_yaw_deg",
    "part_in_base_mm",
];

/// The calibrator (refined) beside the batch solve over every frame, per
/// scenario that ran both: median / 95th of each, the ratio of the 95th
/// percentiles (calibrator / batch; 1 is the maximum-likelihood limit) and,
/// paired on the same logs, the median of the per-trial ratio of the errors.
fn maximum_likelihood_limit(out: &mut String, rows: &[SummaryRow], outcomes: &[TrialOutcome]) {
    let pairs: Vec<(&SummaryRow, &SummaryRow)> = rows
        .iter()
        .filter(|r| r.method == Method::Batch)
        .filter_map(|batch| {
            let refined = rows
                .iter()
                .find(|r| r.scenario == batch.scenario && r.method == Method::Refined)?;
            Some((refined, batch))
        })
        .collect();
    if pairs.is_empty() {
        return;
    }
    let _ = writeln!(
        out,
        "\n## The maximum-likelihood limit: the calibrator against a batch solve over every frame\n\n\
         The batch solve (`host_sim::batch_ml`) minimises the squared reprojection errors of every \
         frame and every end-effector sighting (no thinning, f64 pixels; points beyond 5 robust \
         sigmas gated), started from the calibrator's estimate. 95th ratio: the calibrator's 95th \
         percentile over the batch's. Paired ratio: the median over the trials of the calibrator's \
         error over the batch's on the same log.\n"
    );
    let _ = writeln!(
        out,
        "| scenario | metric | calibrator | batch | 95th ratio | paired ratio |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|");
    for (refined, batch) in pairs {
        for metric in LIMIT_METRICS {
            let (Some(calibrator), Some(limit), Some(column)) = (
                refined.metric(metric),
                batch.metric(metric),
                METRIC_COLUMNS.iter().find(|c| c.name == metric),
            ) else {
                continue;
            };
            let ratio = match (calibrator.p95, limit.p95) {
                (Some(a), Some(b)) if b > 0.0 => format!("{:.2}", a / b),
                _ => "-".to_string(),
            };
            let paired: Vec<f64> = outcomes
                .iter()
                .filter(|o| o.scenario == batch.scenario)
                .map(|o| match (&o.refined, &o.batch) {
                    (Ok(a), Some(Ok(b))) => (column.value)(a) / (column.value)(b),
                    _ => f64::INFINITY,
                })
                .collect();
            let paired = match finite(median(&paired)) {
                Some(value) => format!("{value:.2}"),
                None => "-".to_string(),
            };
            let _ = writeln!(
                out,
                "| {} | {} | {} | {} | {} | {} |",
                batch.scenario,
                metric,
                median_p95(Some(calibrator)),
                median_p95(Some(limit)),
                ratio,
                paired
            );
        }
    }
}

/// The markdown report; `notes` are extra lines under the title (e.g. the estimator's settings).
pub fn markdown(
    rows: &[SummaryRow],
    outcomes: &[TrialOutcome],
    trials: usize,
    seed: u64,
    notes: &[String],
) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "# Self-calibration accuracy ({trials} random workcells per scenario, seed {seed})\n"
    );
    let _ = writeln!(
        out,
        "Cells: median / 95th percentile over the trials; a failed calibration counts as an \
         infinite error (`fail` when it reaches the percentile).\n"
    );
    for note in notes {
        let _ = writeln!(out, "{note}\n");
    }
    let headers: Vec<String> = METRIC_COLUMNS.iter().map(|c| c.name.to_string()).collect();
    let _ = writeln!(
        out,
        "| scenario | method | failures | {} |",
        headers.join(" | ")
    );
    let _ = writeln!(out, "|---|---|---|{}", "---|".repeat(headers.len()));
    for row in rows
        .iter()
        .filter(|r| effector_count(&r.scenario).is_none())
    {
        let cells: Vec<String> = METRIC_COLUMNS
            .iter()
            .map(|c| median_p95(row.metric(c.name)))
            .collect();
        let _ = writeln!(
            out,
            "| {} | {} | {}/{} | {} |",
            row.scenario,
            row.method.name(),
            row.failures,
            row.trials,
            cells.join(" | ")
        );
    }

    let _ = writeln!(out, "\n## Targets (refined estimate, 95th percentile)\n");
    let _ = writeln!(out, "| scenario | metric | target | measured | met |");
    let _ = writeln!(out, "|---|---|---|---|---|");
    for target in &TARGETS {
        if let Some((p95, met)) = target_met(rows, target) {
            let _ = writeln!(
                out,
                "| {} | {} | < {} | {} | {} |",
                target.scenario,
                target.metric,
                target.p95_below,
                cell(Some(p95).filter(|v| v.is_finite())),
                if met { "yes" } else { "NO" }
            );
        }
    }

    let sweep: Vec<&SummaryRow> = rows
        .iter()
        .filter(|r| effector_count(&r.scenario).is_some())
        .collect();
    if !sweep.is_empty() {
        let _ = writeln!(
            out,
            "\n## Base pose against the number of frames showing the end effector\n"
        );
        let _ = writeln!(
            out,
            "| scenario | method | failures | base_translation_mm | base_yaw_deg |"
        );
        let _ = writeln!(out, "|---|---|---|---|---|");
        for row in sweep {
            let _ = writeln!(
                out,
                "| {} | {} | {}/{} | {} | {} |",
                row.scenario,
                row.method.name(),
                row.failures,
                row.trials,
                median_p95(row.metric("base_translation_mm")),
                median_p95(row.metric("base_yaw_deg"))
            );
        }
    }

    maximum_likelihood_limit(&mut out, rows, outcomes);
    tilt_breakdown(&mut out, outcomes, &["paper", "near-axis"]);
    uncertainty_coverage(&mut out, outcomes, rows);

    let failures: Vec<&SummaryRow> = rows.iter().filter(|r| r.failures > 0).collect();
    if !failures.is_empty() {
        let _ = writeln!(out, "\n## First failure per scenario and method\n");
        for row in failures {
            let _ = writeln!(
                out,
                "- {} / {}: {}",
                row.scenario,
                row.method.name(),
                row.first_failure.as_deref().unwrap_or("?")
            );
        }
    }
    out
}

fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

/// One row per trial and method; failed rows leave the metric columns empty.
pub fn trials_csv(outcomes: &[TrialOutcome]) -> String {
    let mut out =
        String::from("scenario,trial,seed,effector_frames,camera_tilt_deg,refined_part_sigma_mm,method,status,message");
    for column in &METRIC_COLUMNS {
        out.push(',');
        out.push_str(column.name);
    }
    out.push('\n');
    for outcome in outcomes {
        for method in Method::ALL {
            let Some(errors) = outcome.errors(method) else {
                continue;
            };
            let (status, message, values) = match errors {
                Ok(errors) => (
                    "ok",
                    String::new(),
                    METRIC_COLUMNS
                        .iter()
                        .map(|c| format!("{:.9}", (c.value)(errors)))
                        .collect::<Vec<_>>(),
                ),
                Err(message) => (
                    "failed",
                    message.clone(),
                    vec![String::new(); METRIC_COLUMNS.len()],
                ),
            };
            let _ = writeln!(
                out,
                "{},{},{},{},{:.3},{},{},{},{},{}",
                csv_field(&outcome.scenario),
                outcome.trial,
                outcome.seed,
                outcome.effector_frames,
                outcome.camera_tilt_deg,
                outcome
                    .refined_part_sigma_mm
                    .map_or(String::new(), |s| format!("{s:.6}")),
                method.name(),
                status,
                csv_field(&message),
                values.join(",")
            );
        }
    }
    out
}

/// Writes `report.md`, `trials.csv` and `summary.json` into `directory` (created if needed).
pub fn write_outputs(
    directory: &Path,
    report: &str,
    rows: &[SummaryRow],
    outcomes: &[TrialOutcome],
) -> anyhow::Result<()> {
    fs::create_dir_all(directory)
        .with_context(|| format!("cannot create output folder {}", directory.display()))?;
    let write = |name: &str, text: &str| {
        let path = directory.join(name);
        fs::write(&path, text).with_context(|| format!("cannot write {}", path.display()))
    };
    write("report.md", report)?;
    write("trials.csv", &trials_csv(outcomes))?;
    let json = serde_json::to_string_pretty(rows).context("serialising the summary")?;
    write("summary.json", &json)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accuracy::summary::summarise;

    fn errors(scale: f64) -> ErrorMetrics {
        ErrorMetrics {
            feature_mm: scale,
            part_position_mm: scale,
            part_yaw_deg: scale / 10.0,
            camera_height_mm: scale,
            camera_rotation_deg: scale / 10.0,
            base_translation_mm: scale,
            base_yaw_deg: scale / 100.0,
            part_in_base_mm: scale,
        }
    }

    fn outcome(
        scenario: &str,
        trial: usize,
        refined: Result<ErrorMetrics, String>,
    ) -> TrialOutcome {
        TrialOutcome {
            scenario: scenario.to_string(),
            trial,
            seed: trial as u64,
            effector_frames: 7,
            camera_tilt_deg: 12.0,
            refined_part_sigma_mm: refined.as_ref().ok().map(|e| e.part_position_mm / 2.0),
            refined,
            paper: Ok(errors(10.0)),
            batch: None,
        }
    }

    #[test]
    fn failures_count_as_infinite_errors_in_the_summary() {
        let outcomes = [
            outcome("paper", 0, Ok(errors(1.0))),
            outcome("paper", 1, Ok(errors(3.0))),
            outcome("paper", 2, Err("no ellipse, frame 4".to_string())),
        ];
        let rows = summarise(&outcomes);
        assert_eq!(rows.len(), 2);
        let refined = &rows[0];
        assert_eq!(
            (refined.method, refined.trials, refined.failures),
            (Method::Refined, 3, 1)
        );
        assert_eq!(
            refined.first_failure.as_deref(),
            Some("no ellipse, frame 4")
        );
        let position = refined.metric("part_position_mm").expect("metric");
        assert_eq!(position.median, Some(3.0));
        assert_eq!(position.p95, None);
        let target = &TARGETS[0];
        assert_eq!(target_met(&rows, target), Some((f64::INFINITY, false)));
        assert_eq!(
            rows[1].metric("part_position_mm").and_then(|m| m.p95),
            Some(10.0)
        );

        let report = markdown(&rows, &outcomes, 3, 1, &[]);
        assert!(
            report.contains("| paper | refined | 1/3 | 3.000 / fail |"),
            "{report}"
        );
        assert!(
            report.contains("| paper | part_position_mm | < 2 | fail | NO |"),
            "{report}"
        );
        assert!(report.contains("- paper / refined: no ellipse, frame 4"));
        assert!(
            !report.contains("end effector\n"),
            "no sweep section without sweep rows"
        );
    }

    #[test]
    fn the_batch_rows_and_the_limit_section_appear_only_when_the_batch_ran() {
        let without = [outcome("paper", 0, Ok(errors(2.0)))];
        let report = markdown(&summarise(&without), &without, 1, 1, &[]);
        assert!(!report.contains("| paper | batch |"), "{report}");
        assert!(!report.contains("maximum-likelihood limit"), "{report}");
        let mut with = outcome("paper", 0, Ok(errors(2.0)));
        with.batch = Some(Ok(errors(1.0)));
        let outcomes = [with];
        let rows = summarise(&outcomes);
        assert_eq!(rows.len(), 3);
        let report = markdown(&rows, &outcomes, 1, 1, &[]);
        assert!(report.contains("| paper | batch | 0/1 |"), "{report}");
        assert!(
            report.contains(
                "| paper | part_position_mm | 2.000 / 2.000 | 1.000 / 1.000 | 2.00 | 2.00 |"
            ),
            "{report}"
        );
        assert_eq!(trials_csv(&outcomes).lines().count(), 4);
    }

    #[test]
    fn csv_has_one_row_per_trial_and_method_with_quoted_messages() {
        let outcomes = [
            outcome("paper/effector-5", 0, Ok(errors(2.0))),
            outcome(
                "paper/effector-5",
                1,
                Err("frame 3: \"x\", bad".to_string()),
            ),
        ];
        let csv = trials_csv(&outcomes);
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines.len(), 5);
        let columns = lines[0].split(',').count();
        assert_eq!(columns, 9 + METRIC_COLUMNS.len());
        assert!(
            lines[1].starts_with("paper/effector-5,0,0,7,12.000,1.000000,refined,ok,,2.000000000,")
        );
        assert!(
            lines[3].contains(",refined,failed,\"frame 3: \"\"x\"\", bad\","),
            "{}",
            lines[3]
        );
        let report = markdown(&summarise(&outcomes), &outcomes, 2, 1, &[]);
        assert!(
            report.contains("| paper/effector-5 | refined | 1/2 |"),
            "{report}"
        );
    }

    #[test]
    fn coverage_section_counts_errors_beyond_3_sigma_and_warnings() {
        let mut wide = outcome("near-axis", 2, Ok(errors(12.0)));
        wide.refined_part_sigma_mm = Some(3.0);
        let outcomes = [
            outcome("near-axis", 0, Ok(errors(10.0))),
            outcome("near-axis", 1, Ok(errors(14.0))),
            wide,
            outcome("near-axis", 3, Err("no ellipse".to_string())),
        ];
        let report = markdown(&summarise(&outcomes), &outcomes, 4, 1, &[]);
        // Sigmas 5, 7 and 3 mm: one error beyond 3 sigma (12 / 3), one sigma over 5 mm.
        let line = report
            .lines()
            .find(|l| l.starts_with("| near-axis | 4 |"))
            .unwrap_or_else(|| panic!("{report}"));
        assert!(line.ends_with("| 1 | 1 |"), "{line}");
        assert!(report.contains("`near-axis` (camera tilted 0 to 10 degrees"));
        assert!(report.contains("## paper + near-axis: refined part errors by camera tilt"));
        assert!(report.contains("| 10 to 20 deg | 4 |"), "{report}");
        assert!(!report.contains("| 0 to 10 deg"), "empty bins are left out");
        let noise_free = [outcome("noise-free", 0, Ok(errors(1e-5)))];
        let report = markdown(&summarise(&noise_free), &noise_free, 1, 1, &[]);
        assert!(!report.contains("| noise-free | 1 |"), "{report}");
    }
}
