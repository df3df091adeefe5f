//! Noise-free exactness of the self-calibration on seeded random workcells.

mod calibration_support;

use calibration_support::{Errors, Rng, Scenario, Workcell};
use shared::calibration::{CalibrationConfig, HostCalibrator};

fn calibrate(
    seed: u64,
    scenario: &Scenario,
    config: CalibrationConfig,
) -> (Workcell, HostCalibrator) {
    let mut rng = Rng::new(seed);
    let workcell = Workcell::random(&mut rng, scenario.feature_count, scenario.non_planar);
    let frames = workcell.record(&mut rng, scenario);
    let mut calibrator = HostCalibrator::new(&workcell.header(), config).unwrap();
    for frame in &frames {
        calibrator.push(frame).unwrap();
    }
    (workcell, calibrator)
}

#[test]
fn refined_estimate_is_exact_without_noise() {
    for seed in 1..=8 {
        let (workcell, mut calibrator) =
            calibrate(seed, &Scenario::exact(), CalibrationConfig::default());
        let result = calibrator.estimate().unwrap();
        let errors = Errors::of(&result, &workcell);
        eprintln!("seed {seed}: {errors:?}");
        assert!(errors.max_metres() < 1e-4, "seed {seed}: {errors:?}");
        assert!(errors.max_radians() < 1e-4, "seed {seed}: {errors:?}");
        assert!(result.quality.rms_reprojection_px < 1e-3);
    }
}

#[test]
fn paper_estimate_is_exact_without_noise() {
    for seed in 1..=8 {
        let (workcell, calibrator) =
            calibrate(seed, &Scenario::exact(), CalibrationConfig::default());
        let result = calibrator.paper_estimate().unwrap();
        let errors = Errors::of(&result, &workcell);
        eprintln!("seed {seed}: {errors:?}");
        assert!(errors.max_metres() < 1e-4, "seed {seed}: {errors:?}");
        assert!(errors.max_radians() < 1e-4, "seed {seed}: {errors:?}");
    }
}
