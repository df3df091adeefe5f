//! The true geometry of one workcell: camera, disc, part and robot base, with
//! the transforms of the paper's Eq 1 (`p_base = Rz(yaw) Rz(theta) p_rotating + T`).

use nalgebra::Vector3;
use shared::observation::{
    BaseFromDisc, CalibrationQuality, CalibrationResult, CameraEstimate, LogHeader, PartEstimate,
    RigidTransform, LOG_VERSION, MAX_PART_FEATURES,
};

use super::camera::PinholeCamera;
use crate::geometry::{rotation_z, rows, to_array, wrap_angle};

#[derive(Debug, Clone, PartialEq)]
pub struct Workcell {
    pub camera: PinholeCamera,
    /// The paper's L: the reference mark sits at `(L, 0, 0)` in the rotating frame.
    pub reference_radius_m: f64,
    /// The part's feature points in the rotating frame (z = height above the disc).
    pub features_rotating: Vec<Vector3<f64>>,
    /// Angle of the disc's X axis in the base frame (Eq 14), in (-pi, pi].
    pub base_from_disc_yaw_rad: f64,
    /// The disc centre in the base frame (Eq 13's `T`).
    pub base_from_disc_translation_m: Vector3<f64>,
}

impl Workcell {
    pub fn header(&self) -> LogHeader {
        LogHeader {
            version: LOG_VERSION,
            camera: self.camera.intrinsics,
            reference_radius_m: self.reference_radius_m,
            part_feature_count: self.features_rotating.len(),
            disc_radius_m: None,
        }
    }

    /// A rotating-frame point in the disc frame at conveyor angle `theta` (Eq 2).
    pub fn disc_from_rotating(theta_rad: f64, p_rotating: &Vector3<f64>) -> Vector3<f64> {
        rotation_z(theta_rad) * p_rotating
    }

    pub fn base_from_disc(&self, p_disc: &Vector3<f64>) -> Vector3<f64> {
        rotation_z(self.base_from_disc_yaw_rad) * p_disc + self.base_from_disc_translation_m
    }

    pub fn disc_from_base(&self, p_base: &Vector3<f64>) -> Vector3<f64> {
        rotation_z(-self.base_from_disc_yaw_rad) * (p_base - self.base_from_disc_translation_m)
    }

    /// The reference mark in the disc frame at conveyor angle `theta`.
    pub fn reference_disc(&self, theta_rad: f64) -> Vector3<f64> {
        Self::disc_from_rotating(theta_rad, &Vector3::new(self.reference_radius_m, 0.0, 0.0))
    }

    /// The true values in the calibration-result format; `quality` describes the
    /// recorded log (what a perfect estimator would report).
    pub fn truth(&self, quality: CalibrationQuality) -> CalibrationResult {
        let features_m: heapless::Vec<[f64; 3], MAX_PART_FEATURES> = self
            .features_rotating
            .iter()
            .take(MAX_PART_FEATURES)
            .map(to_array)
            .collect();
        let count = self.features_rotating.len().max(1) as f64;
        let mean = self
            .features_rotating
            .iter()
            .fold(Vector3::zeros(), |sum, p| sum + p)
            / count;
        let yaw_rad = match (
            self.features_rotating.first(),
            self.features_rotating.get(1),
        ) {
            (Some(first), Some(second)) => (second.y - first.y).atan2(second.x - first.x),
            _ => 0.0,
        };
        CalibrationResult {
            camera: CameraEstimate {
                height_m: self.camera.height_m(),
                disc_from_camera: RigidTransform {
                    rotation: rows(&self.camera.disc_from_camera_rotation),
                    translation_m: to_array(&self.camera.optical_centre_disc),
                },
            },
            part: PartEstimate {
                features_m,
                position_m: to_array(&mean),
                yaw_rad,
            },
            base_from_disc: BaseFromDisc {
                yaw_rad: wrap_angle(self.base_from_disc_yaw_rad),
                translation_m: to_array(&self.base_from_disc_translation_m),
            },
            quality,
        }
    }
}
