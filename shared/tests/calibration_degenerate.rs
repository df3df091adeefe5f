//! Degenerate workcells and observations: each gets a typed error or an honest
//! estimate, never a confident wrong answer. "Honest" means the true error of
//! every reported quantity lies within 4 of the one-sigma values that
//! `estimate_with_uncertainty` reports (plus a floor of the solver's own
//! tolerance), so a caller who checks the sigmas is never misled.

mod calibration_support;

use calibration_support::{Errors, Rng, Scenario, Workcell};
use nalgebra::{Matrix3, Rotation3, Vector3};
use shared::calibration::{
    CalibrationConfig, CalibrationError, EstimateUncertainty, HostCalibrator,
};
use shared::observation::{CalibrationResult, ObservationFrame};

/// Errors beyond this many sigmas would be a confident wrong answer.
const SIGMAS: f64 = 4.0;
/// Below this the error is the solver's tolerance, not a misleading estimate.
const FLOOR_M: f64 = 1e-5;
const FLOOR_RAD: f64 = 1e-5;

fn rss(v: [f64; 3]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Feeds the frames (a frame the calibrator refuses is reported as that error).
fn calibrate(
    workcell: &Workcell,
    frames: &[ObservationFrame],
) -> Result<(CalibrationResult, EstimateUncertainty), CalibrationError> {
    let mut calibrator = HostCalibrator::new(&workcell.header(), CalibrationConfig::default())?;
    for frame in frames {
        calibrator.push(frame)?;
    }
    calibrator.estimate_with_uncertainty()
}

/// The largest error of the estimate in units of its reported sigma (each
/// quantity: camera height, part position, base translation, base yaw).
fn worst_sigma_ratio(
    result: &CalibrationResult,
    uncertainty: &EstimateUncertainty,
    workcell: &Workcell,
) -> (f64, String) {
    let errors = Errors::of(result, workcell);
    let ratios = [
        (
            "camera height",
            errors.camera_height_m,
            uncertainty.camera_height_m,
            FLOOR_M,
        ),
        (
            "part position",
            errors.part_position_m,
            rss(uncertainty.part_position_m),
            FLOOR_M,
        ),
        (
            "base translation",
            errors.base_translation_m,
            rss(uncertainty.base_translation_m),
            FLOOR_M,
        ),
        (
            "base yaw",
            errors.base_yaw_rad,
            uncertainty.base_yaw_rad,
            FLOOR_RAD,
        ),
    ];
    ratios
        .iter()
        .map(|&(name, error, sigma, floor)| {
            let ratio = if error <= floor {
                0.0
            } else if sigma.is_finite() && sigma > 0.0 {
                error / sigma
            } else if sigma.is_nan() {
                f64::INFINITY
            } else {
                // An infinite sigma admits any error.
                0.0
            };
            (
                ratio,
                format!("{name}: error {error:.3e}, sigma {sigma:.3e}"),
            )
        })
        .fold((0.0, String::new()), |worst, next| {
            if next.0 > worst.0 {
                next
            } else {
                worst
            }
        })
}

/// Asserts the outcome is a typed error or an honest estimate; returns the error, if any.
fn assert_error_or_honest(
    label: &str,
    workcell: &Workcell,
    outcome: Result<(CalibrationResult, EstimateUncertainty), CalibrationError>,
) -> Option<CalibrationError> {
    match outcome {
        Err(error) => {
            eprintln!("{label}: refused: {error}");
            Some(error)
        }
        Ok((result, uncertainty)) => {
            let (ratio, detail) = worst_sigma_ratio(&result, &uncertainty, workcell);
            eprintln!("{label}: estimate, worst error {ratio:.2} sigma ({detail})");
            assert!(
                ratio <= SIGMAS,
                "{label}: a confident wrong answer, {ratio:.1} sigma ({detail}); uncertainty {uncertainty:?}"
            );
            None
        }
    }
}

/// A camera at `camera_centre_disc` looking at `look_at` (image x roughly horizontal).
fn aim_camera(workcell: &mut Workcell, camera_centre_disc: Vector3<f64>, look_at: Vector3<f64>) {
    let z_axis = (look_at - camera_centre_disc).normalize();
    let x_axis = Vector3::z().cross(&z_axis).normalize();
    let y_axis = z_axis.cross(&x_axis);
    workcell.camera_centre_disc = camera_centre_disc;
    workcell.disc_from_camera =
        Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x_axis, y_axis, z_axis]));
}

#[test]
fn camera_in_the_disc_plane_sees_every_reference_point_on_one_line() {
    for seed in 0..4 {
        let mut rng = Rng::new(100 + seed);
        let mut workcell = Workcell::random(&mut rng, 3, false);
        let distance = rng.uniform(1.5, 2.5);
        let bearing = rng.uniform(-3.0, 3.0);
        aim_camera(
            &mut workcell,
            Vector3::new(distance * bearing.cos(), distance * bearing.sin(), 0.0),
            Vector3::zeros(),
        );
        let frames = workcell.record(&mut rng, &Scenario::paper());
        assert!(frames.iter().filter(|f| f.reference_px.is_some()).count() > 100);
        let outcome = calibrate(&workcell, &frames);
        let error =
            assert_error_or_honest(&format!("edge-on camera, seed {seed}"), &workcell, outcome);
        assert!(
            matches!(
                error,
                Some(
                    CalibrationError::DegenerateConic { .. }
                        | CalibrationError::NotAnEllipse { .. }
                )
            ),
            "seed {seed}: {error:?}"
        );
    }
}

#[test]
fn camera_grazing_the_disc_plane_is_refused_or_honest() {
    // 1 to 10 degrees above the plane: the reference ellipse is a sliver 1 to 10
    // pixels high, and the part's feature circles are as flat.
    for seed in 0..10 {
        let mut rng = Rng::new(200 + seed);
        let mut workcell = Workcell::random(&mut rng, 3, false);
        let distance = rng.uniform(1.5, 2.5);
        let elevation = (1.0 + f64::from(seed as u32)).to_radians();
        let bearing = rng.uniform(-3.0, 3.0);
        aim_camera(
            &mut workcell,
            Vector3::new(
                distance * elevation.cos() * bearing.cos(),
                distance * elevation.cos() * bearing.sin(),
                distance * elevation.sin(),
            ),
            Vector3::zeros(),
        );
        let frames = workcell.record(&mut rng, &Scenario::paper());
        let outcome = calibrate(&workcell, &frames);
        assert_error_or_honest(&format!("grazing camera, seed {seed}"), &workcell, outcome);
    }
}

#[test]
fn too_few_frames_are_refused_or_honest() {
    for (seed, count) in [
        (300, 3usize),
        (301, 5),
        (302, 6),
        (303, 8),
        (304, 12),
        (305, 20),
    ] {
        let mut rng = Rng::new(seed);
        let workcell = Workcell::random(&mut rng, 3, false);
        let scenario = Scenario {
            frames: count,
            effector_frames: count.min(5),
            ..Scenario::paper()
        };
        let frames = workcell.record(&mut rng, &scenario);
        let outcome = calibrate(&workcell, &frames);
        let error =
            assert_error_or_honest(&format!("{count} frames, seed {seed}"), &workcell, outcome);
        if count < 5 {
            assert!(
                matches!(error, Some(CalibrationError::TooFewObservations { .. })),
                "{count} frames: {error:?}"
            );
        }
    }
}

#[test]
fn camera_below_the_disc_plane_is_refused() {
    for seed in 0..4 {
        let mut rng = Rng::new(400 + seed);
        let mut workcell = Workcell::random(&mut rng, 3, false);
        // Mirror the camera through the disc plane (and the image x axis, to keep the
        // camera frame right-handed): it looks up at the disc's underside.
        let mirror = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0));
        let flip_x = Matrix3::from_diagonal(&Vector3::new(-1.0, 1.0, 1.0));
        workcell.disc_from_camera =
            Rotation3::from_matrix_unchecked(mirror * workcell.disc_from_camera.matrix() * flip_x);
        workcell.camera_centre_disc.z = -workcell.camera_centre_disc.z;
        let frames = workcell.record(&mut rng, &Scenario::paper());
        let outcome = calibrate(&workcell, &frames);
        let error =
            assert_error_or_honest(&format!("camera below, seed {seed}"), &workcell, outcome);
        assert_eq!(
            error,
            Some(CalibrationError::CameraBelowDisc),
            "seed {seed}"
        );
    }
}

#[test]
fn coinciding_end_effector_points_are_refused_and_nearly_coinciding_ones_honest() {
    let mut rng = Rng::new(500);
    let workcell = Workcell::random(&mut rng, 3, false);
    let mut frames = workcell.record(&mut rng, &Scenario::paper());
    let index = frames
        .iter()
        .position(|f| f.effector.is_some())
        .expect("a sighting");
    let mut coinciding = frames.clone();
    if let Some(sighting) = coinciding[index].effector.as_mut() {
        sighting.base_m[1] = sighting.base_m[0];
    }
    assert_eq!(
        calibrate(&workcell, &coinciding).err(),
        Some(CalibrationError::CoincidingEffectorPoints {
            frame: index as u32
        })
    );

    // 1 mm apart: the pixels of both points are the same to within the noise, so
    // Eq 10's scale comes from noise; the estimate must say so or refuse.
    for (seed, frame) in (0u64..).zip(frames.iter_mut()) {
        if let Some(sighting) = frame.effector.as_mut() {
            let [b0, _] = sighting.base_m;
            let mut sub = Rng::new(seed);
            let direction =
                Vector3::new(sub.gaussian(), sub.gaussian(), sub.gaussian()).normalize() * 0.001;
            let b1 = Vector3::from(b0) + direction;
            sighting.base_m[1] = [b1.x, b1.y, b1.z];
            let p0 = workcell.disc_from_base(&Vector3::from(b0));
            let p1 = workcell.disc_from_base(&b1);
            if let (Some(q0), Some(q1)) = (workcell.project(&p0), workcell.project(&p1)) {
                sighting.px = [
                    [q0.x + 0.5 * sub.gaussian(), q0.y + 0.5 * sub.gaussian()],
                    [q1.x + 0.5 * sub.gaussian(), q1.y + 0.5 * sub.gaussian()],
                ];
            }
        }
    }
    let outcome = calibrate(&workcell, &frames);
    assert_error_or_honest("effector points 1 mm apart", &workcell, outcome);
}

#[test]
fn a_part_at_the_disc_centre_is_refused_or_honest() {
    for seed in 0..6 {
        let mut rng = Rng::new(600 + seed);
        let mut workcell = Workcell::random(&mut rng, 3, false);
        // Move the part so that its centre sits on the disc's axis; the last three
        // seeds shrink it to 1 mm, so every feature circle is a pixel or less.
        let mean = workcell
            .features_rotating
            .iter()
            .fold(Vector3::zeros(), |sum, p| sum + p)
            / workcell.features_rotating.len() as f64;
        let shrink = if seed < 3 { 1.0 } else { 0.02 };
        for feature in workcell.features_rotating.iter_mut() {
            let offset = *feature - mean;
            *feature = Vector3::new(offset.x * shrink, offset.y * shrink, feature.z);
        }
        let frames = workcell.record(&mut rng, &Scenario::paper());
        assert!(frames.iter().filter(|f| f.part_px.is_some()).count() > 100);
        let outcome = calibrate(&workcell, &frames);
        assert_error_or_honest(
            &format!("part at the centre, seed {seed}"),
            &workcell,
            outcome,
        );
    }
}

#[test]
fn the_honesty_check_catches_a_wrong_answer() {
    // The check itself must be able to fail: a correct estimate judged against a
    // workcell whose base is moved by 20 sigma is flagged.
    let mut rng = Rng::new(700);
    let workcell = Workcell::random(&mut rng, 3, false);
    let frames = workcell.record(&mut rng, &Scenario::paper());
    let (result, uncertainty) = calibrate(&workcell, &frames).expect("paper scenario calibrates");
    let (ratio, _) = worst_sigma_ratio(&result, &uncertainty, &workcell);
    assert!(ratio <= SIGMAS, "{ratio}");
    let mut moved = workcell.clone();
    moved.base_translation += Vector3::new(20.0 * rss(uncertainty.base_translation_m), 0.0, 0.0);
    let (ratio, detail) = worst_sigma_ratio(&result, &uncertainty, &moved);
    assert!(ratio > SIGMAS, "{detail}");
}
