//! The contract's pinhole camera (square pixels, no distortion): pixels to rays, and
//! the projection's Jacobian (`model::Projector` projects points in a pass).

use nalgebra::{Matrix2x3, Vector2, Vector3};

use super::model::JacobianScalar;
use crate::observation::CameraIntrinsics;

/// Closest a point may come to the camera plane (m) and still be projected.
pub(super) const MIN_DEPTH_M: f64 = 1e-6;

#[derive(Debug, Clone, Copy, PartialEq)]
/// The contract's camera as the calibration computes with it.
pub struct Pinhole {
    /// Focal length, pixels.
    pub f_px: f64,
    /// Principal point, column, pixels.
    pub cx: f64,
    /// Principal point, row, pixels.
    pub cy: f64,
}

impl Pinhole {
    /// The camera of `intrinsics`.
    pub fn new(intrinsics: &CameraIntrinsics) -> Self {
        Self {
            f_px: intrinsics.f_px,
            cx: intrinsics.cx,
            cy: intrinsics.cy,
        }
    }

    /// Ray coordinates `((u - cx) / f, (v - cy) / f)` of a pixel: the image point at `f = 1`.
    pub fn ray(&self, pixel: Vector2<f64>) -> Vector2<f64> {
        Vector2::new(
            (pixel.x - self.cx) / self.f_px,
            (pixel.y - self.cy) / self.f_px,
        )
    }
}

/// The projection's Jacobian with respect to the camera-frame point, for a
/// focal length `f_px`, in the point's scalar (f64, or f32 for the bundle
/// adjustment's passes over the points).
pub fn projection_jacobian<T: JacobianScalar>(f_px: T, p_camera: &Vector3<T>) -> Matrix2x3<T> {
    let inverse_z = T::one() / p_camera.z;
    let scale = f_px * inverse_z;
    let zero = T::zero();
    Matrix2x3::new(
        scale,
        zero,
        -scale * p_camera.x * inverse_z,
        zero,
        scale,
        -scale * p_camera.y * inverse_z,
    )
}
