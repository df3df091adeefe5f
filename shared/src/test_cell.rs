//! The cell configuration the unit tests build controllers, workers and
//! pairers for: the experiments' 256x256 camera and 0.4 m reference radius.

use crate::protocol::{CellConfig, JOINTS};

pub fn test_cell_config(conveyor_counts_per_rev: u32, part_feature_count: u8) -> CellConfig {
    CellConfig {
        image_width_px: 256,
        image_height_px: 256,
        f_px: 300.0,
        cx_px: 128.0,
        cy_px: 128.0,
        reference_radius_m: 0.4,
        part_feature_count,
        conveyor_counts_per_rev,
        conveyor_counter_bits: 16,
        joint_counts_per_rad: [10_000.0; JOINTS],
        disc_height_in_base_m: None,
        drop_off_base_m: [0.0, 0.55, 0.3],
        camera_period_ms: 200,
        telemetry_period_ticks: 1,
        home_at_power_on: false,
        grasp_capture_m: [0.005, 0.010],
        grasp_capture_yaw_rad: 0.052,
        disc_radius_m: Some(0.45),
    }
}
