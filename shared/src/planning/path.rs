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

/// Margins a plan keeps from the PUMA's singularities. With a spherical wrist,
/// `det J` factors into an arm term (elbow stretch, wrist centre over the
/// shoulder) times `sin q5` (the wrist). The ready posture's arm term is 0.11
/// m^3 and a straight elbow's 0; below the margins Eq 23's joint accelerations,
/// and the joint speeds a task speed needs, grow without bound.
pub const MIN_ARM_MANIPULABILITY: f64 = 0.05;
/// The wrist's margin: `|sin q5|` at least this (see [`MIN_ARM_MANIPULABILITY`]).
pub const MIN_WRIST_SINE: f64 = 0.1;

/// Largest share of the arm's full stretch (shoulder to wrist centre, `a2 +
/// sqrt(a3^2 + d4^2)`) a plan may ask for: the elbow singularity is the sphere
/// at the full stretch, and inverse kinematics that jumps to the other elbow
/// branch between two samples could otherwise hide a path across it.
pub const MAX_STRETCH: f64 = 0.93;

/// Whether the wrist centre over a gripper-down flange at `flange` is within
/// [`MAX_STRETCH`] of the arm's reach (from the task-space position alone).
pub fn within_reach<T: RealField + Copy>(
    robot: &Puma560<T>,
    flange: &nalgebra::Vector3<T>,
) -> bool {
    within_stretch(robot, flange, convert::<f64, T>(MAX_STRETCH))
}

/// Whether the wrist centre over a gripper-down flange at `flange` is within
/// `max_stretch` (a fraction) of the arm's reach.
pub fn within_stretch<T: RealField + Copy>(
    robot: &Puma560<T>,
    flange: &nalgebra::Vector3<T>,
    max_stretch: T,
) -> bool {
    let [l1, l2, l3, l4, _, l6] = robot.dh_table();
    let stretch = l2.a + (l3.a * l3.a + l4.d * l4.d).sqrt();
    // The wrist centre sits d6 above a downward flange; the arm's plane is offset
    // d2 + d3 from the base axis; the shoulder is d1 above the base.
    let wrist = flange + nalgebra::Vector3::new(T::zero(), T::zero(), l6.d);
    let offset = l2.d + l3.d;
    let horizontal_sq = wrist.x * wrist.x + wrist.y * wrist.y - offset * offset;
    let vertical = wrist.z - l1.d;
    let reach_sq = horizontal_sq.max(T::zero()) + vertical * vertical;
    let limit = stretch * max_stretch;
    reach_sq <= limit * limit
}

/// Whether `q` keeps the margins from every singularity.
pub fn well_conditioned<T: RealField + Copy>(robot: &Puma560<T>, q: &JointVector<T>) -> bool {
    let wrist = q.get(4).map_or_else(T::zero, |q5| q5.sin().abs());
    let arm_margin: T = convert(MIN_ARM_MANIPULABILITY);
    wrist >= convert(MIN_WRIST_SINE) && robot.jacobian(q).determinant().abs() >= arm_margin * wrist
}

/// A desired flange motion over `[0, duration]` (gripper down, yaw about Z).
pub trait TaskPath<T: RealField + Copy> {
    /// The path's duration, s.
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
    check_joint_limits_with_margin(path, robot, q_start, samples, fraction, T::zero())
}

/// [`check_joint_limits`], every joint also kept `position_margin` inside its
/// range (or, where `q_start` already lies within the margin, no nearer its
/// stop than at the start). The inverse kinematics clamp to the range, so
/// without a margin a path onto a joint's stop would pass.
pub fn check_joint_limits_with_margin<T: RealField + Copy>(
    path: &impl TaskPath<T>,
    robot: &Puma560<T>,
    q_start: &JointVector<T>,
    samples: usize,
    fraction: T,
    position_margin: T,
) -> Result<JointVector<T>, PlanError> {
    let limits = robot.joint_limits();
    let lowest = limits
        .position_min
        .zip_map(q_start, |lo, start| (lo + position_margin).min(start));
    let highest = limits
        .position_max
        .zip_map(q_start, |hi, start| (hi - position_margin).max(start));
    let ik = IkConfig::default();
    let mut q = *q_start;
    let mut previous_sign = None;
    for t in sample_times(path.duration(), samples) {
        let time_s: f64 = nalgebra::try_convert(t).unwrap_or(f64::NAN);
        let state = path.sample(t);
        if !within_reach(robot, &state.position) {
            return Err(PlanError::Singular { time_s });
        }
        q = solve_ik(robot, &state.pose(), &q, &ik)?;
        if !well_conditioned(robot, &q) {
            return Err(PlanError::Singular { time_s });
        }
        if let Some(joint) = q
            .iter()
            .zip(lowest.iter().zip(highest.iter()))
            .position(|(x, (lo, hi))| !(*x >= *lo && *x <= *hi))
        {
            return Err(PlanError::JointPositionLimit { joint });
        }
        let jacobian = robot.jacobian(&q);
        // det J changes sign only through a singularity: two well-conditioned
        // samples on either side of one (the inverse kinematics having jumped
        // to the other elbow or wrist branch) must not hide the crossing.
        let sign = jacobian.determinant() > T::zero();
        if previous_sign.is_some_and(|previous| previous != sign) {
            return Err(PlanError::Singular { time_s });
        }
        previous_sign = Some(sign);
        let lu = jacobian.lu();
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

/// The largest share of a joint's speed limit that following `path` from
/// `q_start` asks for over `samples` samples (`J^-1 v` at each), with the
/// joint angles at the end. Unlike [`check_joint_limits`] it measures
/// rather than refuses, so that a move can be slowed until it fits.
pub fn peak_speed_share<T: RealField + Copy>(
    path: &impl TaskPath<T>,
    robot: &Puma560<T>,
    q_start: &JointVector<T>,
    samples: usize,
) -> Result<(T, JointVector<T>), PlanError> {
    let limits = robot.joint_limits();
    let ik = IkConfig::default();
    let mut q = *q_start;
    let mut worst = T::zero();
    for t in sample_times(path.duration(), samples) {
        let time_s: f64 = nalgebra::try_convert(t).unwrap_or(f64::NAN);
        let state = path.sample(t);
        q = solve_ik(robot, &state.pose(), &q, &ik)?;
        let qd = robot
            .jacobian(&q)
            .lu()
            .solve(&state.twist())
            .ok_or(PlanError::Singular { time_s })?;
        for (v, limit) in qd.iter().zip(limits.velocity_max.iter()) {
            let share = v.abs() / *limit;
            if !share.is_finite() {
                return Err(PlanError::Singular { time_s });
            }
            worst = worst.max(share);
        }
    }
    Ok((worst, q))
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
