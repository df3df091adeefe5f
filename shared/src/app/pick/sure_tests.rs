//! When the pick trusts its estimate enough to grasp: the part's sigmas in
//! the base frame against the gripper's capture the cell configuration states.

use super::settings::PickSettings;
use super::PickController;
use crate::protocol::CalibrationReport;
use crate::test_cell::test_cell_config;

pub(super) fn report(horizontal_m: f32, vertical_m: f32, yaw_rad: f32) -> CalibrationReport {
    CalibrationReport {
        time_us: 0,
        camera_height_m: 2.5,
        camera_tilt_rad: 0.3,
        base_yaw_rad: 0.1,
        base_translation_m: [0.6, -0.2, -0.3],
        part_rotating_m: [0.25, 0.0, 0.04],
        part_yaw_rotating_rad: 0.3,
        sigma_part_m: 0.001,
        sigma_base_m: 0.001,
        sigma_base_yaw_rad: 0.001,
        frames_used: 200,
        effector_frames_used: 40,
        rms_reprojection_px: 0.5,
        points_gated: 0,
        frames_folded: 0,
        folds_discarded: 0,
        sigma_grasp_horizontal_m: horizontal_m,
        sigma_grasp_vertical_m: vertical_m,
        sigma_grasp_yaw_rad: yaw_rad,
    }
}

#[test]
fn the_pick_is_sure_only_well_inside_every_capture() {
    // The test cell's gripper: 5 mm, 10 mm and 0.052 rad.
    let settings = PickSettings::default();
    let pick = PickController::new(&test_cell_config(4096, 3), settings, 1)
        .unwrap_or_else(|e| panic!("{}", e.field));
    let (h, v, yaw) = (
        0.005 / settings.sure_horizontal_sigmas,
        0.010 / settings.sure_axis_sigmas,
        0.052 / settings.sure_axis_sigmas,
    );
    let inside = 0.99;
    assert!(pick.sure_to_grasp(&report(h * inside, v * inside, yaw * inside)));
    let outside = 1.01;
    assert!(!pick.sure_to_grasp(&report(h * outside, v * inside, yaw * inside)));
    assert!(!pick.sure_to_grasp(&report(h * inside, v * outside, yaw * inside)));
    assert!(!pick.sure_to_grasp(&report(h * inside, v * inside, yaw * outside)));
    // An undefined sigma is never sure.
    assert!(!pick.sure_to_grasp(&report(f32::NAN, v * inside, yaw * inside)));
}

#[test]
fn a_capture_that_is_not_a_positive_size_is_refused() {
    let settings = PickSettings::default();
    for (horizontal, vertical, yaw, field) in [
        (0.0, 0.01, 0.05, "grasp_capture_m"),
        (0.005, f32::NAN, 0.05, "grasp_capture_m"),
        (0.005, 0.01, -0.05, "grasp_capture_yaw_rad"),
    ] {
        let mut config = test_cell_config(4096, 3);
        config.grasp_capture_m = [horizontal, vertical];
        config.grasp_capture_yaw_rad = yaw;
        let refused = PickController::new(&config, settings, 1).map(|_| ());
        assert_eq!(refused.map_err(|e| e.field), Err(field));
    }
}
