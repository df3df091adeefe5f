//! Summaries of the Monte-Carlo outcomes: median and 95th percentile per
//! scenario, method and metric, and the accuracy targets.

use serde::Serialize;

use super::harness::{Method, TrialOutcome};
use super::metrics::{ErrorMetrics, METRIC_COLUMNS};
use super::stats::{median, percentile};

#[derive(Debug, Clone, Serialize)]
pub struct MetricSummary {
    pub metric: &'static str,
    pub unit: &'static str,
    /// `None` (JSON null) when infinite: more than half (or 5 %) of the trials failed.
    pub median: Option<f64>,
    pub p95: Option<f64>,
}

#[derive(Debug, Clone, Serialize)]
pub struct SummaryRow {
    pub scenario: String,
    pub method: Method,
    pub trials: usize,
    pub failures: usize,
    /// The first failure message, to start the diagnosis from.
    pub first_failure: Option<String>,
    pub metrics: Vec<MetricSummary>,
}

impl SummaryRow {
    pub fn metric(&self, name: &str) -> Option<&MetricSummary> {
        self.metrics.iter().find(|m| m.metric == name)
    }
}

pub(super) fn finite(value: Option<f64>) -> Option<f64> {
    value.filter(|v| v.is_finite())
}

/// Groups outcomes by scenario (in first-seen order) and method.
pub fn summarise(outcomes: &[TrialOutcome]) -> Vec<SummaryRow> {
    let mut scenarios: Vec<&str> = Vec::new();
    for outcome in outcomes {
        if !scenarios.contains(&outcome.scenario.as_str()) {
            scenarios.push(&outcome.scenario);
        }
    }
    scenarios
        .iter()
        .flat_map(|scenario| {
            Method::ALL.into_iter().filter_map(move |method| {
                let results: Vec<&Result<ErrorMetrics, String>> = outcomes
                    .iter()
                    .filter(|o| o.scenario == *scenario)
                    .filter_map(|o| o.errors(method))
                    .collect();
                if results.is_empty() {
                    // A method not run (the batch solve without `--batch`) has no row.
                    return None;
                }
                let metrics = METRIC_COLUMNS
                    .iter()
                    .map(|column| {
                        let values: Vec<f64> = results
                            .iter()
                            .map(|r| r.as_ref().map_or(f64::INFINITY, column.value))
                            .collect();
                        MetricSummary {
                            metric: column.name,
                            unit: column.unit,
                            median: finite(median(&values)),
                            p95: finite(percentile(&values, 0.95)),
                        }
                    })
                    .collect();
                Some(SummaryRow {
                    scenario: scenario.to_string(),
                    method,
                    trials: results.len(),
                    failures: results.iter().filter(|r| r.is_err()).count(),
                    first_failure: results.iter().find_map(|r| r.as_ref().err().cloned()),
                    metrics,
                })
            })
        })
        .collect()
}

/// A 95th-percentile target of the issue.
pub struct Target {
    pub scenario: &'static str,
    pub metric: &'static str,
    pub p95_below: f64,
}

/// Paper scenario: 2 mm part position, 0.8 deg part yaw, 5.5 mm camera height,
/// 15 mm base translation, 0.35 deg base yaw. Noise-free: every error below
/// 0.1 mm and 0.01 deg.
pub const TARGETS: [Target; 12] = [
    Target {
        scenario: "paper",
        metric: "part_position_mm",
        p95_below: 2.0,
    },
    Target {
        scenario: "paper",
        metric: "part_yaw_deg",
        p95_below: 0.8,
    },
    Target {
        scenario: "paper",
        metric: "camera_height_mm",
        p95_below: 5.5,
    },
    Target {
        scenario: "paper",
        metric: "base_translation_mm",
        p95_below: 15.0,
    },
    Target {
        scenario: "paper",
        metric: "base_yaw_deg",
        p95_below: 0.35,
    },
    Target {
        scenario: "noise-free",
        metric: "feature_mm",
        p95_below: 0.1,
    },
    Target {
        scenario: "noise-free",
        metric: "part_position_mm",
        p95_below: 0.1,
    },
    Target {
        scenario: "noise-free",
        metric: "part_yaw_deg",
        p95_below: 0.01,
    },
    Target {
        scenario: "noise-free",
        metric: "camera_height_mm",
        p95_below: 0.1,
    },
    Target {
        scenario: "noise-free",
        metric: "camera_rotation_deg",
        p95_below: 0.01,
    },
    Target {
        scenario: "noise-free",
        metric: "base_translation_mm",
        p95_below: 0.1,
    },
    Target {
        scenario: "noise-free",
        metric: "base_yaw_deg",
        p95_below: 0.01,
    },
];

/// Whether a target is met by the refined estimate; `None` if its scenario was not run.
pub fn target_met(rows: &[SummaryRow], target: &Target) -> Option<(f64, bool)> {
    let row = rows
        .iter()
        .find(|r| r.scenario == target.scenario && r.method == Method::Refined)?;
    let p95 = row
        .metric(target.metric)
        .and_then(|m| m.p95)
        .unwrap_or(f64::INFINITY);
    Some((p95, p95 < target.p95_below))
}
