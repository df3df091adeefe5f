//! The calibrated cell as the control loop uses it: `base_from_disc`, the part in
//! the rotating frame, the camera (to keep the marks in view), and how sure the
//! estimator is of them.

use nalgebra::{Matrix3, Vector3};

use crate::calibration::{EstimateUncertainty, SelfCalibrator};
use crate::fusion::part_motion_in_base;
use crate::observation::{CalibrationResult, CameraIntrinsics};
use crate::planning::TaskState;
use crate::protocol::CalibrationReport;

/// One self-calibration, in the control loop's precision.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellEstimate {
    /// `base_from_disc` (Eqs 13 and 14).
    pub base_yaw: f32,
    /// `base_from_disc`'s translation (Eq 15), m.
    pub base_translation: Vector3<f32>,
    /// The grasp point (mean of the features, paper Eqs 3 to 8) in the rotating frame, and the part's yaw.
    pub part_rotating: Vector3<f32>,
    /// The part's yaw in the rotating frame, rad.
    pub part_yaw_rotating: f32,
    /// `disc_from_camera` (f64: only the planner uses it).
    pub disc_from_camera: Matrix3<f64>,
    /// The camera's centre in the disc frame (with `disc_from_camera`).
    pub camera_centre_disc: Vector3<f64>,
    /// The pixel noise the calibration measured from its residuals (1-sigma,
    /// px): what the view monitor's noise floor is sized by.
    pub pixel_sigma_px: f32,
    /// The estimate as telemetry reports it.
    pub report: CalibrationReport,
}

fn norm3(v: &[f64; 3]) -> f64 {
    let [x, y, z] = *v;
    libm::sqrt(x * x + y * y + z * z)
}

fn to_f32(v: &[f64; 3]) -> [f32; 3] {
    v.map(|x| x as f32)
}

impl CellEstimate {
    /// The estimate from a calibration `result`, its uncertainty `sigma`, made at
    /// `time_us`.
    pub fn new(result: &CalibrationResult, sigma: &EstimateUncertainty, time_us: u64) -> Self {
        let rows = result.camera.disc_from_camera.rotation;
        let rotation = Matrix3::from_fn(|r, c| {
            rows.get(r)
                .and_then(|row| row.get(c))
                .copied()
                .unwrap_or(0.0)
        });
        let [cx, cy, cz] = result.camera.disc_from_camera.translation_m;
        // The optical axis in the disc frame is the rotation's third column.
        let tilt = libm::acos((-rotation.m33).clamp(-1.0, 1.0));
        let [bx, by, bz] = result.base_from_disc.translation_m;
        let [px, py, pz] = result.part.position_m;
        let report = CalibrationReport {
            time_us,
            camera_height_m: result.camera.height_m as f32,
            camera_tilt_rad: tilt as f32,
            base_yaw_rad: result.base_from_disc.yaw_rad as f32,
            base_translation_m: to_f32(&result.base_from_disc.translation_m),
            part_rotating_m: to_f32(&result.part.position_m),
            part_yaw_rotating_rad: result.part.yaw_rad as f32,
            sigma_part_m: norm3(&sigma.part_position_m) as f32,
            sigma_base_m: norm3(&sigma.base_translation_m) as f32,
            sigma_base_yaw_rad: sigma.base_yaw_rad as f32,
            frames_used: u16::try_from(result.quality.frames_used).unwrap_or(u16::MAX),
            effector_frames_used: u16::try_from(result.quality.effector_frames_used)
                .unwrap_or(u16::MAX),
            rms_reprojection_px: result.quality.rms_reprojection_px as f32,
            points_gated: result.quality.outliers_rejected,
            frames_folded: 0,
            folds_discarded: 0,
            sigma_grasp_horizontal_m: sigma.part_base_horizontal_m as f32,
            sigma_grasp_vertical_m: sigma.part_base_vertical_m as f32,
            sigma_grasp_yaw_rad: sigma.part_yaw_base_rad as f32,
        };
        Self {
            base_yaw: result.base_from_disc.yaw_rad as f32,
            base_translation: Vector3::new(bx as f32, by as f32, bz as f32),
            part_rotating: Vector3::new(px as f32, py as f32, pz as f32),
            part_yaw_rotating: result.part.yaw_rad as f32,
            disc_from_camera: rotation,
            camera_centre_disc: Vector3::new(cx, cy, cz),
            pixel_sigma_px: result.quality.pixel_sigma_px as f32,
            report,
        }
    }

    /// The report with what `calibrator` has folded and discarded so far
    /// (telemetry's `frames_folded`, `folds_discarded`).
    pub fn with_folding<const F: usize, const E: usize, const P: usize>(
        mut self,
        calibrator: &SelfCalibrator<F, E, P>,
    ) -> Self {
        self.report.frames_folded = calibrator.folded().map_or(0, |folded| folded.frames());
        self.report.folds_discarded =
            u16::try_from(calibrator.folds_discarded()).unwrap_or(u16::MAX);
        self
    }

    /// The grasp point's state in the base frame with the conveyor at
    /// `(theta, omega, alpha)`: Eq 1 and its derivatives.
    pub fn grasp_point(&self, theta: f32, omega: f32, alpha: f32) -> TaskState<f32> {
        let m = part_motion_in_base(
            self.base_yaw,
            &self.base_translation,
            &self.part_rotating,
            self.part_yaw_rotating,
            theta,
            omega,
            alpha,
        );
        TaskState {
            position: m.position_base,
            velocity: m.velocity_base,
            acceleration: m.acceleration_base,
            yaw: m.yaw_base,
            yaw_rate: m.yaw_rate,
            yaw_acceleration: m.yaw_acceleration,
        }
    }

    /// The disc's top surface height in the base frame.
    pub fn disc_height(&self) -> f32 {
        self.base_translation.z
    }

    /// The disc centre in the base frame.
    pub fn disc_centre(&self) -> Vector3<f32> {
        self.base_translation
    }

    /// Where the camera would see `p_base`, if in front of it.
    pub fn project(&self, camera: &CameraIntrinsics, p_base: &Vector3<f32>) -> Option<[f64; 2]> {
        let p = p_base.cast::<f64>() - self.base_translation.cast::<f64>();
        let (s, c) = libm::sincos(-f64::from(self.base_yaw));
        let p_disc = Vector3::new(c * p.x - s * p.y, s * p.x + c * p.y, p.z);
        let p_camera = self.disc_from_camera.transpose() * (p_disc - self.camera_centre_disc);
        (p_camera.z > 1e-6).then(|| {
            [
                camera.f_px * p_camera.x / p_camera.z + camera.cx,
                camera.f_px * p_camera.y / p_camera.z + camera.cy,
            ]
        })
    }
}
