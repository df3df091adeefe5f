//! A task-space path the gripper follows, and its proof in joint space.
//!
//! Every plan of the pick (intercept quintics, arcs round the base axis) is
//! checked the same way before the arm follows it: inverse kinematics at every
//! sample, joint speeds `J^-1 v` and torques `RNEA(q, qd, J^-1 (a - Jdot qd))`
//! within a fraction of the robot's limits (the rest is left to Eq 23's feedback).

use nalgebra::{convert, RealField};

use super::ik::{solve_ik, IkConfig};
use super::{PlanError, TaskState};
use crate::robot::{JointVector, Puma560};

/// A desired flange motion over `[0, duration]` (gripper down, yaw about Z).
pub trait TaskPath<T: RealField + Copy> {
    fn duration(&self) -> T;
    /// The desired state at `t` (clamped to the path).
    fn sample(&self, t: T) -> TaskState<T>;
}

/// `samples` evenly spaced times over the path, both ends included.
pub fn sample_times<T: RealField + Copy>(duration: T, samples: usize) -> impl Iterator<Item = T> {
    let n = samples.max(2);
    let last: T = convert((n - 1) as f64);
    (0..n).map(move |i| duration * convert::<f64, T>(i as f64) / last)
}

/// Proves `path` in joint space from `q_start`: reachable at every sample, joint
/// speeds and torques within `fraction` of the robot's limits. Returns the joint
/// angles at the end.
pub fn check_joint_limits<T: RealField + Copy>(
    path: &impl TaskPath<T>,
    robot: &Puma560<T>,
    q_start: &JointVector<T>,
    samples: usize,
    fraction: T,
) -> Result<JointVector<T>, PlanError> {
    let limits = robot.joint_limits();
    let ik = IkConfig::default();
    let mut q = *q_start;
    for t in sample_times(path.duration(), samples) {
        let time_s: f64 = nalgebra::try_convert(t).unwrap_or(f64::NAN);
        let state = path.sample(t);
        q = solve_ik(robot, &state.pose(), &q, &ik)?;
        let lu = robot.jacobian(&q).lu();
        let qd = lu
            .solve(&state.twist())
            .ok_or(PlanError::Singular { time_s })?;
        let bias = robot.jacobian_dot_qd(&q, &qd);
        let qdd = lu
            .solve(&(state.acceleration6() - bias))
            .ok_or(PlanError::Singular { time_s })?;
        if let Some(joint) = first_over(&qd, &limits.velocity_max, fraction) {
            return Err(PlanError::JointVelocityLimit { joint, time_s });
        }
        let tau = robot.inverse_dynamics(&q, &qd, &qdd);
        if let Some(joint) = first_over(&tau, &limits.torque_max, fraction) {
            return Err(PlanError::JointTorqueLimit { joint, time_s });
        }
    }
    Ok(q)
}

/// The first joint whose `|value|` exceeds `fraction * limit` (or is not finite).
fn first_over<T: RealField + Copy>(
    value: &JointVector<T>,
    limit: &JointVector<T>,
    fraction: T,
) -> Option<usize> {
    value
        .iter()
        .zip(limit.iter())
        .position(|(v, l)| !(v.is_finite() && v.abs() <= *l * fraction))
}
