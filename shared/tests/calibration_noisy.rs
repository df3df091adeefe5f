//! Accuracy under noise, dropouts and outliers on seeded random workcells.
//!
//! Each scenario runs a fixed set of seeds and checks the 95th percentile of every error
//! against a bound with margin over what the team's targets require; `monte_carlo_report`
//! (ignored by default: `cargo test -p shared --release --test calibration_noisy -- --ignored
//! --nocapture`) prints the percentiles over 100 workcells for both estimators.

mod calibration_support;

use calibration_support::{Errors, Rng, Scenario, Workcell};
use shared::calibration::{CalibrationConfig, CalibrationError, HostCalibrator};
use shared::observation::CalibrationResult;

fn run(
    seed: u64,
    scenario: &Scenario,
    config: CalibrationConfig,
    paper: bool,
) -> (Workcell, Result<CalibrationResult, CalibrationError>) {
    let mut rng = Rng::new(seed);
    let workcell = Workcell::random(&mut rng, scenario.feature_count, scenario.non_planar);
    let frames = workcell.record(&mut rng, scenario);
    let config = CalibrationConfig {
        disc_height_in_base_m: scenario.known_height.then_some(workcell.base_translation.z),
        ..config
    };
    let mut calibrator = HostCalibrator::new(&workcell.header(), config).unwrap();
    for frame in &frames {
        calibrator.push(frame).unwrap();
    }
    let result = if paper {
        calibrator.paper_estimate()
    } else {
        calibrator.estimate()
    };
    (workcell, result)
}

/// 95th percentiles: part position (m), part yaw (rad), camera height (m),
/// base translation (m), base yaw (rad).
#[derive(Debug, Clone, Copy)]
struct Percentiles {
    part_position_m: f64,
    part_yaw_deg: f64,
    camera_height_m: f64,
    base_translation_m: f64,
    base_yaw_deg: f64,
    failures: usize,
}

fn percentile(mut values: Vec<f64>, q: f64) -> f64 {
    values.sort_by(f64::total_cmp);
    if values.is_empty() {
        return f64::NAN;
    }
    let index = ((values.len() as f64 - 1.0) * q).round() as usize;
    values[index]
}

fn study(
    seeds: std::ops::Range<u64>,
    scenario: &Scenario,
    config: CalibrationConfig,
    paper: bool,
) -> Percentiles {
    let mut all = Vec::new();
    let mut failures = 0;
    for seed in seeds {
        let (workcell, result) = run(seed, scenario, config, paper);
        match result {
            Ok(result) => all.push(Errors::of(&result, &workcell)),
            Err(error) => {
                eprintln!("seed {seed}: {error}");
                failures += 1;
            }
        }
    }
    let p95 = |f: fn(&Errors) -> f64| percentile(all.iter().map(f).collect(), 0.95);
    Percentiles {
        part_position_m: p95(|e| e.part_position_m),
        part_yaw_deg: p95(|e| e.part_yaw_rad.to_degrees()),
        camera_height_m: p95(|e| e.camera_height_m),
        base_translation_m: p95(|e| e.base_translation_m),
        base_yaw_deg: p95(|e| e.base_yaw_rad.to_degrees()),
        failures,
    }
}

fn assert_within(p: &Percentiles, limits: [f64; 5]) {
    let [part_position, part_yaw, height, base_translation, base_yaw] = limits;
    assert_eq!(p.failures, 0, "{p:?}");
    assert!(p.part_position_m < part_position, "{p:?}");
    assert!(p.part_yaw_deg < part_yaw, "{p:?}");
    assert!(p.camera_height_m < height, "{p:?}");
    assert!(p.base_translation_m < base_translation, "{p:?}");
    assert!(p.base_yaw_deg < base_yaw, "{p:?}");
}

/// Seeds of the always-run checks (the Monte-Carlo report uses 1000..1100).
const SEEDS: std::ops::Range<u64> = 1..25;

// Limits: about 1.6x the 95th percentiles measured over 100 workcells of this generator
// (which match the refinement started from the truth, i.e. the information limit).

#[test]
fn paper_setting_is_accurate() {
    let p = study(
        SEEDS,
        &Scenario::paper(),
        CalibrationConfig::default(),
        false,
    );
    assert_within(&p, [0.012, 1.2, 0.016, 0.036, 1.0]);
}

#[test]
fn refinement_beats_the_papers_two_frame_method() {
    let refined = study(
        SEEDS,
        &Scenario::paper(),
        CalibrationConfig::default(),
        false,
    );
    let paper = study(
        SEEDS,
        &Scenario::paper(),
        CalibrationConfig::default(),
        true,
    );
    assert_eq!(paper.failures, 0, "{paper:?}");
    assert!(
        refined.part_yaw_deg < paper.part_yaw_deg,
        "{refined:?} {paper:?}"
    );
    assert!(
        refined.base_yaw_deg < paper.base_yaw_deg,
        "{refined:?} {paper:?}"
    );
    assert!(
        refined.base_translation_m < paper.base_translation_m,
        "{refined:?} {paper:?}"
    );
    assert!(
        refined.camera_height_m < paper.camera_height_m,
        "{refined:?} {paper:?}"
    );
}

#[test]
fn noise_dropouts_and_outliers_are_handled() {
    let scenario = Scenario {
        pixel_sigma: 1.0,
        dropout: 0.1,
        outlier: 0.01,
        ..Scenario::paper()
    };
    let config = CalibrationConfig {
        pixel_sigma: 1.0,
        ..CalibrationConfig::default()
    };
    let p = study(SEEDS, &scenario, config, false);
    assert_within(&p, [0.02, 2.7, 0.028, 0.09, 1.8]);
}

#[test]
fn outliers_are_rejected_and_counted() {
    let scenario = Scenario {
        outlier: 0.01,
        ..Scenario::paper()
    };
    let (_, result) = run(7, &scenario, CalibrationConfig::default(), false);
    let result = result.unwrap();
    assert!(
        result.quality.outliers_rejected >= 3,
        "{:?}",
        result.quality
    );
    // The inliers' RMS stays that of 0.5 px noise in 2-D (0.71 px).
    assert!(
        result.quality.rms_reprojection_px < 0.8,
        "{:?}",
        result.quality
    );
}

#[test]
fn quarter_revolution_suffices() {
    let scenario = Scenario {
        rotation_rad: std::f64::consts::FRAC_PI_2,
        ..Scenario::paper()
    };
    let p = study(SEEDS, &scenario, CalibrationConfig::default(), false);
    assert_within(&p, [0.021, 2.6, 0.02, 0.045, 0.9]);
}

#[test]
fn non_planar_part_is_located() {
    let scenario = Scenario {
        non_planar: true,
        ..Scenario::paper()
    };
    let p = study(SEEDS, &scenario, CalibrationConfig::default(), false);
    assert_within(&p, [0.014, 1.2, 0.013, 0.036, 1.0]);
}

#[test]
fn known_disc_height_pins_the_translation() {
    let scenario = Scenario {
        known_height: true,
        ..Scenario::paper()
    };
    let p = study(SEEDS, &scenario, CalibrationConfig::default(), false);
    assert_within(&p, [0.012, 1.2, 0.016, 0.007, 1.0]);
    let (workcell, result) = run(3, &scenario, CalibrationConfig::default(), false);
    let translation_z = result.unwrap().base_from_disc.translation_m[2];
    assert!((translation_z - workcell.base_translation.z).abs() < 1e-9);
}

#[test]
fn conveyor_standing_still_and_reversing_is_fine() {
    // Theta goes up, stops, and comes back: the estimators may not assume its sign.
    let scenario = Scenario::paper();
    let mut rng = Rng::new(11);
    let workcell = Workcell::random(&mut rng, 3, false);
    let mut frames = workcell.record(&mut rng, &scenario);
    let count = frames.len();
    let tail: Vec<_> = frames[..count / 2].iter().rev().cloned().collect();
    for (k, frame) in tail.into_iter().enumerate() {
        let mut frame = frame;
        frame.t_s = 100.0 + k as f64 * 0.1;
        frames.push(frame);
    }
    let mut calibrator =
        HostCalibrator::new(&workcell.header(), CalibrationConfig::default()).unwrap();
    for frame in &frames {
        calibrator.push(frame).unwrap();
    }
    let errors = Errors::of(&calibrator.estimate().unwrap(), &workcell);
    assert!(
        errors.part_position_m < 0.012 && errors.base_translation_m < 0.04,
        "{errors:?}"
    );
}

#[test]
#[ignore = "Monte-Carlo report over 100 workcells; run in release with --nocapture"]
fn monte_carlo_report() {
    // Prints the 95th percentiles of both estimators; fails if the refined estimate fails on
    // any workcell or does worse than the paper's method.
    let config = CalibrationConfig::default();
    let noisy = Scenario {
        pixel_sigma: 1.0,
        dropout: 0.1,
        outlier: 0.01,
        ..Scenario::paper()
    };
    let quarter = Scenario {
        rotation_rad: std::f64::consts::FRAC_PI_2,
        ..Scenario::paper()
    };
    let non_planar = Scenario {
        non_planar: true,
        ..Scenario::paper()
    };
    let noisy_config = CalibrationConfig {
        pixel_sigma: 1.0,
        ..config
    };
    for (name, scenario, config) in [
        ("paper setting", Scenario::paper(), config),
        (
            "paper setting, plain least squares (no Huber, no gate)",
            Scenario::paper(),
            CalibrationConfig {
                huber_k: 1e9,
                outlier_gate_sigma: 1e9,
                ..config
            },
        ),
        (
            "paper setting, known disc height",
            Scenario {
                known_height: true,
                ..Scenario::paper()
            },
            config,
        ),
        ("1 px, 10 % dropouts, 1 % outliers", noisy, noisy_config),
        ("quarter revolution", quarter, config),
        ("non-planar part", non_planar, config),
    ] {
        let refined = study(1000..1100, &scenario, config, false);
        let paper = study(1000..1100, &scenario, config, true);
        eprintln!("{name}\n  refined p95: {refined:?}\n  paper   p95: {paper:?}");
        assert_eq!(refined.failures, 0, "{name}");
        assert!(
            refined.part_yaw_deg < paper.part_yaw_deg || paper.part_yaw_deg.is_nan(),
            "{name}"
        );
        assert!(
            refined.base_translation_m < paper.base_translation_m
                || paper.base_translation_m.is_nan(),
            "{name}"
        );
    }
}

#[test]
fn reported_standard_deviations_match_the_actual_errors() {
    // Normalised errors (error / reported sigma) must have an RMS near 1 over many workcells.
    let (mut height, mut yaw, mut base_x, mut part_z) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for seed in 200..260 {
        let mut rng = Rng::new(seed);
        let scenario = Scenario::paper();
        let workcell = Workcell::random(&mut rng, scenario.feature_count, false);
        let frames = workcell.record(&mut rng, &scenario);
        let mut calibrator =
            HostCalibrator::new(&workcell.header(), CalibrationConfig::default()).unwrap();
        frames
            .iter()
            .for_each(|frame| calibrator.push(frame).unwrap());
        let (result, sigma) = calibrator.estimate_with_uncertainty().unwrap();
        height
            .push((result.camera.height_m - workcell.camera_centre_disc.z) / sigma.camera_height_m);
        let yaw_error = (result.base_from_disc.yaw_rad - workcell.base_yaw)
            .sin()
            .asin();
        yaw.push(yaw_error / sigma.base_yaw_rad);
        base_x.push(
            (result.base_from_disc.translation_m[0] - workcell.base_translation.x)
                / sigma.base_translation_m[0],
        );
        let true_mean_z = workcell.features_rotating.iter().map(|f| f.z).sum::<f64>() / 3.0;
        part_z.push((result.part.position_m[2] - true_mean_z) / sigma.part_position_m[2]);
    }
    for (name, values) in [
        ("height", height),
        ("base yaw", yaw),
        ("base x", base_x),
        ("part z", part_z),
    ] {
        let rms = (values.iter().map(|v| v * v).sum::<f64>() / values.len() as f64).sqrt();
        eprintln!("{name}: RMS of normalised error {rms:.2}");
        assert!((0.6..1.6).contains(&rms), "{name}: {rms}");
    }
}

/// The calibrator measures the pixel noise from its residuals (nobody tells it):
/// with its prior at the default 0.5 px, the measured sigma tracks the true one
/// from a quarter to twice the prior within 20 %, with and without outliers.
#[test]
fn the_pixel_noise_is_measured_from_the_residuals() {
    for true_sigma in [0.25, 0.5, 1.0] {
        for (seed, outlier) in [(3, 0.0), (4, 0.0), (5, 0.01)] {
            let scenario = Scenario {
                pixel_sigma: true_sigma,
                outlier,
                ..Scenario::paper()
            };
            let (_, result) = run(seed, &scenario, CalibrationConfig::default(), false);
            let measured = result.unwrap().quality.pixel_sigma_px;
            assert!(
                (measured / true_sigma - 1.0).abs() < 0.2,
                "true {true_sigma} px, seed {seed}: measured {measured} px"
            );
        }
    }
}
