//! What the controller needs from a robot model.
//!
//! The control law is written against this trait rather than against
//! `Puma560` directly so that it states exactly which model terms Eq 23 uses
//! (kinematics for the errors, `J` and `Jdot qd` for the acceleration
//! resolution, one RNEA pass for the torques, the friction law for the
//! feed-forward) and so that the controller's
//! model can differ from the plant's (mismatch tests). The per-configuration
//! work (for the PUMA the six `sin`/`cos` pairs) is done once per step and
//! shared by kinematics and dynamics, which matters on the M4F.

use nalgebra::{Isometry3, Matrix6, RealField, Vector6};

/// Joint-space vector of the six-axis arm.
pub type Joints<T> = Vector6<T>;

/// Flange kinematics at one state `(q, qd)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TaskKinematics<T: RealField + Copy> {
    /// `base_from_flange` (frame {6} in the base frame).
    pub base_from_flange: Isometry3<T>,
    /// Geometric Jacobian in the base frame, rows 0-2 linear, 3-5 angular.
    pub jacobian: Matrix6<T>,
    /// `Jdot qd`: the flange's classical acceleration `[a; alpha]` at `qdd = 0`.
    pub jacobian_dot_qd: Vector6<T>,
}

/// Kinematic and dynamic terms used by the task-space computed-torque law.
pub trait TaskSpaceModel<T: RealField + Copy> {
    /// Work that depends on `q` only and is shared by the other calls.
    type Configuration;
    /// Precomputes what depends on `q` alone.
    fn configuration(&self, q: &Joints<T>) -> Self::Configuration;
    /// Pose, Jacobian and `Jdot qd` of the flange.
    fn task_kinematics(&self, config: &Self::Configuration, qd: &Joints<T>) -> TaskKinematics<T>;
    /// RNEA with gravity and the model's armature term at `(q, qd, qdd)`;
    /// friction is left out (see [`Self::friction_torque`]): Eq 23 evaluates
    /// it at the reference's joint speeds, not at the measured ones.
    fn inverse_dynamics(
        &self,
        config: &Self::Configuration,
        qd: &Joints<T>,
        qdd: &Joints<T>,
    ) -> Joints<T>;
    /// The joint friction the motors must overcome at joint speeds `qd`
    /// (zeros for a model without friction).
    fn friction_torque(&self, qd: &Joints<T>) -> Joints<T>;
    /// Torque that holds the arm still at `q`.
    fn gravity_torque(&self, q: &Joints<T>) -> Joints<T>;
    /// Symmetric torque limits `|tau_i| <= limit_i` (N m).
    fn torque_limits(&self) -> Joints<T>;
}
