//! The synthetic workcell: drawn within the documented ranges, and its log and
//! truth file agree with each other under the contract's frame conventions
//! (checked by re-projecting from the truth file alone).

use std::f64::consts::{PI, TAU};

use host_sim::recording::{read_truth_file, simulate, truth_path_for, write_truth_file};
use host_sim::scenario::{FeatureHeights, Scenario, SCENARIO_NAMES};
use host_sim::world::dimensions::{DISC_RADIUS_M, SHOULDER_HEIGHT_M};
use host_sim::world::effector::{EFFECTOR_HEIGHT_RANGE_M, EFFECTOR_MARK_SPACING_M};
use nalgebra::{Matrix3, Vector3};
use shared::observation::{CalibrationResult, LogHeader, PixelPoint};

fn rotation_from_rows(r: &[[f64; 3]; 3]) -> Matrix3<f64> {
    Matrix3::from_row_slice(&r.concat())
}

fn rz(angle: f64) -> Matrix3<f64> {
    let (s, c) = angle.sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// Projects a disc-frame point with only the truth result and the header, as the contract defines.
fn project(truth: &CalibrationResult, header: &LogHeader, p_disc: Vector3<f64>) -> PixelPoint {
    let pose = &truth.camera.disc_from_camera;
    let rotation = rotation_from_rows(&pose.rotation);
    let t = Vector3::from(pose.translation_m);
    let p_camera = rotation.transpose() * (p_disc - t);
    let c = &header.camera;
    [
        c.f_px * p_camera.x / p_camera.z + c.cx,
        c.f_px * p_camera.y / p_camera.z + c.cy,
    ]
}

fn close(a: PixelPoint, b: PixelPoint, tolerance: f64) -> bool {
    (a[0] - b[0]).abs() <= tolerance && (a[1] - b[1]).abs() <= tolerance
}

#[test]
fn workcells_stay_within_the_documented_ranges() {
    for name in SCENARIO_NAMES {
        let scenario = Scenario::named(name).expect("scenario");
        for seed in 0..25 {
            let run = simulate(&scenario, seed).expect("workcell");
            let truth = &run.truth.result;
            let pose = &truth.camera.disc_from_camera;
            let rotation = rotation_from_rows(&pose.rotation);
            assert!((rotation.transpose() * rotation - Matrix3::identity()).norm() < 1e-12);
            assert!((rotation.determinant() - 1.0).abs() < 1e-12);
            assert!((1.8..=3.0).contains(&truth.camera.height_m));
            assert_eq!(truth.camera.height_m, pose.translation_m[2]);
            // Tilt: angle between the optical axis (third column) and straight down.
            let optical_axis = rotation.column(2);
            let tilt_deg = (-optical_axis.z).acos().to_degrees();
            let (low, high) = scenario.camera_tilt_deg;
            assert!(
                (low - 1e-9..=high + 1e-9).contains(&tilt_deg),
                "{name}: tilt {tilt_deg} deg outside {low} to {high}"
            );
            assert!((tilt_deg - run.truth.workcell.camera_tilt_deg).abs() < 1e-9);
            assert_eq!(
                (run.log.header.camera.width, run.log.header.camera.height),
                (256, 256)
            );

            let [x, y, z] = truth.base_from_disc.translation_m;
            assert!((0.6..=1.0).contains(&x.hypot(y)), "disc centre {x} {y}");
            assert!((SHOULDER_HEIGHT_M - 0.5..=SHOULDER_HEIGHT_M).contains(&z));
            assert!(truth.base_from_disc.yaw_rad > -PI && truth.base_from_disc.yaw_rad <= PI);

            assert_eq!(truth.part.features_m.len(), scenario.part_feature_count);
            let heights: Vec<f64> = truth.part.features_m.iter().map(|p| p[2]).collect();
            match scenario.feature_heights {
                FeatureHeights::FlatTop { min_m, max_m } => {
                    assert!(heights
                        .iter()
                        .all(|h| *h == heights[0] && (min_m..=max_m).contains(h)));
                }
                FeatureHeights::Spread {
                    min_m,
                    max_m,
                    min_spread_m,
                } => {
                    assert!(heights.iter().all(|h| (min_m..=max_m).contains(h)));
                    assert!(heights[1] - heights[0] >= min_spread_m - 1e-12);
                }
            }
            for p in &truth.part.features_m {
                assert!(p[0].hypot(p[1]) < DISC_RADIUS_M);
            }
        }
    }
}

#[test]
fn noise_free_log_matches_reprojection_of_the_truth_file() {
    for seed in 0..10 {
        let run =
            simulate(&Scenario::named("noise-free").expect("scenario"), seed).expect("workcell");
        let truth = &run.truth.result;
        let header = &run.log.header;
        let yaw = truth.base_from_disc.yaw_rad;
        let base_t = Vector3::from(truth.base_from_disc.translation_m);
        let mut effector_frames = 0;
        for frame in &run.log.frames {
            let theta = frame.conveyor_angle_rad;
            let centre = frame.center_px.expect("no dropouts when noise-free");
            assert!(close(
                centre,
                project(truth, header, Vector3::zeros()),
                1e-9
            ));
            let reference = Vector3::new(
                header.reference_radius_m * theta.cos(),
                header.reference_radius_m * theta.sin(),
                0.0,
            );
            assert!(close(
                frame.reference_px.expect("reference"),
                project(truth, header, reference),
                1e-9
            ));
            let part = frame.part_px.as_ref().expect("part");
            for (seen, p_rotating) in part.iter().zip(&truth.part.features_m) {
                let p_disc = rz(theta) * Vector3::from(*p_rotating);
                assert!(close(*seen, project(truth, header, p_disc), 1e-9));
            }
            if let Some(sighting) = frame.effector {
                effector_frames += 1;
                let marks_disc: Vec<Vector3<f64>> = sighting
                    .base_m
                    .iter()
                    .map(|p| rz(-yaw) * (Vector3::from(*p) - base_t))
                    .collect();
                for (seen, p_disc) in sighting.px.iter().zip(&marks_disc) {
                    assert!(close(*seen, project(truth, header, *p_disc), 1e-9));
                    let (low, high) = EFFECTOR_HEIGHT_RANGE_M;
                    assert!(p_disc.z >= low - 1e-12 && p_disc.z <= high + 1e-12);
                }
                assert!(
                    ((marks_disc[1] - marks_disc[0]).norm() - EFFECTOR_MARK_SPACING_M).abs()
                        < 1e-12
                );
                // The PUMA 560 reaches it: within a2 + d4 of the shoulder.
                for p in &sighting.base_m {
                    assert!(
                        (Vector3::from(*p) - Vector3::new(0.0, 0.0, SHOULDER_HEIGHT_M)).norm()
                            <= 0.8636
                    );
                }
            }
        }
        assert!((5..=20).contains(&effector_frames));
        assert_eq!(
            run.truth.result.quality.effector_frames_used,
            effector_frames
        );
        assert_eq!(run.truth.result.quality.rms_reprojection_px, 0.0);
    }
}

#[test]
fn image_angle_of_the_reference_decreases_as_theta_grows() {
    // Contract: seen from above (x right, y down) the image angle about the centre's image decreases.
    for seed in 0..10 {
        let run =
            simulate(&Scenario::named("noise-free").expect("scenario"), seed).expect("workcell");
        let angles: Vec<f64> = run
            .log
            .frames
            .iter()
            .map(|f| {
                let [cu, cv] = f.center_px.expect("centre");
                let [ru, rv] = f.reference_px.expect("reference");
                (rv - cv).atan2(ru - cu)
            })
            .collect();
        let total: f64 = angles
            .windows(2)
            .map(|w| (w[1] - w[0] + PI).rem_euclid(TAU) - PI)
            .sum();
        assert!(
            total < -5.5,
            "seed {seed}: image angle moved {total} rad over a revolution"
        );
    }
}

#[test]
fn noisy_detections_are_all_inside_the_image_and_dropouts_match_the_scenario() {
    let scenario = Scenario::named("noisy").expect("scenario");
    let (mut centres, mut frames, mut outliers) = (0_usize, 0_usize, 0_u32);
    for seed in 0..10 {
        let run = simulate(&scenario, seed).expect("workcell");
        let camera = run.log.header.camera;
        outliers += run.truth.result.quality.outliers_rejected;
        for frame in &run.log.frames {
            frames += 1;
            centres += usize::from(frame.center_px.is_some());
            let points = frame
                .center_px
                .iter()
                .chain(frame.reference_px.iter())
                .chain(frame.part_px.iter().flatten())
                .chain(frame.effector.iter().flat_map(|e| e.px.iter()));
            for p in points {
                assert!(camera.contains(*p), "{p:?} outside the image");
            }
        }
    }
    let missing = 1.0 - centres as f64 / frames as f64;
    assert!(
        (0.07..=0.13).contains(&missing),
        "centre dropout rate {missing}"
    );
    // About 1 % of roughly 5.5 points a frame over 3000 frames.
    assert!((80..=260).contains(&outliers), "{outliers} outliers");
}

#[test]
fn paper_noise_level_matches_the_scenario() {
    let run = simulate(&Scenario::paper(), 4).expect("workcell");
    // RMS of a 2-D distance with 0.5 px per axis: 0.5 * sqrt(2).
    let rms = run.truth.result.quality.rms_reprojection_px;
    assert!((rms - 0.5 * 2.0_f64.sqrt()).abs() < 0.05, "rms {rms}");
}

#[test]
fn same_seed_same_log_and_truth_file_round_trips() {
    let scenario = Scenario::named("non-planar").expect("scenario");
    let first = simulate(&scenario, 77).expect("workcell");
    let second = simulate(&scenario, 77).expect("workcell");
    assert_eq!(first.log, second.log);
    let other = simulate(&scenario, 78).expect("workcell");
    assert_ne!(first.log.header, other.log.header);

    let dir = tempfile::tempdir().expect("temp dir");
    let log_path = dir.path().join("run.jsonl");
    let truth_path = truth_path_for(&log_path);
    assert_eq!(truth_path, dir.path().join("run.truth.json"));
    write_truth_file(&truth_path, &first.truth).expect("write truth");
    assert_eq!(
        read_truth_file(&truth_path).expect("read truth"),
        first.truth
    );
    // The truth file also reads as a plain calibration result (extra keys ignored).
    let text = std::fs::read_to_string(&truth_path).expect("text");
    let as_result: CalibrationResult = serde_json::from_str(&text).expect("calibration result");
    assert_eq!(as_result, first.truth.result);
}
