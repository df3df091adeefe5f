//! The batch maximum-likelihood solve (`host_sim::batch_ml`): exact on noise-free
//! logs, in agreement with the calibrator where both see every frame, independent
//! of its start, and robust to a gross outlier.

use host_sim::batch_ml::{batch_estimate, BatchEstimate};
use host_sim::calibration::calibrate_log;
use host_sim::geometry::{angle_distance, from_array, from_rows};
use host_sim::log::ObservationLog;
use host_sim::recording::{simulate, SimulatedRun};
use host_sim::scenario::Scenario;
use shared::calibration::CalibrationConfig;
use shared::observation::CalibrationResult;

fn record(scenario: &str, seed: u64) -> SimulatedRun {
    simulate(&Scenario::named(scenario).expect("scenario"), seed).expect("workcell")
}

/// The calibrator's estimate of `log`, the batch solve's start.
fn calibrator(log: &ObservationLog, config: CalibrationConfig) -> CalibrationResult {
    calibrate_log(log, config)
        .expect("calibration runs")
        .refined
        .expect("calibrator estimate")
}

fn batch(log: &ObservationLog, config: CalibrationConfig) -> BatchEstimate {
    let start = calibrator(log, config);
    batch_estimate(log, &config, &start).expect("batch estimate")
}

/// Largest difference between two results over every estimated quantity (m, rad).
fn largest_difference(a: &CalibrationResult, b: &CalibrationResult) -> f64 {
    let distance = |p: [f64; 3], q: [f64; 3]| (from_array(p) - from_array(q)).norm();
    let rotation = (from_rows(&a.camera.disc_from_camera.rotation)
        - from_rows(&b.camera.disc_from_camera.rotation))
    .amax();
    let features = a
        .part
        .features_m
        .iter()
        .zip(b.part.features_m.iter())
        .map(|(p, q)| distance(*p, *q))
        .fold(0.0, f64::max);
    [
        rotation,
        distance(
            a.camera.disc_from_camera.translation_m,
            b.camera.disc_from_camera.translation_m,
        ),
        features,
        angle_distance(a.base_from_disc.yaw_rad, b.base_from_disc.yaw_rad),
        distance(
            a.base_from_disc.translation_m,
            b.base_from_disc.translation_m,
        ),
    ]
    .into_iter()
    .fold(0.0, f64::max)
}

#[test]
fn a_noise_free_log_gives_the_truth() {
    for seed in [1, 2, 3, 4] {
        let run = record("noise-free", seed);
        let estimate = batch(&run.log, CalibrationConfig::default());
        let difference = largest_difference(&estimate.result, &run.truth.result);
        assert!(
            difference < 1e-6,
            "seed {seed}: {difference:e} from the truth"
        );
        assert_eq!(estimate.result.quality.outliers_rejected, 0);
        assert!(estimate.result.quality.rms_reprojection_px < 1e-6);
    }
}

#[test]
fn a_noise_free_log_with_the_disc_height_known_gives_the_truth() {
    let run = record("noise-free", 5);
    let config = CalibrationConfig {
        disc_height_in_base_m: Some(run.truth.result.base_from_disc.translation_m[2]),
        ..CalibrationConfig::default()
    };
    let estimate = batch(&run.log, config);
    assert!(largest_difference(&estimate.result, &run.truth.result) < 1e-6);
    // The height is held, not estimated: one unknown fewer and no sigma.
    assert_eq!(estimate.parameters, 6 + 3 * 3 + 3);
    assert_eq!(estimate.uncertainty.base_translation_m[2], 0.0);
}

/// Where the calibrator keeps every frame (300 of its 1024, at most 20 of its
/// 256 sightings) both solve the same least-squares problem: they differ only by
/// the calibrator's Huber weights and f32 pixels: measured at most 0.075 sigma on
/// these seeds, asserted below 0.2.
#[test]
fn with_every_frame_kept_the_calibrator_agrees_with_the_batch_within_its_covariance() {
    for seed in 1..=8 {
        let run = record("paper", seed);
        assert!(run.log.frames.len() < 1024);
        let config = CalibrationConfig::default();
        let start = calibrator(&run.log, config);
        let estimate = batch_estimate(&run.log, &config, &start).expect("batch");
        let sigma = &estimate.uncertainty;
        for axis in 0..3 {
            for (name, calibrated, batch, sigma) in [
                (
                    "part position",
                    start.part.position_m[axis],
                    estimate.result.part.position_m[axis],
                    sigma.part_position_m[axis],
                ),
                (
                    "base translation",
                    start.base_from_disc.translation_m[axis],
                    estimate.result.base_from_disc.translation_m[axis],
                    sigma.base_translation_m[axis],
                ),
            ] {
                assert!(
                    sigma > 0.0 && sigma.is_finite(),
                    "seed {seed}: {name} sigma"
                );
                let in_sigmas = (calibrated - batch).abs() / sigma;
                assert!(
                    in_sigmas < 0.2,
                    "seed {seed}: {name} axis {axis}: the calibrator is {in_sigmas:.3} sigma from the batch"
                );
            }
        }
    }
}

/// The Cramér-Rao sigma is honest: over seeded workcells the batch's part
/// position errors, in its own sigmas, scatter like a standard normal.
#[test]
fn the_batch_sigma_matches_its_actual_errors() {
    let mut normalised = Vec::new();
    for seed in 1..=30 {
        let run = record("paper", seed);
        let estimate = batch(&run.log, CalibrationConfig::default());
        for axis in 0..3 {
            let error =
                estimate.result.part.position_m[axis] - run.truth.result.part.position_m[axis];
            normalised.push(error / estimate.uncertainty.part_position_m[axis]);
        }
    }
    let rms = (normalised.iter().map(|z| z * z).sum::<f64>() / normalised.len() as f64).sqrt();
    assert!((0.7..1.3).contains(&rms), "rms of error / sigma {rms:.3}");
}

/// A start moved well away from the calibrator's (degrees, centimetres)
/// converges to the same optimum.
#[test]
fn a_perturbed_start_reaches_the_same_optimum() {
    for (scenario, seed) in [("paper", 11), ("noisy", 12), ("non-planar", 13)] {
        let run = record(scenario, seed);
        let config = CalibrationConfig::default();
        let start = calibrator(&run.log, config);
        let from_calibrator = batch_estimate(&run.log, &config, &start).expect("batch");

        let mut moved = start.clone();
        let tilt = nalgebra::Rotation3::from_euler_angles(0.04, -0.03, 0.05);
        let rotation = from_rows(&moved.camera.disc_from_camera.rotation) * tilt.matrix();
        moved.camera.disc_from_camera.rotation = host_sim::geometry::rows(&rotation);
        for (axis, offset) in [0.05, -0.04, 0.08].into_iter().enumerate() {
            moved.camera.disc_from_camera.translation_m[axis] += offset;
            moved.base_from_disc.translation_m[axis] -= offset;
        }
        for (index, feature) in moved.part.features_m.iter_mut().enumerate() {
            feature[0] += 0.02;
            feature[1] -= 0.01 * index as f64;
            feature[2] += 0.015;
        }
        moved.base_from_disc.yaw_rad += 0.08;
        let from_moved = batch_estimate(&run.log, &config, &moved).expect("batch from moved");

        assert!(
            largest_difference(&start, &moved) > 0.05,
            "the start really moved"
        );
        let difference = largest_difference(&from_calibrator.result, &from_moved.result);
        assert!(
            difference < 1e-8,
            "{scenario} seed {seed}: optima {difference:e} apart"
        );
        assert_eq!(
            from_calibrator.observations_kept,
            from_moved.observations_kept
        );
        assert!(from_calibrator.gate_settled && from_moved.gate_settled);
    }
}

/// One reference detection moved 40 px is gated: the estimate is that of the
/// log without it; with the gate opened it pulls the estimate away.
#[test]
fn a_gross_outlier_is_gated() {
    let run = record("paper", 21);
    let frame = (0..run.log.frames.len())
        .rev()
        .find(|&i| {
            run.log.frames[i]
                .reference_px
                .is_some_and(|[u, v]| u > 50.0 && u < 200.0 && v > 50.0 && v < 200.0)
        })
        .expect("a reference detection well inside the image");
    let mut corrupted = run.log.clone();
    if let Some(reference) = corrupted.frames[frame].reference_px.as_mut() {
        reference[0] += 40.0;
    }
    let mut without = run.log.clone();
    without.frames[frame].reference_px = None;

    let config = CalibrationConfig::default();
    let gated = batch(&corrupted, config);
    let clean = batch(&without, config);
    assert_eq!(gated.result.quality.outliers_rejected, 1);
    assert_eq!(gated.observations, clean.observations + 1);
    assert_eq!(gated.observations_kept, clean.observations_kept);
    let difference = largest_difference(&gated.result, &clean.result);
    assert!(
        difference < 1e-9,
        "gated estimate {difference:e} from the clean one"
    );

    // The gate is what keeps it out: wide open, the outlier moves the estimate.
    let open = CalibrationConfig {
        outlier_gate_sigma: 1e6,
        ..config
    };
    let start = calibrator(&corrupted, config);
    let pulled = batch_estimate(&corrupted, &open, &start).expect("batch without a gate");
    assert_eq!(pulled.result.quality.outliers_rejected, 0);
    assert!(largest_difference(&pulled.result, &clean.result) > 1e-5);
}

/// `host-sim record --frames` then `host-sim calibrate --batch --truth`: the
/// batch result on stdout in the contract's JSON with its Cramér-Rao sigmas,
/// the errors of both estimates on stderr.
#[test]
fn calibrate_batch_prints_the_result_and_both_estimates_errors() {
    let folder = tempfile::tempdir().expect("temporary folder");
    let log = folder.path().join("run.jsonl");
    let host_sim = |args: &[&std::ffi::OsStr]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args(args)
            .output()
            .expect("host-sim runs")
    };
    let recorded = host_sim(&[
        "record".as_ref(),
        "--scenario".as_ref(),
        "paper".as_ref(),
        "--frames".as_ref(),
        "400".as_ref(),
        "-o".as_ref(),
        log.as_os_str(),
    ]);
    assert!(recorded.status.success(), "{recorded:?}");
    let truth = folder.path().join("run.truth.json");
    let output = host_sim(&[
        "calibrate".as_ref(),
        "--batch".as_ref(),
        "--truth".as_ref(),
        truth.as_os_str(),
        log.as_os_str(),
    ]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    let printed: serde_json::Value = serde_json::from_slice(&output.stdout).expect("JSON");
    let result: CalibrationResult = serde_json::from_value(printed.clone()).expect("a result");
    assert_eq!(result.quality.frames_used, 400);
    let sigma = printed["uncertainty_1sigma"]["part_position_m"][0]
        .as_f64()
        .expect("part position sigma");
    assert!(sigma > 0.0 && sigma < 0.005, "{sigma}");
    for needle in [
        "batch maximum-likelihood estimate",
        "measured pixel sigma",
        "batch errors: feature_mm",
        "calibrator errors: feature_mm",
    ] {
        assert!(stderr.contains(needle), "{needle} missing: {stderr}");
    }
}
