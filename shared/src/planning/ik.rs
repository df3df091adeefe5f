//! Inverse kinematics of the PUMA 560 by damped least squares.
//!
//! The controller of Eq 23 works in task space and needs no inverse kinematics;
//! the planner does, to prove a path is inside the joint limits before the arm
//! follows it, and to say early that a part is out of reach. DLS
//! (`dq = J^T (J J^T + lambda^2 I)^-1 e`) stays bounded at singular poses, where a
//! plain Jacobian inverse does not.

use nalgebra::{convert, Isometry3, Matrix6, RealField, Vector6};

use super::PlanError;
use crate::control::orientation_error;
use crate::robot::{JointVector, Puma560};

/// Iteration limits and tolerances.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkConfig<T> {
    /// Most Newton steps.
    pub max_iterations: u32,
    /// Position tolerance, m.
    pub position_tolerance_m: T,
    /// Orientation tolerance, rad.
    pub orientation_tolerance_rad: T,
    /// DLS damping `lambda` (m-equivalent units).
    pub damping: T,
    /// Largest joint step per iteration, rad.
    pub max_step_rad: T,
}

impl<T: RealField + Copy> Default for IkConfig<T> {
    fn default() -> Self {
        Self {
            max_iterations: 200,
            position_tolerance_m: convert(1e-5),
            orientation_tolerance_rad: convert(1e-5),
            damping: convert(1e-3),
            max_step_rad: convert(0.3),
        }
    }
}

/// The pose error `[p_target - p; log(R_target R^T)]`, in the base frame, the
/// units of the geometric Jacobian's rows (the same SO(3) error Eq 23's
/// controller uses).
pub fn pose_error<T: RealField + Copy>(target: &Isometry3<T>, pose: &Isometry3<T>) -> Vector6<T> {
    let dp = target.translation.vector - pose.translation.vector;
    let dr = orientation_error(&target.rotation, &pose.rotation);
    Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z)
}

/// Joint angles that put the flange at `target`, starting from `seed`, inside the
/// joint position limits.
pub fn solve_ik<T: RealField + Copy>(
    robot: &Puma560<T>,
    target: &Isometry3<T>,
    seed: &JointVector<T>,
    config: &IkConfig<T>,
) -> Result<JointVector<T>, PlanError> {
    let finite = target.translation.vector.iter().all(|x| x.is_finite())
        && target.rotation.coords.iter().all(|x| x.is_finite())
        && seed.iter().all(|x| x.is_finite());
    if !finite {
        return Err(PlanError::NonFinite {
            what: "IK target or seed",
        });
    }
    let limits = robot.joint_limits();
    let mut q = seed.zip_zip_map(&limits.position_min, &limits.position_max, |x, lo, hi| {
        x.max(lo).min(hi)
    });
    let lambda2 = config.damping * config.damping;
    let mut residual = (T::zero(), T::zero());
    for _ in 0..config.max_iterations {
        let pose = robot.forward_kinematics(&q);
        let error = pose_error(target, &pose);
        let position_error = error.fixed_rows::<3>(0).norm();
        let orientation_error = error.fixed_rows::<3>(3).norm();
        residual = (position_error, orientation_error);
        if position_error <= config.position_tolerance_m
            && orientation_error <= config.orientation_tolerance_rad
        {
            return Ok(q);
        }
        let jacobian = robot.jacobian(&q);
        let jjt = jacobian * jacobian.transpose() + Matrix6::identity() * lambda2;
        let Some(cholesky) = jjt.cholesky() else {
            break;
        };
        let mut step = jacobian.transpose() * cholesky.solve(&error);
        let largest = step.amax();
        if largest > config.max_step_rad {
            step *= config.max_step_rad / largest;
        }
        q = (q + step).zip_zip_map(&limits.position_min, &limits.position_max, |x, lo, hi| {
            x.max(lo).min(hi)
        });
    }
    let (p, o) = residual;
    Err(PlanError::IkDidNotConverge {
        position_error_m: nalgebra::try_convert(p).unwrap_or(f64::NAN),
        orientation_error_rad: nalgebra::try_convert(o).unwrap_or(f64::NAN),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planning::gripper_down_rotation;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    fn qn() -> JointVector<f64> {
        crate::planning::grasp_pose::ready_posture()
    }

    /// Warm starts, as the planner uses it: from 0.25 rad away on every joint.
    #[test]
    fn reaches_poses_from_forward_kinematics_with_warm_starts() {
        let robot = Puma560::<f64>::new();
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut uniform = move || crate::test_rng::splitmix(&mut state);
        for _ in 0..20 {
            let q_true = qn() + JointVector::from_fn(|_, _| uniform() * 1.2 - 0.6);
            let seed =
                q_true + JointVector::from_fn(|_, _| if uniform() < 0.5 { -0.25 } else { 0.25 });
            let target = robot.forward_kinematics(&q_true);
            let q = solve_ik(&robot, &target, &seed, &IkConfig::default()).unwrap();
            let reached = robot.forward_kinematics(&q);
            assert!(pose_error(&target, &reached).norm() < 2e-5);
        }
    }

    #[test]
    fn reaches_a_gripper_down_pose_over_the_disc() {
        let robot = Puma560::<f64>::new();
        let target = Isometry3::from_parts(
            Translation3::new(0.6, -0.15, 0.35),
            UnitQuaternion::from_rotation_matrix(&gripper_down_rotation(0.4)),
        );
        let q = solve_ik(&robot, &target, &qn(), &IkConfig::default()).unwrap();
        let z = robot.forward_kinematics(&q).rotation * Vector3::z();
        assert!((z + Vector3::z()).norm() < 1e-4);
    }

    #[test]
    fn says_when_a_pose_is_out_of_reach() {
        let robot = Puma560::<f64>::new();
        let target = Isometry3::translation(3.0, 0.0, 0.5);
        assert!(matches!(
            solve_ik(&robot, &target, &qn(), &IkConfig::default()),
            Err(PlanError::IkDidNotConverge { .. })
        ));
        let nan = Isometry3::translation(f64::NAN, 0.0, 0.5);
        assert!(matches!(
            solve_ik(&robot, &nan, &qn(), &IkConfig::default()),
            Err(PlanError::NonFinite { .. })
        ));
    }
}
