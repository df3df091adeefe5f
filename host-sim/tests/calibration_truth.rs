//! The calibration's truth is scored in the controller's own disc frame: it
//! starts where the disc stood when the pick began, after homing (the disc
//! turned 1.4 rad meanwhile on the default seed), so `calibration.csv`'s base
//! yaw error is the estimator's, within its sigmas, not that turn.

use host_sim::pick::runner::run_pick_in_process;
use host_sim::scenario::pick::PickScenarioFile;

#[test]
fn the_base_yaw_is_scored_in_the_controllers_disc_frame() {
    let experiment = PickScenarioFile::default_experiment("turning").unwrap();
    let run = run_pick_in_process(&experiment, 1).unwrap();
    assert!(run.calibrations.len() >= 2, "{}", run.calibrations.len());
    for calibration in &run.calibrations {
        let error = host_sim::geometry::wrap_angle(
            f64::from(calibration.report.base_yaw_rad) - calibration.true_base_yaw_rad,
        );
        let sigma = f64::from(calibration.report.sigma_base_yaw_rad);
        assert!(error.abs() < 3.0 * sigma, "{error} rad against {sigma}");
    }
}
