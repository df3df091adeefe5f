//! The workcell as the batch solve parameterises it, the predicted pixel of
//! each observation and its analytic Jacobian.
//!
//! Written apart from `shared::calibration::model` on purpose (a sign error in
//! one cannot hide in the other), and parameterised differently: the camera is
//! `p_camera = camera_from_disc * p_disc + camera_translation`, with a rotation
//! increment applied on the left in the camera frame, where `shared` moves
//! `disc_from_camera` on the right and the optical centre in the disc frame.
//! The point models are the paper's: Eq 1 for a part feature
//! (`p_disc = Rz(theta) p_rotating`), Eq 9 for an end-effector point
//! (`p_disc = Rz(-yaw) (p_base - translation)`), and the disc centre and the
//! reference point at known disc coordinates.

use nalgebra::{DVector, Matrix2x3, Matrix3, Rotation3, Vector2, Vector3};
use shared::observation::CameraIntrinsics;

use super::observations::{Observation, Target};

/// Closest a point may come to the camera's plane and still be projected, m.
const MIN_DEPTH_M: f64 = 1e-6;

/// Camera pose, part features and `base_from_disc`.
#[derive(Debug, Clone, PartialEq)]
pub struct BatchModel {
    /// `p_camera = camera_from_disc * p_disc + camera_translation`.
    pub camera_from_disc: Rotation3<f64>,
    /// The disc origin in the camera frame, m.
    pub camera_translation: Vector3<f64>,
    /// Feature points in the rotating frame, m.
    pub features_rotating: Vec<Vector3<f64>>,
    /// `p_base = Rz(base_yaw) p_disc + base_translation` (Eq 14), rad, unwrapped.
    pub base_yaw_rad: f64,
    /// The disc centre in the base frame, m.
    pub base_translation: Vector3<f64>,
}

/// `Rz(angle)` (the paper's Eq 2).
pub fn rotation_z(angle_rad: f64) -> Matrix3<f64> {
    crate::geometry::rotation_z(angle_rad)
}

/// Where each unknown sits in the parameter vector: camera rotation increment
/// (3), camera translation (3), 3 per feature, then base yaw and translation x,
/// y (and z unless the disc height in the base frame is known). Without any
/// end-effector sighting the base is unobservable and left out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    pub feature_count: usize,
    pub base_free: bool,
    pub base_height_free: bool,
}

/// Most parameter columns one observation touches: the camera's 6 and the base's 4.
pub const MAX_COLUMNS: usize = 10;

impl Layout {
    pub const CAMERA_ROTATION: usize = 0;
    pub const CAMERA_TRANSLATION: usize = 3;

    pub fn feature(&self, index: usize) -> usize {
        6 + 3 * index
    }

    /// Offset of the base yaw (followed by its translation), if the base is free.
    pub fn base(&self) -> Option<usize> {
        self.base_free.then(|| 6 + 3 * self.feature_count)
    }

    /// Translation axes of the base that are free (z only without a known disc height).
    pub fn base_axes(&self) -> usize {
        if self.base_height_free {
            3
        } else {
            2
        }
    }

    /// Unknowns solved for.
    pub fn parameter_count(&self) -> usize {
        6 + 3 * self.feature_count + self.base().map_or(0, |_| 1 + self.base_axes())
    }
}

/// The residual (predicted minus measured pixel) and its nonzero Jacobian columns.
#[derive(Debug, Clone, Copy)]
pub struct Linearised {
    pub residual: Vector2<f64>,
    columns: [(usize, Vector2<f64>); MAX_COLUMNS],
    len: usize,
}

impl Linearised {
    fn push(&mut self, index: usize, column: Vector2<f64>) {
        if let Some(slot) = self.columns.get_mut(self.len) {
            *slot = (index, column);
            self.len += 1;
        }
    }

    /// `(parameter index, d residual / d parameter)` of every parameter it depends on.
    pub fn columns(&self) -> &[(usize, Vector2<f64>)] {
        self.columns.get(..self.len).unwrap_or(&[])
    }
}

/// The pinhole of the contract: `u = f x / z + cx`, `v = f y / z + cy`, and its
/// Jacobian with respect to the camera-frame point; `None` at or behind the camera.
fn project(
    camera: &CameraIntrinsics,
    p_camera: &Vector3<f64>,
) -> Option<(Vector2<f64>, Matrix2x3<f64>)> {
    // NaN depth is refused along with depths at or behind the camera.
    if p_camera.z.is_nan() || p_camera.z <= MIN_DEPTH_M {
        return None;
    }
    let inverse_z = 1.0 / p_camera.z;
    let (x, y) = (p_camera.x * inverse_z, p_camera.y * inverse_z);
    let scale = camera.f_px * inverse_z;
    let pixel = Vector2::new(camera.f_px * x + camera.cx, camera.f_px * y + camera.cy);
    let jacobian = Matrix2x3::new(scale, 0.0, -scale * x, 0.0, scale, -scale * y);
    Some((pixel, jacobian))
}

impl BatchModel {
    /// The observed point in the disc frame under this model.
    pub fn point_disc(&self, target: &Target) -> Vector3<f64> {
        match *target {
            Target::KnownDisc(p_disc) => p_disc,
            Target::Feature { index, theta_rad } => {
                let p_rotating = self
                    .features_rotating
                    .get(index)
                    .copied()
                    .unwrap_or_else(Vector3::zeros);
                rotation_z(theta_rad) * p_rotating
            }
            Target::Effector(p_base) => {
                rotation_z(-self.base_yaw_rad) * (p_base - self.base_translation)
            }
        }
    }

    /// Predicted minus measured pixel; `None` when the point is behind the camera.
    pub fn residual(
        &self,
        camera: &CameraIntrinsics,
        observation: &Observation,
    ) -> Option<Vector2<f64>> {
        let p_camera =
            self.camera_from_disc * self.point_disc(&observation.target) + self.camera_translation;
        project(camera, &p_camera).map(|(pixel, _)| pixel - observation.pixel)
    }

    /// The residual with its analytic Jacobian in `layout`'s parameters.
    pub fn linearise(
        &self,
        camera: &CameraIntrinsics,
        layout: &Layout,
        observation: &Observation,
    ) -> Option<Linearised> {
        let p_disc = self.point_disc(&observation.target);
        let rotation = self.camera_from_disc.matrix();
        let rotated = rotation * p_disc;
        let (pixel, d_pixel) = project(camera, &(rotated + self.camera_translation))?;
        let mut out = Linearised {
            residual: pixel - observation.pixel,
            columns: [(0, Vector2::zeros()); MAX_COLUMNS],
            len: 0,
        };
        // Exp(delta) q = q + delta x q = q - [q]x delta: the rotation increment's block.
        let d_rotation = d_pixel * (-rotated.cross_matrix());
        for axis in 0..3 {
            out.push(
                Layout::CAMERA_ROTATION + axis,
                d_rotation.column(axis).into_owned(),
            );
            out.push(
                Layout::CAMERA_TRANSLATION + axis,
                d_pixel.column(axis).into_owned(),
            );
        }
        let d_point_disc = d_pixel * rotation;
        match observation.target {
            Target::KnownDisc(_) => {}
            Target::Feature { index, theta_rad } => {
                let d_feature = d_point_disc * rotation_z(theta_rad);
                for axis in 0..3 {
                    out.push(
                        layout.feature(index) + axis,
                        d_feature.column(axis).into_owned(),
                    );
                }
            }
            Target::Effector(_) => {
                if let Some(base) = layout.base() {
                    // d Rz(-yaw) w / d yaw = (p_disc.y, -p_disc.x, 0).
                    out.push(base, d_point_disc * Vector3::new(p_disc.y, -p_disc.x, 0.0));
                    let d_translation = -(d_point_disc * rotation_z(-self.base_yaw_rad));
                    for axis in 0..layout.base_axes() {
                        out.push(base + 1 + axis, d_translation.column(axis).into_owned());
                    }
                }
            }
        }
        Some(out)
    }

    /// The model moved by `step` (laid out as `layout`).
    pub fn retract(&self, layout: &Layout, step: &DVector<f64>) -> Self {
        let at = |index: usize| step.get(index).copied().unwrap_or(0.0);
        let vector = |offset: usize| Vector3::new(at(offset), at(offset + 1), at(offset + 2));
        let mut next = self.clone();
        next.camera_from_disc =
            Rotation3::new(vector(Layout::CAMERA_ROTATION)) * self.camera_from_disc;
        next.camera_from_disc.renormalize();
        next.camera_translation += vector(Layout::CAMERA_TRANSLATION);
        for (index, feature) in next.features_rotating.iter_mut().enumerate() {
            *feature += vector(layout.feature(index));
        }
        if let Some(base) = layout.base() {
            next.base_yaw_rad += at(base);
            for axis in 0..layout.base_axes() {
                next.base_translation[axis] += at(base + 1 + axis);
            }
        }
        next
    }

    /// The optical centre in the disc frame, `-camera_from_disc^T camera_translation`.
    pub fn camera_centre_disc(&self) -> Vector3<f64> {
        -(self.camera_from_disc.inverse() * self.camera_translation)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> CameraIntrinsics {
        CameraIntrinsics {
            width: 256,
            height: 256,
            f_px: 290.0,
            cx: 127.5,
            cy: 127.5,
        }
    }

    fn model() -> BatchModel {
        BatchModel {
            camera_from_disc: Rotation3::new(Vector3::new(3.0, 0.2, -0.4)),
            camera_translation: Vector3::new(0.1, -0.2, 2.3),
            features_rotating: vec![
                Vector3::new(0.2, 0.05, 0.04),
                Vector3::new(0.25, 0.06, 0.05),
            ],
            base_yaw_rad: 0.7,
            base_translation: Vector3::new(0.9, -0.3, -0.12),
        }
    }

    /// The analytic Jacobian against central differences through `retract`, for
    /// every kind of observation and both base layouts.
    #[test]
    fn analytic_jacobian_matches_central_differences() {
        let camera = camera();
        let model = model();
        let observations = [
            Target::KnownDisc(Vector3::new(0.3, 0.1, 0.0)),
            Target::Feature {
                index: 1,
                theta_rad: 2.1,
            },
            Target::Effector(Vector3::new(0.8, -0.2, 0.1)),
        ]
        .map(|target| Observation {
            pixel: Vector2::new(100.0, 90.0),
            target,
            frame: 0,
        });
        for base_height_free in [true, false] {
            let layout = Layout {
                feature_count: 2,
                base_free: true,
                base_height_free,
            };
            for observation in &observations {
                let linearised = model.linearise(&camera, &layout, observation).unwrap();
                let mut analytic = vec![Vector2::zeros(); layout.parameter_count()];
                for (index, column) in linearised.columns() {
                    analytic[*index] += column;
                }
                for (index, expected) in analytic.iter().enumerate() {
                    let h = 1e-6;
                    let mut step = DVector::zeros(layout.parameter_count());
                    step[index] = h;
                    let plus = model.retract(&layout, &step).residual(&camera, observation);
                    step[index] = -h;
                    let minus = model.retract(&layout, &step).residual(&camera, observation);
                    let numeric = (plus.unwrap() - minus.unwrap()) / (2.0 * h);
                    assert!(
                        (numeric - expected).norm() < 1e-5 * (1.0 + numeric.norm()),
                        "parameter {index} of {observation:?}: {numeric} against {expected}"
                    );
                }
            }
        }
    }
}
