//! Noise-free exactness of the self-calibration on seeded random workcells.

mod calibration_support;

use calibration_support::{Errors, Rng, Scenario, Workcell};
use shared::calibration::{CalibrationConfig, FirmwareCalibrator, HostCalibrator};

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

#[test]
fn firmware_instance_thins_its_store_and_stays_exact() {
    // 600 frames over two revolutions into 96 slots: the store thins to every 8th frame.
    let scenario = Scenario {
        frames: 600,
        rotation_rad: 4.0 * std::f64::consts::PI,
        effector_frames: 40,
        ..Scenario::exact()
    };
    let mut rng = Rng::new(21);
    let workcell = Workcell::random(&mut rng, 3, false);
    let frames = workcell.record(&mut rng, &scenario);
    let mut calibrator =
        FirmwareCalibrator::new(&workcell.header(), CalibrationConfig::default()).unwrap();
    for frame in &frames {
        calibrator.push(frame).unwrap();
    }
    let result = calibrator.estimate().unwrap();
    let errors = Errors::of(&result, &workcell);
    assert!(
        errors.max_metres() < 1e-4 && errors.max_radians() < 1e-4,
        "{errors:?}"
    );
    assert_eq!(result.quality.frames_used, 600);
    assert!(result.quality.effector_frames_used <= 16);
}

#[test]
fn known_disc_height_is_exact_and_kept() {
    let mut rng = Rng::new(31);
    let workcell = Workcell::random(&mut rng, 4, true);
    let frames = workcell.record(
        &mut rng,
        &Scenario {
            feature_count: 4,
            non_planar: true,
            ..Scenario::exact()
        },
    );
    let config = CalibrationConfig {
        disc_height_in_base_m: Some(workcell.base_translation.z),
        ..CalibrationConfig::default()
    };
    let mut calibrator = HostCalibrator::new(&workcell.header(), config).unwrap();
    frames
        .iter()
        .for_each(|frame| calibrator.push(frame).unwrap());
    for result in [
        calibrator.estimate().unwrap(),
        calibrator.paper_estimate().unwrap(),
    ] {
        let errors = Errors::of(&result, &workcell);
        assert!(
            errors.max_metres() < 1e-4 && errors.max_radians() < 1e-4,
            "{errors:?}"
        );
        assert_eq!(
            result.base_from_disc.translation_m[2],
            workcell.base_translation.z
        );
    }
}

#[test]
fn recursive_conic_passes_through_every_reference_image() {
    let (workcell, calibrator) = calibrate(41, &Scenario::exact(), CalibrationConfig::default());
    let conic = calibrator.conic().unwrap();
    let mut rng = Rng::new(41);
    let _ = Workcell::random(&mut rng, 3, false);
    for frame in workcell.record(&mut rng, &Scenario::exact()) {
        if let Some([u, v]) = frame.reference_px {
            let k = &workcell.intrinsics;
            let ray = nalgebra::Vector2::new((u - k.cx) / k.f_px, (v - k.cy) / k.f_px);
            assert!(conic.sampson_distance(ray) * k.f_px < 1e-6);
        }
    }
}

#[test]
fn steep_effector_segments_with_two_depth_roots_are_resolved() {
    // Every sighting but one shows a nearly vertical segment, for which Eq 10 may have two
    // valid roots; the estimate must still be exact.
    let mut rng = Rng::new(51);
    let workcell = Workcell::random(&mut rng, 3, false);
    let mut frames = workcell.record(&mut rng, &Scenario::exact());
    let mut sightings = 0;
    for frame in frames.iter_mut().filter(|f| f.effector.is_some()) {
        let angle = sightings as f64 * 0.7;
        let lean = if sightings == 0 { 0.1 } else { 0.004 };
        let p0 = nalgebra::Vector3::new(0.25 * angle.cos(), 0.25 * angle.sin(), 0.1);
        let p1 = p0
            + nalgebra::Vector3::new(
                lean * angle.cos(),
                lean * angle.sin(),
                if sightings == 0 { 0.0 } else { 0.1 },
            );
        let (Some(q0), Some(q1)) = (workcell.project(&p0), workcell.project(&p1)) else {
            continue;
        };
        let (b0, b1) = (workcell.base_from_disc(&p0), workcell.base_from_disc(&p1));
        frame.effector = Some(shared::observation::EffectorSighting {
            px: [[q0.x, q0.y], [q1.x, q1.y]],
            base_m: [[b0.x, b0.y, b0.z], [b1.x, b1.y, b1.z]],
        });
        sightings += 1;
    }
    assert!(sightings >= 5);
    // Check that the scenario really has ambiguous sightings (in the true virtual camera).
    use shared::calibration::effector::{depth_roots, DepthRoots};
    use shared::calibration::pinhole::Pinhole;
    use shared::calibration::virtual_rotation::VirtualRotation;
    let rotation = VirtualRotation::from_pose(
        &workcell.disc_from_camera,
        &workcell.camera_centre_disc,
        0.4,
    )
    .unwrap();
    let pinhole = Pinhole::new(&workcell.intrinsics);
    let ambiguous = frames
        .iter()
        .filter_map(|f| f.effector.as_ref())
        .filter(|s| {
            let m = |i: usize| {
                rotation
                    .to_virtual(pinhole.ray(nalgebra::Vector2::new(s.px[i][0], s.px[i][1])))
                    .unwrap()
            };
            let (b0, b1) = (
                nalgebra::Vector3::from(s.base_m[0]),
                nalgebra::Vector3::from(s.base_m[1]),
            );
            matches!(
                depth_roots(m(0), m(1), b1.z - b0.z, (b1 - b0).norm()),
                DepthRoots::Ambiguous(_)
            )
        })
        .count();
    assert!(ambiguous >= 3, "{ambiguous}");
    let mut calibrator =
        HostCalibrator::new(&workcell.header(), CalibrationConfig::default()).unwrap();
    frames
        .iter()
        .for_each(|frame| calibrator.push(frame).unwrap());
    let errors = Errors::of(&calibrator.estimate().unwrap(), &workcell);
    assert!(
        errors.max_metres() < 1e-4 && errors.max_radians() < 1e-4,
        "{errors:?}"
    );
}
