//! A synthetic pick for the tests, the benchmark of the figures and a look at
//! the outputs without a simulation.

use shared::protocol::PickPhase;

use super::record::{CalibrationRecord, GraspRecord, PickResult, PickRun, TickRecord};
use super::report::wrap_angle_rad;

/// A synthetic pick of `records` samples at 100 Hz, for the tests, the
/// benchmark of the figures and a look at the outputs without a simulation: the
/// part turns on the disc, the estimate (with a small bias and ripple) appears
/// at calibration, the tool closes in and grasps. Nothing here is a result of
/// the controller.
#[doc(hidden)]
pub fn synthetic_run(experiment: &str, records: usize) -> PickRun {
    use super::record::PhaseEvent;
    use crate::world::CellLayout;
    use shared::protocol::CalibrationReport;

    let period_s = 0.01;
    let duration_s = records as f64 * period_s;
    let phase_starts = [
        (0.0, PickPhase::SearchEffector),
        (0.2, PickPhase::CalibrateBase),
        (0.3, PickPhase::Locate),
        (0.4, PickPhase::Intercept),
        (0.55, PickPhase::Track),
        (0.65, PickPhase::Descend),
        (0.7, PickPhase::Grasp),
        (0.75, PickPhase::Lift),
        (0.85, PickPhase::Return),
    ];
    let phase_at = |fraction: f64| {
        phase_starts
            .iter()
            .take_while(|(start, _)| *start <= fraction)
            .last()
            .map_or(PickPhase::Idle, |&(_, phase)| phase)
    };
    let disc_centre = [0.6, -0.2, -0.3];
    let radius = 0.25;
    let omega = 0.5;
    let calibrated_after_s = 0.3 * duration_s;
    let grasp_t_s = 0.72 * duration_s;
    let records: Vec<TickRecord> = (0..records)
        .map(|i| {
            let t_s = i as f64 * period_s;
            let theta = omega * t_s;
            let part = [
                disc_centre[0] + radius * theta.cos(),
                disc_centre[1] + radius * theta.sin(),
                disc_centre[2] + 0.04,
            ];
            let calibrated = t_s >= calibrated_after_s;
            let ripple = (7.0 * t_s).sin();
            let estimate = calibrated.then(|| {
                [
                    part[0] + 0.004 + 0.002 * ripple,
                    part[1] - 0.003 + 0.002 * ripple,
                    part[2] + 0.001,
                ]
            });
            let fraction = t_s / duration_s.max(period_s);
            let approach = ((fraction - 0.4) / 0.3).clamp(0.0, 1.0);
            let ready = [0.4, 0.1, 0.2];
            let tool: [f64; 3] = core::array::from_fn(|k| {
                let target = part.get(k).copied().unwrap_or_default();
                let start = ready.get(k).copied().unwrap_or_default();
                start + (target - start) * approach
            });
            let q_rad = core::array::from_fn(|j| 0.1 * j as f64 + 0.2 * (t_s + j as f64).sin());
            TickRecord {
                t_s,
                phase: phase_at(fraction),
                part_true_base_m: part,
                part_true_yaw_rad: wrap_angle_rad(theta + 0.3),
                part_est_base_m: estimate,
                part_est_yaw_rad: calibrated.then(|| wrap_angle_rad(theta + 0.3 + 0.02 * ripple)),
                part_sigma_m: if calibrated { 0.003 } else { 0.0 },
                tool_true_base_m: tool,
                tool_true_yaw_rad: wrap_angle_rad(theta),
                tool_ref_base_m: tool.map(|c| c + 0.001 * ripple),
                tool_ref_yaw_rad: wrap_angle_rad(theta + 0.01),
                theta_true_rad: theta,
                theta_est_wrapped_rad: wrap_angle_rad(theta + 0.001),
                omega_true_rad_s: omega,
                omega_est_rad_s: omega * 1.001,
                q_rad,
                qd_rad_s: q_rad.map(|q| 0.5 * q),
                tau_nm: q_rad.map(|q| 10.0 * q),
            }
        })
        .collect();
    let phases = phase_starts
        .iter()
        .map(|&(fraction, phase)| PhaseEvent {
            t_s: fraction * duration_s,
            phase,
        })
        .collect();
    let calibration = CalibrationRecord {
        t_s: calibrated_after_s,
        report: CalibrationReport {
            time_us: (calibrated_after_s * 1e6) as u64,
            camera_height_m: 1.52,
            camera_tilt_rad: 0.01,
            base_yaw_rad: 0.105,
            base_translation_m: [0.601, -0.198, -0.302],
            part_rotating_m: [0.25, 0.0, 0.04],
            part_yaw_rotating_rad: 0.3,
            sigma_part_m: 0.003,
            sigma_base_m: 0.002,
            sigma_base_yaw_rad: 0.004,
            frames_used: 120,
            effector_frames_used: 30,
            rms_reprojection_px: 0.8,
            points_gated: 0,
            frames_folded: 0,
            folds_discarded: 0,
            sigma_grasp_horizontal_m: 0.002,
            sigma_grasp_vertical_m: 0.003,
            sigma_grasp_yaw_rad: 0.004,
        },
        true_camera_height_m: 1.5,
        true_base_yaw_rad: 0.1,
        true_base_translation_m: [0.6, -0.2, -0.3],
    };
    PickRun {
        experiment: experiment.to_owned(),
        seed: 7,
        layout: CellLayout {
            disc_centre_base_m: disc_centre,
            disc_radius_m: 0.4,
            camera_centre_base_m: [0.6, -0.2, 1.2],
            drop_off_base_m: [0.1, 0.5, 0.0],
        },
        records,
        phases,
        calibrations: vec![calibration],
        grasp: Some(GraspRecord {
            t_s: grasp_t_s,
            succeeded: true,
            position_error_m: [0.003, 0.004, 0.0],
            yaw_error_rad: 0.01,
            relative_speed_m_s: 0.002,
            estimate_error_m: Some([0.01234, -0.00456, 0.0021]),
            estimate_yaw_error_rad: Some(2.0_f64.to_radians()),
        }),
        result: PickResult::Success,
        placed_error_m: Some(0.004),
        calibrated_after_s: Some(calibrated_after_s),
        duration_s,
        max_speed_ratio: 0.6,
        max_torque_ratio: 0.7,
        min_tool_clearance_m: 0.02,
        end_joint_speed_rad_s: 0.0,
        link: Default::default(),
        safety: Default::default(),
        vision: None,
    }
}
