//! Diagnostic (ignored): does the refinement from the truth land where it lands from the
//! estimator's own start? Separates convergence problems from the information limit.

mod calibration_support;

use calibration_support::{Errors, Rng, Scenario, Workcell};
use shared::calibration::model::WorkcellModel;
use shared::calibration::pinhole::Pinhole;
use shared::calibration::records::{to_f32, EffectorRecord, FrameRecord};
use shared::calibration::refine::{refine, Problem};
use shared::calibration::{CalibrationConfig, HostCalibrator};
use shared::observation::MAX_PART_FEATURES;

#[test]
#[ignore = "diagnostic"]
fn refine_from_truth_versus_own_start() {
    for seed in [1012u64, 1027, 1031, 1032, 1034, 1035, 1018] {
        let mut rng = Rng::new(seed);
        let scenario = Scenario::paper();
        let workcell = Workcell::random(&mut rng, 3, false);
        let frames = workcell.record(&mut rng, &scenario);
        let mut calibrator =
            HostCalibrator::new(&workcell.header(), CalibrationConfig::default()).unwrap();
        for frame in &frames {
            calibrator.push(frame).unwrap();
        }
        let own = calibrator.estimate().unwrap();
        let records: Vec<FrameRecord> = frames
            .iter()
            .map(|f| FrameRecord {
                theta: f.conveyor_angle_rad,
                centre: f.center_px.map(to_f32),
                reference: f.reference_px.map(to_f32),
                part: f.part_px.as_ref().map(|p| {
                    let mut a = [[0f32; 2]; MAX_PART_FEATURES];
                    for (s, q) in a.iter_mut().zip(p.iter()) {
                        *s = to_f32(*q);
                    }
                    a
                }),
            })
            .collect();
        let effectors: Vec<EffectorRecord> = frames
            .iter()
            .filter_map(|f| f.effector.as_ref().map(EffectorRecord::from_sighting))
            .collect();
        let problem = Problem {
            pinhole: Pinhole::new(&workcell.intrinsics),
            frames: &records,
            effectors: &effectors,
            feature_count: 3,
            reference_radius_m: 0.4,
            fix_base_height: false,
        };
        let mut features = [nalgebra::Vector3::zeros(); MAX_PART_FEATURES];
        for (s, f) in features.iter_mut().zip(&workcell.features_rotating) {
            *s = *f;
        }
        let truth = WorkcellModel {
            disc_from_camera: workcell.disc_from_camera,
            camera_centre_disc: workcell.camera_centre_disc,
            features_rotating: features,
            feature_count: 3,
            base_yaw: workcell.base_yaw,
            base_translation: workcell.base_translation,
        };
        let from_truth = refine(&problem, truth, &CalibrationConfig::default()).unwrap();
        let m = from_truth.model;
        let e_own = Errors::of(&own, &workcell);
        eprintln!("{seed} own:   {e_own:?}");
        eprintln!(
            "{seed} truth: h {:.4} cam {:.4} f0 {:.4} base {:.4} yaw {:.3}deg",
            (m.camera_centre_disc.z - workcell.camera_centre_disc.z).abs(),
            (m.camera_centre_disc - workcell.camera_centre_disc).norm(),
            (m.features_rotating[0] - workcell.features_rotating[0]).norm(),
            (m.base_translation - workcell.base_translation).norm(),
            (m.base_yaw - workcell.base_yaw).to_degrees()
        );
    }
}
