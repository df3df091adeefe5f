//! [`TaskSpaceModel`] for the PUMA 560 model of `crate::robot`.
//!
//! Uses the model's split API (`JointTrig`, `frame_chain_with`,
//! `jacobian_dot_qd_with`, `inverse_dynamics_with`) so that one control step
//! evaluates the six `sin`/`cos` pairs and the frame chain once.

use nalgebra::{convert, Isometry3, RealField, Rotation3, Translation3, UnitQuaternion};

use super::model::{Joints, TaskKinematics, TaskSpaceModel};
use super::trig::sin_cos;
use crate::robot::{JointTrig, Puma560, SinCos};

/// The share of a joint's rated torque (the table's limit) the controller
/// commands at most. A drive's torque constant is within 5 % of the table's
/// and its commutation ripple adds up to 3 %, so the torque a joint feels is
/// up to 1.05 * 1.03 = 1.08 times the command: 0.92 of the rating keeps it
/// within the rating (0.92 * 1.0815 = 0.995).
pub const DRIVE_TORQUE_HEADROOM: f32 = 0.92;

impl<T: RealField + Copy> TaskSpaceModel<T> for Puma560<T> {
    type Configuration = JointTrig<T>;

    /// Same values as `JointTrig::new`, through [`super::trig::sin_cos`]:
    /// about 60 instructions per joint on the M4F instead of 2,100.
    fn configuration(&self, q: &Joints<T>) -> JointTrig<T> {
        JointTrig {
            joints: core::array::from_fn(|i| {
                let (sin, cos) = sin_cos(q.get(i).copied().unwrap_or_else(T::zero));
                SinCos { sin, cos }
            }),
        }
    }

    /// Same quantities as `forward_kinematics`, `jacobian` and
    /// `jacobian_dot_qd`, sharing one frame chain.
    fn task_kinematics(&self, trig: &JointTrig<T>, qd: &Joints<T>) -> TaskKinematics<T> {
        let chain = self.frame_chain_with(trig);
        let rotation = Rotation3::from_matrix_unchecked(chain.base_from_flange_rotation());
        TaskKinematics {
            base_from_flange: Isometry3::from_parts(
                Translation3::from(chain.flange_origin()),
                UnitQuaternion::from_rotation_matrix(&rotation),
            ),
            jacobian: self.jacobian_from_chain(&chain),
            jacobian_dot_qd: self.jacobian_dot_qd_with(trig, &chain, qd),
        }
    }

    /// `inverse_dynamics_with` without its friction term: the rigid body's
    /// RNEA with gravity plus `G^2 Jm qdd`.
    fn inverse_dynamics(&self, trig: &JointTrig<T>, qd: &Joints<T>, qdd: &Joints<T>) -> Joints<T> {
        self.rigid_inverse_dynamics_with(trig, qd, qdd, &(-self.gravity))
            + self.armature_inertia().component_mul(qdd)
    }

    fn friction_torque(&self, qd: &Joints<T>) -> Joints<T> {
        Puma560::friction_torque(self, qd)
    }

    /// `rne(q, 0, 0)`: friction is zero at rest and armature needs `qdd`, so
    /// this equals `Puma560::gravity_torque` with the cheaper trig.
    fn gravity_torque(&self, q: &Joints<T>) -> Joints<T> {
        let zero = Joints::zeros();
        self.inverse_dynamics_with(&self.configuration(q), &zero, &zero)
    }

    /// The rated limits times [`DRIVE_TORQUE_HEADROOM`].
    fn torque_limits(&self) -> Joints<T> {
        self.joint_limits().torque_max * convert::<f64, T>(f64::from(DRIVE_TORQUE_HEADROOM))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shared-chain evaluation equals the model's separate public calls.
    #[test]
    fn task_kinematics_matches_the_model_api() {
        let model = Puma560::<f64>::new();
        let q = Joints::new(0.3, 0.7, -2.1, 0.4, 0.9, -1.2);
        let qd = Joints::new(-0.5, 0.8, 1.1, -1.4, 0.6, 2.0);
        let k = model.task_kinematics(&model.configuration(&q), &qd);
        let pose = model.forward_kinematics(&q);
        assert!((k.base_from_flange.translation.vector - pose.translation.vector).norm() < 1e-14);
        assert!(k.base_from_flange.rotation.angle_to(&pose.rotation) < 1e-12);
        assert!((k.jacobian - model.jacobian(&q)).norm() < 1e-14);
        assert!((k.jacobian_dot_qd - model.jacobian_dot_qd(&q, &qd)).norm() < 1e-12);
        let with_drive = Puma560::<f64>::new().with_drive(crate::robot::DriveOptions {
            armature: true,
            friction: true,
        });
        let gravity = TaskSpaceModel::gravity_torque(&with_drive, &q);
        assert!((gravity - with_drive.gravity_torque(&q)).amax() < 1e-12);
        // The trait's RNEA leaves friction out; with it added back at the
        // same speeds it is the model's full inverse dynamics.
        let qdd = Joints::new(1.0, -2.0, 0.5, 3.0, -1.5, 2.5);
        let rigid =
            TaskSpaceModel::inverse_dynamics(&with_drive, &with_drive.configuration(&q), &qd, &qdd);
        let friction = TaskSpaceModel::friction_torque(&with_drive, &qd);
        assert!(friction.amax() > 1.0, "the drive's friction is on");
        assert!((rigid + friction - with_drive.inverse_dynamics(&q, &qd, &qdd)).amax() < 1e-9);
    }
}
