//! The workcell model every estimate describes, and the predicted image of each kind of
//! observation under it (Eq 1 for the part, Eq 9 for the end effector, the reference
//! point at `(L cos theta, L sin theta, 0)` and the disc centre at the origin).

use nalgebra::{Matrix2x3, Matrix3, RealField, Rotation3, SMatrix, Vector2, Vector3};

use super::frame_store::FrameView;
use super::pinhole::{projection_jacobian, Pinhole, MIN_DEPTH_M};
use super::records::{to_vector, EffectorRecord, FrameRecord};
use super::uncertainty::GraspGeometry;
use crate::observation::MAX_PART_FEATURES;

/// Camera pose, part feature points and `base_from_disc`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorkcellModel {
    /// `p_disc = disc_from_camera * p_camera + camera_centre_disc`.
    pub disc_from_camera: Rotation3<f64>,
    /// The camera's centre in the disc frame, m.
    pub camera_centre_disc: Vector3<f64>,
    /// Feature points in the rotating frame; `0..feature_count` are meaningful.
    pub features_rotating: [Vector3<f64>; MAX_PART_FEATURES],
    /// How many features the part has.
    pub feature_count: usize,
    /// `p_base = Rz(base_yaw) p_disc + base_translation`.
    pub base_yaw: f64,
    /// `base_from_disc`'s translation, m.
    pub base_translation: Vector3<f64>,
}

/// `Rz(angle)`, the paper's Eq 2.
pub fn rotation_z(angle: f64) -> Matrix3<f64> {
    let (s, c) = libm::sincos(angle);
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// What an image point is the image of.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Target {
    /// A point fixed in the disc frame with known coordinates (centre, reference point).
    KnownDisc(Vector3<f64>),
    /// Feature `index` of the part, seen at conveyor angle `theta`.
    Feature {
        /// Which feature.
        index: usize,
        /// `cos theta`, `sin theta` of the conveyor angle: computed once a frame
        /// (a software sincos is thousands of instructions on the Cortex-M4F).
        cos_sin: [f64; 2],
    },
    /// An end-effector point with known base-frame coordinates.
    Effector(Vector3<f64>),
}

/// One measured image point and what it shows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// The measured pixel.
    pub pixel: Vector2<f64>,
    /// What it is the image of.
    pub target: Target,
}

/// Jacobian of one residual: camera (rotation increment, centre) and, for features and the
/// end effector, the block of the unknowns it depends on; in f64, or in f32 where the
/// bundle adjustment sums its normal equations ([`super::refine`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResidualJacobian<T: nalgebra::Scalar = f64> {
    /// d residual / d camera pose (rotation, then centre).
    pub camera: SMatrix<T, 2, 6>,
    /// The other unknowns' block.
    pub other: OtherBlock<T>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
/// The block of a residual's Jacobian besides the camera's.
pub enum OtherBlock<T: nalgebra::Scalar = f64> {
    /// The point is known (centre, reference): no other unknown.
    None,
    /// d residual / d feature point (rotating frame).
    Feature {
        /// Which feature.
        index: usize,
        /// d residual / d feature point.
        jacobian: Matrix2x3<T>,
    },
    /// d residual / d (base_yaw, base_translation).
    Base(SMatrix<T, 2, 4>),
}

/// The scalars a residual and its Jacobian are computed in ([`Projector`]): f64,
/// and f32 (the Cortex-M4F's FPU).
pub trait JacobianScalar: RealField + Copy {
    /// The nearest value of this type.
    fn nearest(value: f64) -> Self;
}

impl JacobianScalar for f64 {
    fn nearest(value: f64) -> Self {
        value
    }
}

impl JacobianScalar for f32 {
    fn nearest(value: f64) -> Self {
        value as f32
    }
}

/// `Rz(theta)` from its cosine and sine.
fn planar_rotation([c, s]: [f64; 2]) -> Matrix3<f64> {
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// Calls `visit` for every stored image point with the given reference radius.
pub fn for_each_observation(
    frames: FrameView<'_>,
    effectors: &[EffectorRecord],
    feature_count: usize,
    reference_radius_m: f64,
    mut visit: impl FnMut(&Observation),
) {
    for frame in frames.iter() {
        for_each_frame_observation(&frame, feature_count, reference_radius_m, &mut visit);
    }
    for sighting in effectors {
        for_each_sighting_observation(sighting, &mut visit);
    }
}

/// Calls `visit` for the image points of one frame (disc centre, reference point, the
/// part's features).
pub fn for_each_frame_observation(
    frame: &FrameRecord<'_>,
    feature_count: usize,
    reference_radius_m: f64,
    mut visit: impl FnMut(&Observation),
) {
    if let Some(centre) = frame.centre {
        visit(&Observation {
            pixel: to_vector(centre),
            target: Target::KnownDisc(Vector3::zeros()),
        });
    }
    if frame.reference.is_none() && frame.part.is_none() {
        return;
    }
    // One sincos a frame, for the reference point and the part alike.
    let (s, c) = libm::sincos(frame.theta);
    if let Some(reference) = frame.reference {
        let p_disc = Vector3::new(reference_radius_m * c, reference_radius_m * s, 0.0);
        visit(&Observation {
            pixel: to_vector(reference),
            target: Target::KnownDisc(p_disc),
        });
    }
    if let Some(part) = frame.part {
        for (index, pixel) in part.iter().take(feature_count).enumerate() {
            visit(&Observation {
                pixel: to_vector(*pixel),
                target: Target::Feature {
                    index,
                    cos_sin: [c, s],
                },
            });
        }
    }
}

/// Calls `visit` for the two end-effector points of one sighting.
pub fn for_each_sighting_observation(
    sighting: &EffectorRecord,
    mut visit: impl FnMut(&Observation),
) {
    for which in 0..2 {
        visit(&Observation {
            pixel: sighting.pixel(which),
            target: Target::Effector(sighting.base_point(which)),
        });
    }
}

impl WorkcellModel {
    /// The part's mean and yaw line, where its uncertainty in the base frame
    /// is taken (`EstimateUncertainty::part_base_*`).
    pub fn grasp_geometry(&self) -> GraspGeometry {
        let features = self.features_rotating.iter().take(self.feature_count);
        let count = self.feature_count.clamp(1, MAX_PART_FEATURES) as f64;
        let part_rotating = features.fold(Vector3::zeros(), |sum, f| sum + f) / count;
        let yaw_line_rotating = match self.features_rotating.get(..2) {
            Some([first, second]) if self.feature_count >= 2 => second - first,
            _ => Vector3::zeros(),
        };
        GraspGeometry {
            part_rotating,
            yaw_line_rotating,
            base_yaw: self.base_yaw,
        }
    }

    /// The increment that [`WorkcellModel::retract`] applies to `from` to reach this
    /// model (to first order in the rotation): where a folded linearisation at `from`
    /// ([`super::folded`]) reads the current model.
    pub fn difference_from(&self, from: &WorkcellModel) -> SMatrix<f64, PARAMETERS, 1> {
        let mut increment = SMatrix::<f64, PARAMETERS, 1>::zeros();
        let relative = from.disc_from_camera.inverse() * self.disc_from_camera;
        increment
            .fixed_view_mut::<3, 1>(0, 0)
            .copy_from(&relative.scaled_axis());
        increment
            .fixed_view_mut::<3, 1>(3, 0)
            .copy_from(&(self.camera_centre_disc - from.camera_centre_disc));
        for (slot, (to, at)) in self
            .features_rotating
            .iter()
            .zip(&from.features_rotating)
            .enumerate()
        {
            increment
                .fixed_view_mut::<3, 1>(FEATURE_OFFSET + 3 * slot, 0)
                .copy_from(&(to - at));
        }
        if let Some(yaw) = increment.get_mut(BASE_OFFSET) {
            *yaw = self.base_yaw - from.base_yaw;
        }
        increment
            .fixed_view_mut::<3, 1>(BASE_OFFSET + 1, 0)
            .copy_from(&(self.base_translation - from.base_translation));
        increment
    }

    /// Applies an increment laid out as [rotation (3), camera centre (3), features (3 each,
    /// `MAX_PART_FEATURES` slots), base yaw, base translation (3)].
    pub fn retract(&self, increment: &SMatrix<f64, PARAMETERS, 1>) -> Self {
        let mut next = *self;
        let rotation: Vector3<f64> = increment.fixed_view::<3, 1>(0, 0).into_owned();
        next.disc_from_camera = self.disc_from_camera * Rotation3::new(rotation);
        next.disc_from_camera.renormalize();
        next.camera_centre_disc += increment.fixed_view::<3, 1>(3, 0);
        for (slot, feature) in next.features_rotating.iter_mut().enumerate() {
            *feature += increment.fixed_view::<3, 1>(FEATURE_OFFSET + 3 * slot, 0);
        }
        next.base_yaw += increment.fixed_view::<1, 1>(BASE_OFFSET, 0).x;
        next.base_translation += increment.fixed_view::<3, 1>(BASE_OFFSET + 1, 0);
        next
    }
}

/// A [`WorkcellModel`] made ready for a pass over many points, in the
/// scalar `T` the pass computes in: the rotations every residual needs are
/// computed once (each point used to take its own inverse camera rotation
/// and, for a sighting, a software sincos of the base yaw: thousands of
/// instructions on the Cortex-M4F). In f64 it is the model; in f32 every
/// residual is good to some 3e-5 px (a pixel coordinate of 256 holds 1.5e-5
/// px in f32), a ten-thousandth of the pixel noise: what a Gauss-Newton
/// step needs, though not what a cost comparison of two nearby models does
/// (see `refine`'s passes).
#[derive(Debug, Clone, Copy)]
pub struct Projector<T: JacobianScalar> {
    f_px: T,
    centre_px: Vector2<T>,
    camera_from_disc: Matrix3<T>,
    camera_centre_disc: Vector3<T>,
    features_rotating: [Vector3<T>; MAX_PART_FEATURES],
    base_translation: Vector3<T>,
    /// `Rz(-base_yaw)`.
    disc_from_base: Matrix3<T>,
}

impl<T: JacobianScalar> Projector<T> {
    /// `model` seen through `pinhole`, in `T`.
    pub fn new(model: &WorkcellModel, pinhole: &Pinhole) -> Self {
        let to_t = |value: f64| T::nearest(value);
        Self {
            f_px: to_t(pinhole.f_px),
            centre_px: Vector2::new(to_t(pinhole.cx), to_t(pinhole.cy)),
            camera_from_disc: model.disc_from_camera.inverse().matrix().map(to_t),
            camera_centre_disc: model.camera_centre_disc.map(to_t),
            features_rotating: model.features_rotating.map(|p| p.map(to_t)),
            base_translation: model.base_translation.map(to_t),
            disc_from_base: rotation_z(-model.base_yaw).map(to_t),
        }
    }

    /// Disc-frame coordinates of the observed point under the model.
    pub fn point_disc(&self, target: &Target) -> Vector3<T> {
        let to_t = |value: f64| T::nearest(value);
        match *target {
            Target::KnownDisc(p) => p.map(to_t),
            Target::Feature {
                index,
                cos_sin: [c, s],
            } => {
                let p = self
                    .features_rotating
                    .get(index)
                    .copied()
                    .unwrap_or_else(Vector3::zeros);
                let (c, s) = (to_t(c), to_t(s));
                Vector3::new(c * p.x - s * p.y, s * p.x + c * p.y, p.z)
            }
            Target::Effector(p_base) => {
                self.disc_from_base * (p_base.map(to_t) - self.base_translation)
            }
        }
    }

    /// The point in the camera frame and its pixel, or `None` behind the camera.
    fn image(&self, p_disc: &Vector3<T>) -> Option<(Vector3<T>, Vector2<T>)> {
        let p_camera = self.camera_from_disc * (p_disc - self.camera_centre_disc);
        if p_camera.z <= T::nearest(MIN_DEPTH_M) {
            return None;
        }
        let pixel = Vector2::new(
            self.f_px * p_camera.x / p_camera.z,
            self.f_px * p_camera.y / p_camera.z,
        ) + self.centre_px;
        Some((p_camera, pixel))
    }

    /// Predicted minus measured pixel, or `None` when the point is behind the camera.
    pub fn residual(&self, observation: &Observation) -> Option<Vector2<T>> {
        let p_disc = self.point_disc(&observation.target);
        let (_, pixel) = self.image(&p_disc)?;
        Some(pixel - observation.pixel.map(|v| T::nearest(v)))
    }

    /// The residual and its Jacobian for the increments of [`WorkcellModel::retract`].
    pub fn residual_with_jacobian(
        &self,
        observation: &Observation,
    ) -> Option<(Vector2<T>, ResidualJacobian<T>)> {
        let p_disc = self.point_disc(&observation.target);
        let (p_camera, pixel) = self.image(&p_disc)?;
        let projection = projection_jacobian(self.f_px, &p_camera);
        // Right-perturbed rotation R Exp(delta): p_camera -> p_camera - delta x p_camera.
        let d_rotation = projection * p_camera.cross_matrix();
        let d_point_disc = projection * self.camera_from_disc;
        let d_centre = -d_point_disc;
        let mut camera = SMatrix::<T, 2, 6>::zeros();
        camera.fixed_view_mut::<2, 3>(0, 0).copy_from(&d_rotation);
        camera.fixed_view_mut::<2, 3>(0, 3).copy_from(&d_centre);
        let other = match observation.target {
            Target::KnownDisc(_) => OtherBlock::None,
            Target::Feature { index, cos_sin } => OtherBlock::Feature {
                index,
                jacobian: d_point_disc * planar_rotation(cos_sin).map(|v| T::nearest(v)),
            },
            Target::Effector(_) => {
                // p_disc = Rz(-yaw) (p_base - t): d/d yaw = (p_disc.y, -p_disc.x, 0).
                let d_yaw = d_point_disc * Vector3::new(p_disc.y, -p_disc.x, T::zero());
                let d_translation = -(d_point_disc * self.disc_from_base);
                let mut block = SMatrix::<T, 2, 4>::zeros();
                block.fixed_view_mut::<2, 1>(0, 0).copy_from(&d_yaw);
                block.fixed_view_mut::<2, 3>(0, 1).copy_from(&d_translation);
                OtherBlock::Base(block)
            }
        };
        Some((
            pixel - observation.pixel.map(|v| T::nearest(v)),
            ResidualJacobian { camera, other },
        ))
    }
}

/// Offset of the first feature's parameters.
pub const FEATURE_OFFSET: usize = 6;
/// Offset of `base_yaw` (followed by the translation).
pub const BASE_OFFSET: usize = FEATURE_OFFSET + 3 * MAX_PART_FEATURES;
/// Parameters of the full model: camera 6, features 3 each, base 4.
pub const PARAMETERS: usize = BASE_OFFSET + 4;
