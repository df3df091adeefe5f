//! record -> calibrate end to end: through the binary (files, stdout, stderr,
//! exit status) and through the library on seeded sets of random workcells.

use std::path::Path;
use std::process::{Command, Output};

use host_sim::accuracy::harness::{plan_trials, run_trials, HarnessOptions, Method, TrialOutcome};
use host_sim::accuracy::metrics::{compare, ErrorMetrics};
use host_sim::accuracy::stats::{median, percentile};
use host_sim::recording::read_truth_file;
use host_sim::scenario::Scenario;
use indicatif::ProgressBar;
use shared::observation::CalibrationResult;

fn host_sim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .output()
        .expect("run host-sim")
}

fn path(p: &Path) -> &str {
    p.to_str().expect("utf-8 temp path")
}

#[test]
fn cli_record_then_calibrate_noise_free_recovers_the_truth() {
    let dir = tempfile::tempdir().expect("temp dir");
    let log = dir.path().join("cell.jsonl");
    let recorded = host_sim(&[
        "record",
        "--scenario",
        "noise-free",
        "--seed",
        "42",
        "-o",
        path(&log),
    ]);
    assert!(
        recorded.status.success(),
        "{}",
        String::from_utf8_lossy(&recorded.stderr)
    );
    let truth_path = dir.path().join("cell.truth.json");
    let truth = read_truth_file(&truth_path).expect("truth file beside the log");

    let calibrated = host_sim(&["calibrate", "--truth", path(&truth_path), path(&log)]);
    let stderr = String::from_utf8_lossy(&calibrated.stderr);
    assert!(calibrated.status.success(), "{stderr}");
    let result: CalibrationResult =
        serde_json::from_slice(&calibrated.stdout).expect("stdout is the result JSON");
    let errors = compare(&result, &truth.result).expect("comparable");
    assert_tight(&errors);
    assert!(stderr.contains("refined estimate: camera"), "{stderr}");
    assert!(stderr.contains("refined errors: feature_mm"), "{stderr}");
    assert!(stderr.contains("paper errors: feature_mm"), "{stderr}");
    assert!(
        stderr.contains("refined 1-sigma: camera height"),
        "{stderr}"
    );
    let printed: serde_json::Value = serde_json::from_slice(&calibrated.stdout).expect("JSON");
    assert!(
        printed["uncertainty_1sigma"]["base_yaw_rad"].is_number(),
        "{printed}"
    );
    assert_eq!(result.quality.frames_used, truth.result.quality.frames_used);
    assert_eq!(
        result.quality.effector_frames_used,
        truth.result.quality.effector_frames_used
    );
}

#[test]
fn cli_calibrate_refuses_a_bad_log_naming_line_and_field() {
    let dir = tempfile::tempdir().expect("temp dir");
    let log = dir.path().join("cell.jsonl");
    assert!(host_sim(&[
        "record",
        "--scenario",
        "paper",
        "--seed",
        "5",
        "-o",
        path(&log)
    ])
    .status
    .success());
    let text = std::fs::read_to_string(&log).expect("log");
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let line_17 = &mut lines[16];
    let start = line_17.find("\"reference_px\":").expect("key") + "\"reference_px\":".len();
    let end = line_17[start..].find(",\"part_px\"").expect("next key") + start;
    line_17.replace_range(start..end, "[12.5,\"oops\"]");
    std::fs::write(&log, lines.join("\n")).expect("write");

    let calibrated = host_sim(&["calibrate", path(&log)]);
    let stderr = String::from_utf8_lossy(&calibrated.stderr);
    assert!(!calibrated.status.success());
    assert_eq!(
        calibrated.status.code(),
        Some(1),
        "an error exit, not a panic: {stderr}"
    );
    assert!(
        stderr.contains("line 17: field \"reference_px\": expected [u, v] of 2 finite numbers, got an array [12.5,\"oops\"]"),
        "{stderr}"
    );
    assert!(calibrated.stdout.is_empty());

    let missing = host_sim(&["calibrate", path(&dir.path().join("absent.jsonl"))]);
    assert_eq!(missing.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&missing.stderr).contains("cannot open log"));
    let unknown = host_sim(&["record", "--scenario", "sideways", "-o", path(&log)]);
    assert_eq!(unknown.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&unknown.stderr).contains("unknown scenario \"sideways\""));
}

fn assert_tight(errors: &ErrorMetrics) {
    for (value, bound, name) in [
        (errors.feature_mm, 0.1, "feature_mm"),
        (errors.part_position_mm, 0.1, "part_position_mm"),
        (errors.part_yaw_deg, 0.01, "part_yaw_deg"),
        (errors.camera_height_mm, 0.1, "camera_height_mm"),
        (errors.camera_rotation_deg, 0.01, "camera_rotation_deg"),
        (errors.base_translation_mm, 0.1, "base_translation_mm"),
        (errors.base_yaw_deg, 0.01, "base_yaw_deg"),
    ] {
        assert!(
            value < bound,
            "{name} = {value} (bound {bound}); all: {errors}"
        );
    }
}

fn run(scenario: Scenario, trials: usize, seed: u64) -> Vec<TrialOutcome> {
    let plans = plan_trials(&[scenario], trials, seed);
    run_trials(&plans, &HarnessOptions::default(), &ProgressBar::hidden())
}

fn refined(outcomes: &[TrialOutcome]) -> Vec<ErrorMetrics> {
    outcomes
        .iter()
        .map(|o| match &o.refined {
            Ok(errors) => *errors,
            Err(e) => panic!("trial {} (record seed {}) failed: {e}", o.trial, o.seed),
        })
        .collect()
}

#[test]
fn noise_free_workcells_are_recovered_exactly() {
    let outcomes = run(Scenario::named("noise-free").expect("scenario"), 12, 2024);
    for (outcome, errors) in outcomes.iter().zip(refined(&outcomes)) {
        assert_tight(&errors);
        // The paper's own method is exact without noise too.
        let paper = outcome
            .errors(Method::Paper)
            .expect("the paper's method always runs")
            .as_ref()
            .expect("paper estimate");
        assert_tight(paper);
    }
}

fn p95(values: impl Iterator<Item = f64>) -> f64 {
    percentile(&values.collect::<Vec<_>>(), 0.95).expect("non-empty")
}

/// The five targets (95th percentile, paper scenario) on a seeded set of
/// 40 workcells, every camera tilt the scenario draws (10 to 35 degrees) included.
#[test]
fn paper_scenario_meets_the_accuracy_targets() {
    let outcomes = run(Scenario::paper(), 40, 7);
    let errors = refined(&outcomes);
    let all = || errors.iter();
    for (p95, target, name) in [
        (
            p95(all().map(|e| e.part_position_mm)),
            2.0,
            "part position (mm)",
        ),
        (p95(all().map(|e| e.part_yaw_deg)), 0.8, "part yaw (deg)"),
        (
            p95(all().map(|e| e.camera_height_mm)),
            5.5,
            "camera height (mm)",
        ),
        (
            p95(all().map(|e| e.base_translation_mm)),
            15.0,
            "base translation (mm)",
        ),
        (p95(all().map(|e| e.base_yaw_deg)), 0.35, "base yaw (deg)"),
    ] {
        assert!(p95 < target, "{name}: 95th percentile {p95} >= {target}");
    }
    // The refined estimate improves on the paper's two-frame method.
    let paper_base: Vec<f64> = outcomes
        .iter()
        .filter_map(|o| o.paper.as_ref().ok().map(|e| e.base_translation_mm))
        .collect();
    let refined_base: Vec<f64> = all().map(|e| e.base_translation_mm).collect();
    assert!(median(&refined_base) < median(&paper_base));
}

/// A camera nearly above the disc's axis (tilt 0 to 10 degrees): the part position
/// is poorly observable, so no 2 mm target, but the reported uncertainty must cover
/// the actual error and the user must be warned where it is large.
#[test]
fn near_axis_uncertainty_covers_the_part_error_and_large_sigmas_warn() {
    let outcomes = run(Scenario::named("near-axis").expect("scenario"), 40, 7);
    let errors = refined(&outcomes);
    let mut warned = 0;
    for (outcome, errors) in outcomes.iter().zip(&errors) {
        assert!(
            outcome.camera_tilt_deg < 10.0,
            "tilt {}",
            outcome.camera_tilt_deg
        );
        let sigma_mm = outcome.refined_part_sigma_mm.expect("refined uncertainty");
        assert!(
            errors.part_position_mm <= 4.0 * sigma_mm,
            "trial {} (record seed {}): part error {} mm > 4 x sigma {sigma_mm} mm",
            outcome.trial,
            outcome.seed,
            errors.part_position_mm
        );
        if sigma_mm > 5.0 {
            warned += 1;
        }
    }
    // The degenerate geometry really shows: some estimates are far off and say so.
    assert!(warned >= 3, "only {warned} of 40 near-axis workcells warn");
    assert!(p95(errors.iter().map(|e| e.part_position_mm)) > 2.0);
}

fn calibrate_stderr(scenario: &str, seed: &str) -> String {
    let dir = tempfile::tempdir().expect("temp dir");
    let log = dir.path().join("cell.jsonl");
    let recorded = host_sim(&[
        "record",
        "--scenario",
        scenario,
        "--seed",
        seed,
        "-o",
        path(&log),
    ]);
    assert!(
        recorded.status.success(),
        "{}",
        String::from_utf8_lossy(&recorded.stderr)
    );
    let calibrated = host_sim(&["calibrate", path(&log)]);
    let stderr = String::from_utf8_lossy(&calibrated.stderr).into_owned();
    assert!(calibrated.status.success(), "{stderr}");
    stderr
}

const NEAR_AXIS_WARNING: &str =
    "warning: the camera is nearly above the disc's axis: feature heights are poorly observable";

#[test]
fn calibrate_and_the_default_run_warn_about_a_camera_above_the_disc_axis() {
    // near-axis seed 1: a camera 0.8 degrees from vertical, part height 1-sigma about 25 mm.
    let near_axis = calibrate_stderr("near-axis", "1");
    assert!(near_axis.contains(NEAR_AXIS_WARNING), "{near_axis}");
    assert!(
        near_axis.contains("mount the camera further to the side"),
        "{near_axis}"
    );
    let slanted = calibrate_stderr("paper", "1");
    assert!(!slanted.contains("warning:"), "{slanted}");

    let demo = host_sim(&["calibration-demo", "--scenario", "near-axis", "--seed", "1"]);
    let stderr = String::from_utf8_lossy(&demo.stderr);
    assert!(demo.status.success(), "{stderr}");
    assert!(stderr.contains(NEAR_AXIS_WARNING), "{stderr}");
    let default = host_sim(&["calibration-demo"]);
    let stderr = String::from_utf8_lossy(&default.stderr);
    assert!(default.status.success(), "{stderr}");
    assert!(!stderr.contains("warning:"), "{stderr}");
    assert!(String::from_utf8_lossy(&default.stdout).contains("| part position (mm) |"));
}

/// The conveyor may turn either way and a log may cover only part of a
/// revolution (contract): the refined estimate still succeeds with sane errors.
#[test]
fn reverse_and_quarter_turn_logs_calibrate() {
    for name in ["reverse", "quarter-turn"] {
        let outcomes = run(Scenario::named(name).expect("scenario"), 6, 11);
        for errors in refined(&outcomes) {
            // Loose bounds, about twice the 95th percentiles of 100 workcells.
            assert!(errors.base_translation_mm < 30.0, "{name}: {errors}");
            assert!(errors.camera_height_mm < 12.0, "{name}: {errors}");
            assert!(errors.base_yaw_deg < 0.8, "{name}: {errors}");
        }
    }
}

#[test]
fn cli_names_the_file_line_of_a_frame_the_calibration_refuses() {
    let dir = tempfile::tempdir().expect("temp dir");
    let log = dir.path().join("cell.jsonl");
    assert!(host_sim(&[
        "record",
        "--scenario",
        "paper",
        "--seed",
        "8",
        "-o",
        path(&log)
    ])
    .status
    .success());
    let text = std::fs::read_to_string(&log).expect("log");
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    // Valid JSON per the contract, but Eq 10 needs two distinct effector points.
    let coinciding = "\"effector_px\":[[100.0,100.0],[100.0,100.0]],\"effector_base_m\":[[0.5,0.1,0.7],[0.5,0.1,0.7]]";
    let frame = lines
        .iter()
        .position(|l| {
            l.contains("\"effector_px\":null,\"effector_base_m\":null")
                && !l.contains("\"t_s\":0.0,")
        })
        .expect("a frame without the effector");
    lines[frame] =
        lines[frame].replace("\"effector_px\":null,\"effector_base_m\":null", coinciding);
    // A blank line before it shifts its line number by one.
    lines.insert(2, String::new());
    std::fs::write(&log, lines.join("\n")).expect("write");

    let calibrated = host_sim(&["calibrate", path(&log)]);
    let stderr = String::from_utf8_lossy(&calibrated.stderr);
    assert_eq!(calibrated.status.code(), Some(1), "{stderr}");
    let expected = format!("line {}: the calibration refuses the frame", frame + 2);
    assert!(
        stderr.contains(&expected),
        "wanted {expected:?} in {stderr}"
    );
}
