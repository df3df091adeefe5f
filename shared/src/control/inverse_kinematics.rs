//! Numerical inverse kinematics by damped Newton steps on the task error.
//!
//! Used to place the arm on a reference before the controller takes over
//! (initial state of the simulations). It reuses the pieces of Eq 23: the
//! log-map orientation error and the damped least-squares solve, so it also
//! passes through singular configurations without blowing up.

use nalgebra::{Isometry3, RealField, Vector6};

use super::dls::{solve_damped, DampingConfig};
use super::error::{ControlError, ControlInput};
use super::model::{Joints, TaskSpaceModel};
use super::orientation::orientation_error;

/// Joint position with `base_from_flange(q) = target`, starting from `seed`.
///
/// Stops when the position error is below `tolerance` (m) and the
/// orientation error below `tolerance` (rad); errors with
/// [`ControlError::InverseKinematicsDidNotConverge`] after `max_iterations`.
pub fn solve_pose<T: RealField + Copy, M: TaskSpaceModel<T>>(
    model: &M,
    target: &Isometry3<T>,
    seed: &Joints<T>,
    tolerance: T,
    max_iterations: usize,
) -> Result<Joints<T>, ControlError> {
    if !seed.iter().all(|x| x.is_finite()) {
        return Err(ControlError::NonFiniteInput(ControlInput::JointPosition));
    }
    let damping = DampingConfig {
        manipulability_threshold: nalgebra::convert(1e-3),
        max_damping: nalgebra::convert(0.05),
    };
    let mut q = *seed;
    for _ in 0..max_iterations {
        let kinematics = model.task_kinematics(&model.configuration(&q), &Joints::zeros());
        let position = target.translation.vector - kinematics.base_from_flange.translation.vector;
        let rotation = orientation_error(&target.rotation, &kinematics.base_from_flange.rotation);
        if position.norm() < tolerance && rotation.norm() < tolerance {
            return Ok(q);
        }
        let error = Vector6::new(
            position.x, position.y, position.z, rotation.x, rotation.y, rotation.z,
        );
        q += solve_damped(&kinematics.jacobian, &error, &damping)?.x;
        if !q.iter().all(|x| x.is_finite()) {
            break;
        }
    }
    Err(ControlError::InverseKinematicsDidNotConverge)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::Puma560;

    #[test]
    fn recovers_a_reachable_pose() {
        let model = Puma560::<f64>::new();
        let q_true = Joints::new(0.2, 0.6, -2.4, 0.3, 1.0, -0.4);
        let target = model.forward_kinematics(&q_true);
        let seed = q_true + Joints::new(0.1, -0.1, 0.1, -0.1, 0.1, -0.1);
        let q = solve_pose(&model, &target, &seed, 1e-10, 50).unwrap();
        let reached = model.forward_kinematics(&q);
        assert!((reached.translation.vector - target.translation.vector).norm() < 1e-9);
        assert!(reached.rotation.angle_to(&target.rotation) < 1e-9);
    }

    #[test]
    fn unreachable_pose_is_an_error() {
        let model = Puma560::<f64>::new();
        let far = Isometry3::translation(3.0, 0.0, 0.5);
        assert_eq!(
            solve_pose(&model, &far, &Joints::zeros(), 1e-9, 30),
            Err(ControlError::InverseKinematicsDidNotConverge)
        );
    }
}
