//! Every degenerate or invalid input gets its typed error, and a rejected frame leaves the
//! estimator as it was.

mod calibration_support;

use calibration_support::{Rng, Scenario, Workcell};
use nalgebra::{Matrix3, Rotation3, Vector3};
use shared::calibration::{
    CalibrationConfig, CalibrationError, ConicKind, FirmwareCalibrator, HostCalibrator,
};
use shared::observation::{EffectorSighting, ObservationFrame};

fn recorded(seed: u64) -> (Workcell, Vec<ObservationFrame>) {
    let mut rng = Rng::new(seed);
    let workcell = Workcell::random(&mut rng, 3, false);
    let frames = workcell.record(&mut rng, &Scenario::paper());
    (workcell, frames)
}

fn calibrator_with(workcell: &Workcell, frames: &[ObservationFrame]) -> HostCalibrator {
    let mut calibrator =
        HostCalibrator::new(&workcell.header(), CalibrationConfig::default()).unwrap();
    for frame in frames {
        calibrator.push(frame).unwrap();
    }
    calibrator
}

/// Frames that show only a reference point at the given pixels and angles (plus the centre).
fn reference_only(points: &[([f64; 2], f64)]) -> Vec<ObservationFrame> {
    points
        .iter()
        .enumerate()
        .map(|(k, &(pixel, theta))| ObservationFrame {
            t_s: k as f64,
            conveyor_angle_rad: theta,
            center_px: Some([128.0, 128.0]),
            reference_px: Some(pixel),
            part_px: None,
            effector: None,
            rim: None,
        })
        .collect()
}

fn estimate_both(
    workcell: &Workcell,
    frames: &[ObservationFrame],
) -> [Result<(), CalibrationError>; 2] {
    let mut calibrator = calibrator_with(workcell, frames);
    [
        calibrator.estimate().map(|_| ()),
        calibrator.paper_estimate().map(|_| ()),
    ]
}

#[test]
fn invalid_frames_are_rejected_and_leave_the_state_unchanged() {
    let (workcell, frames) = recorded(5);
    let mut clean = calibrator_with(&workcell, &frames);
    let mut dirty = HostCalibrator::new(&workcell.header(), CalibrationConfig::default()).unwrap();
    for (k, frame) in frames.iter().enumerate() {
        dirty.push(frame).unwrap();
        if k == 100 {
            let mut nan = frame.clone();
            nan.t_s += 0.01;
            nan.center_px = Some([f64::NAN, 3.0]);
            let error = dirty.push(&nan).unwrap_err();
            assert_eq!(
                error,
                CalibrationError::NonFiniteValue {
                    frame: 101,
                    field: "center_px"
                }
            );
            assert!(
                error.to_string().contains("frame 101") && error.to_string().contains("center_px")
            );
            let mut wrong_count = frame.clone();
            if let Some(part) = wrong_count.part_px.as_mut() {
                part.pop();
            } else {
                wrong_count.part_px = Some(heapless::Vec::from_slice(&[[1.0, 2.0]]).unwrap());
            }
            assert!(matches!(
                dirty.push(&wrong_count),
                Err(CalibrationError::WrongFeatureCount {
                    frame: 102,
                    expected: 3,
                    ..
                })
            ));
            let mut backwards = frame.clone();
            backwards.t_s -= 1.0;
            assert!(matches!(
                dirty.push(&backwards),
                Err(CalibrationError::TimeWentBackwards { frame: 103, .. })
            ));
            let mut coinciding = frame.clone();
            coinciding.effector = Some(EffectorSighting {
                px: [[10.0, 10.0], [20.0, 20.0]],
                base_m: [[0.5, 0.1, 0.2]; 2],
            });
            assert_eq!(
                dirty.push(&coinciding),
                Err(CalibrationError::CoincidingEffectorPoints { frame: 104 })
            );
            let mut infinite_angle = frame.clone();
            infinite_angle.conveyor_angle_rad = f64::INFINITY;
            assert!(matches!(
                dirty.push(&infinite_angle),
                Err(CalibrationError::NonFiniteValue {
                    field: "conveyor_angle_rad",
                    ..
                })
            ));
            // Finite but far outside the image: refused (it would poison the conic fit).
            let mut outside = frame.clone();
            outside.reference_px = Some([1e80, 12.0]);
            let error = dirty.push(&outside).unwrap_err();
            assert!(matches!(
                error,
                CalibrationError::OutsideImage {
                    field: "reference_px",
                    ..
                }
            ));
            assert!(error.to_string().contains("outside the image"));
        }
    }
    assert_eq!(clean.estimate().unwrap(), dirty.estimate().unwrap());
    assert_eq!(
        clean.paper_estimate().unwrap(),
        dirty.paper_estimate().unwrap()
    );
}

#[test]
fn invalid_header_is_refused() {
    let (workcell, _) = recorded(1);
    let mut header = workcell.header();
    header.camera.f_px = 0.0;
    assert_eq!(
        HostCalibrator::new(&header, CalibrationConfig::default()).unwrap_err(),
        CalibrationError::InvalidHeader {
            field: "camera.f_px"
        }
    );
    let mut header = workcell.header();
    header.part_feature_count = 1;
    assert!(HostCalibrator::new(&header, CalibrationConfig::default()).is_err());
    let bad_sigma = CalibrationConfig {
        pixel_sigma: f64::NAN,
        ..CalibrationConfig::default()
    };
    assert_eq!(
        HostCalibrator::new(&workcell.header(), bad_sigma).unwrap_err(),
        CalibrationError::InvalidConfig {
            field: "pixel_sigma"
        }
    );
    let bad_height = CalibrationConfig {
        disc_height_in_base_m: Some(f64::INFINITY),
        ..CalibrationConfig::default()
    };
    assert!(HostCalibrator::new(&workcell.header(), bad_height).is_err());
}

#[test]
fn too_few_frames() {
    let (workcell, frames) = recorded(2);
    let few: Vec<_> = frames.iter().step_by(75).take(4).cloned().collect();
    for result in estimate_both(&workcell, &few) {
        assert!(
            matches!(
                result,
                Err(CalibrationError::TooFewObservations { needed: 5, .. })
            ),
            "{result:?}"
        );
    }
    let empty = HostCalibrator::new(&workcell.header(), CalibrationConfig::default()).unwrap();
    assert!(matches!(
        empty.paper_estimate(),
        Err(CalibrationError::TooFewObservations { .. })
    ));
}

#[test]
fn conveyor_that_barely_turned() {
    let (workcell, frames) = recorded(3);
    let few: Vec<_> = frames.iter().take(10).cloned().collect();
    for result in estimate_both(&workcell, &few) {
        assert!(
            matches!(result, Err(CalibrationError::InsufficientRotation { .. })),
            "{result:?}"
        );
    }
}

#[test]
fn collinear_reference_points() {
    let (workcell, _) = recorded(4);
    let points: Vec<_> = (0..40)
        .map(|k| ([60.0 + 2.0 * k as f64, 50.0 + k as f64], k as f64 * 0.16))
        .collect();
    for result in estimate_both(&workcell, &reference_only(&points)) {
        assert!(
            matches!(result, Err(CalibrationError::DegenerateConic { .. })),
            "{result:?}"
        );
    }
}

#[test]
fn hyperbola_and_parabola_reference_tracks() {
    let (workcell, _) = recorded(4);
    let hyperbola: Vec<_> = (0..40)
        .map(|k| {
            let t = -1.0 + k as f64 * 0.05;
            (
                [128.0 + 30.0 * t.cosh(), 128.0 + 30.0 * t.sinh()],
                k as f64 * 0.16,
            )
        })
        .collect();
    for result in estimate_both(&workcell, &reference_only(&hyperbola)) {
        assert_eq!(
            result,
            Err(CalibrationError::NotAnEllipse {
                kind: ConicKind::Hyperbola
            })
        );
    }
    let parabola: Vec<_> = (0..40)
        .map(|k| {
            let t = -1.0 + k as f64 * 0.05;
            ([128.0 + 60.0 * t, 60.0 + 60.0 * t * t], k as f64 * 0.16)
        })
        .collect();
    for result in estimate_both(&workcell, &reference_only(&parabola)) {
        assert_eq!(
            result,
            Err(CalibrationError::NotAnEllipse {
                kind: ConicKind::Parabola
            })
        );
    }
}

#[test]
fn camera_below_the_disc() {
    let mut rng = Rng::new(6);
    let mut workcell = Workcell::random(&mut rng, 3, false);
    // Mirror the camera through the disc plane: it now looks up at the disc from below
    // (the image x axis is mirrored too, to keep a right-handed camera frame).
    let mirror = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0));
    let flip_x = Matrix3::from_diagonal(&Vector3::new(-1.0, 1.0, 1.0));
    let looking_up = mirror * workcell.disc_from_camera.matrix() * flip_x;
    workcell.disc_from_camera = Rotation3::from_matrix_unchecked(looking_up);
    workcell.camera_centre_disc.z = -workcell.camera_centre_disc.z;
    let frames = workcell.record(&mut rng, &Scenario::exact());
    assert!(frames.iter().filter(|f| f.reference_px.is_some()).count() > 100);
    for result in estimate_both(&workcell, &frames) {
        assert_eq!(result, Err(CalibrationError::CameraBelowDisc));
    }
}

#[test]
fn no_valid_root_of_eq_10() {
    let (workcell, mut frames) = recorded(8);
    // Vertical 0.1 m segments: G = |m0|^2 d^2 >= 0 and F^2 - E G <= 0 (Cauchy-Schwarz), so
    // Eq 10 has no real root unless the image segment points at the image centre.
    for frame in frames.iter_mut() {
        if let Some(sighting) = frame.effector.as_mut() {
            let [b0, _] = sighting.base_m;
            sighting.base_m = [b0, [b0[0], b0[1], b0[2] - 0.1]];
            sighting.px = [[100.0, 90.0], [140.0, 160.0]];
        }
    }
    for result in estimate_both(&workcell, &frames) {
        assert_eq!(result, Err(CalibrationError::NoValidDepthRoot { frame: 0 }));
    }
}

#[test]
fn no_effector_sighting() {
    let (workcell, mut frames) = recorded(9);
    frames.iter_mut().for_each(|f| f.effector = None);
    for result in estimate_both(&workcell, &frames) {
        assert!(
            matches!(
                result,
                Err(CalibrationError::TooFewObservations { needed: 1, .. })
            ),
            "{result:?}"
        );
    }
}

#[test]
fn calibrator_sizes_are_documented() {
    let firmware = core::mem::size_of::<FirmwareCalibrator>();
    let host = core::mem::size_of::<HostCalibrator>();
    eprintln!("size_of FirmwareCalibrator = {firmware} B, HostCalibrator = {host} B");
    assert!(firmware <= 24 * 1024, "{firmware}");
    assert!(host <= 160 * 1024, "{host}");
}

#[test]
fn pick_calibrator_packs_its_frames() {
    use shared::app::pick::PickCalibrator;
    let pick = core::mem::size_of::<PickCalibrator>();
    eprintln!("size_of PickCalibrator = {pick} B");
    // 256 frames of five f32 pixels, an f64 angle, a presence byte and a u32
    // offer index (13,568 B), 128 sightings of 40 + 4 B and the header, config and
    // conic (under 18.5 KiB without the indices: it was 32 KiB with every frame
    // laid out for eight features), plus 3.5 KiB for what it folds when they are
    // full (the arrowhead normal equations and two linearisation points), plus
    // 576 B for the recent-bias windows that flag a creeping camera, plus
    // 352 B for the disc's rim (its running mean and the 16 points the
    // refinement weighs).
    assert!(pick <= 24 * 1024, "{pick}");
}
