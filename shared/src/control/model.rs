//! What the controller needs from a robot model.
//!
//! The control law is written against this trait rather than against
//! `Puma560` directly so that it states exactly which model terms Eq 23 uses
//! (kinematics for the errors, `J` and `Jdot qd` for the acceleration
//! resolution, one RNEA pass for the torques) and so that the controller's
//! model can differ from the plant's (mismatch tests).

use nalgebra::{Isometry3, Matrix6, RealField, Vector6};

/// Joint-space vector of the six-axis arm.
pub type Joints<T> = Vector6<T>;

/// Kinematic and dynamic terms used by the task-space computed-torque law.
pub trait TaskSpaceModel<T: RealField + Copy> {
    /// `base_from_flange` (frame {6} in the base frame).
    fn base_from_flange(&self, q: &Joints<T>) -> Isometry3<T>;
    /// Geometric Jacobian in the base frame, rows 0-2 linear, 3-5 angular.
    fn jacobian(&self, q: &Joints<T>) -> Matrix6<T>;
    /// `Jdot qd`: the flange's classical acceleration at `qdd = 0`.
    fn jacobian_dot_qd(&self, q: &Joints<T>, qd: &Joints<T>) -> Vector6<T>;
    /// RNEA with gravity (and the model's armature/friction terms).
    fn inverse_dynamics(&self, q: &Joints<T>, qd: &Joints<T>, qdd: &Joints<T>) -> Joints<T>;
    /// Torque that holds the arm still at `q`.
    fn gravity_torque(&self, q: &Joints<T>) -> Joints<T>;
    /// Symmetric torque limits `|tau_i| <= limit_i` [N m].
    fn torque_limits(&self) -> Joints<T>;
}
