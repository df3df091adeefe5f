//! The pinhole camera of the contract: square pixels, no distortion, known
//! intrinsics (paper assumption A5), posed by `disc_from_camera`.

use nalgebra::{Matrix3, Vector3};
use shared::observation::{CameraIntrinsics, PixelPoint};

/// Depth below which a point counts as behind (or in) the camera and is not imaged.
const MIN_DEPTH_M: f64 = 1e-6;

#[derive(Debug, Clone, PartialEq)]
pub struct PinholeCamera {
    pub intrinsics: CameraIntrinsics,
    /// Columns are the camera's x, y, z axes in the disc frame: `p_disc = R * p_camera + t`.
    pub disc_from_camera_rotation: Matrix3<f64>,
    /// The optical centre in the disc frame.
    pub optical_centre_disc: Vector3<f64>,
}

impl PinholeCamera {
    /// Image of a disc-frame point, or `None` when it is behind the camera.
    /// (Inside-the-image is checked separately: noise may move a point out.)
    pub fn project(&self, p_disc: &Vector3<f64>) -> Option<PixelPoint> {
        let p_camera =
            self.disc_from_camera_rotation.transpose() * (p_disc - self.optical_centre_disc);
        if p_camera.z < MIN_DEPTH_M {
            return None;
        }
        let CameraIntrinsics { f_px, cx, cy, .. } = self.intrinsics;
        Some([
            f_px * p_camera.x / p_camera.z + cx,
            f_px * p_camera.y / p_camera.z + cy,
        ])
    }

    /// Whether `p` is inside the image with at least `margin_px` to spare on every side.
    pub fn contains_with_margin(&self, p: PixelPoint, margin_px: f64) -> bool {
        let [u, v] = p;
        let CameraIntrinsics { width, height, .. } = self.intrinsics;
        u >= -0.5 + margin_px
            && u <= f64::from(width) - 0.5 - margin_px
            && v >= -0.5 + margin_px
            && v <= f64::from(height) - 0.5 - margin_px
    }

    /// The image of `p_disc` if it lies in view with `margin_px` to spare.
    pub fn project_in_view(&self, p_disc: &Vector3<f64>, margin_px: f64) -> Option<PixelPoint> {
        self.project(p_disc)
            .filter(|&p| self.contains_with_margin(p, margin_px))
    }

    /// Height of the optical centre above the disc plane.
    pub fn height_m(&self) -> f64 {
        self.optical_centre_disc.z
    }
}
