//! Meeting a moving part: the earliest smooth path from the gripper's present
//! motion to the part's motion (position, velocity and acceleration matched, with
//! the part's yaw and yaw rate), within task-space and joint limits.
//!
//! The part's future is known from Eq 1 and the conveyor's state, so "where will
//! the part be in `d` seconds" is a function. The planner scans durations from
//! short to long, keeps the first whose quintic respects the speed and
//! acceleration limits (then refines it by bisection), and proves it in joint
//! space: inverse kinematics at every sample, joint speeds `J^-1 v` and torques
//! `RNEA(q, qd, J^-1 (a - Jdot qd))` within the robot's limits. The result is
//! time-optimal only among quintics ("time-optimal-ish"), but it is smooth, so
//! Eq 23's feed-forward acceleration never steps.

use nalgebra::{
    convert, Isometry3, RealField, Translation3, UnitQuaternion, Vector1, Vector3, Vector6,
};

use super::grasp_pose::{gripper_down_rotation, nearest_equivalent_yaw};
use super::path::{check_joint_limits, check_joint_limits_with_margin, sample_times, TaskPath};
use super::{PlanError, Quintic};
use crate::robot::{JointVector, Puma560};

/// Position, velocity and acceleration of the gripper (or of a target), with the
/// yaw about the vertical and its derivatives; the gripper points down.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TaskState<T: RealField + Copy> {
    /// Flange position, base frame, m.
    pub position: Vector3<T>,
    /// Its velocity, m/s.
    pub velocity: Vector3<T>,
    /// Its acceleration, m/s^2.
    pub acceleration: Vector3<T>,
    /// Yaw about the base Z, rad.
    pub yaw: T,
    /// Its rate, rad/s.
    pub yaw_rate: T,
    /// Its acceleration, rad/s^2.
    pub yaw_acceleration: T,
}

impl<T: RealField + Copy> TaskState<T> {
    /// At rest at `position` with `yaw`.
    pub fn at_rest(position: Vector3<T>, yaw: T) -> Self {
        Self {
            position,
            velocity: Vector3::zeros(),
            acceleration: Vector3::zeros(),
            yaw,
            yaw_rate: T::zero(),
            yaw_acceleration: T::zero(),
        }
    }

    /// The flange pose (gripper down, turned to `yaw`).
    pub fn pose(&self) -> Isometry3<T> {
        Isometry3::from_parts(
            Translation3::from(self.position),
            UnitQuaternion::from_rotation_matrix(&gripper_down_rotation(self.yaw)),
        )
    }

    /// Twist `[v; omega]` in the base frame (the geometric Jacobian's units).
    pub fn twist(&self) -> Vector6<T> {
        let v = self.velocity;
        Vector6::new(v.x, v.y, v.z, T::zero(), T::zero(), self.yaw_rate)
    }

    /// Classical acceleration `[a; alpha]` in the base frame.
    pub fn acceleration6(&self) -> Vector6<T> {
        let a = self.acceleration;
        Vector6::new(a.x, a.y, a.z, T::zero(), T::zero(), self.yaw_acceleration)
    }

    fn is_finite(&self) -> bool {
        self.position
            .iter()
            .chain(self.velocity.iter())
            .chain(self.acceleration.iter())
            .all(|x| x.is_finite())
            && self.yaw.is_finite()
            && self.yaw_rate.is_finite()
            && self.yaw_acceleration.is_finite()
    }
}

/// Limits and search settings of the planner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InterceptLimits<T> {
    /// Largest flange speed, m/s.
    pub max_speed_m_s: T,
    /// Largest flange acceleration, m/s^2.
    pub max_acceleration_m_s2: T,
    /// Largest yaw rate, rad/s.
    pub max_yaw_rate_rad_s: T,
    /// Shortest intercept considered, s.
    pub min_duration_s: T,
    /// Longest intercept considered, s.
    pub max_duration_s: T,
    /// Step of the coarse scan over durations.
    pub duration_step_s: T,
    /// Samples per candidate path for the limit checks.
    pub samples: usize,
    /// The gripper's symmetry about its axis (pi for two fingers).
    pub yaw_symmetry_rad: T,
    /// Fraction of the joint speed and torque limits a plan may use (room for
    /// the feedback terms of Eq 23).
    pub joint_limit_fraction: T,
    /// How far inside its range every joint stays along the plan, rad (or no
    /// nearer its stop than at the start, where it starts within this).
    pub joint_position_margin_rad: T,
}

impl<T: RealField + Copy> Default for InterceptLimits<T> {
    fn default() -> Self {
        Self {
            max_speed_m_s: convert(1.0),
            max_acceleration_m_s2: convert(3.0),
            max_yaw_rate_rad_s: convert(2.0),
            min_duration_s: convert(0.3),
            max_duration_s: convert(6.0),
            duration_step_s: convert(0.1),
            samples: 24,
            yaw_symmetry_rad: T::pi(),
            joint_limit_fraction: convert(0.7),
            joint_position_margin_rad: T::zero(),
        }
    }
}

/// A planned intercept: quintics in position and yaw over `duration`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InterceptPlan<T: RealField + Copy> {
    position: Quintic<T, 3>,
    yaw: Quintic<T, 1>,
}

impl<T: RealField + Copy> InterceptPlan<T> {
    /// The straight quintic from `start` to `end` in `duration`.
    pub fn between(
        start: &TaskState<T>,
        end: &TaskState<T>,
        duration: T,
        yaw_symmetry: T,
    ) -> Result<Self, PlanError> {
        let end_yaw = nearest_equivalent_yaw(start.yaw, end.yaw, yaw_symmetry);
        Ok(Self {
            position: Quintic::new(
                [start.position, start.velocity, start.acceleration],
                [end.position, end.velocity, end.acceleration],
                duration,
            )?,
            yaw: Quintic::new(
                [
                    Vector1::new(start.yaw),
                    Vector1::new(start.yaw_rate),
                    Vector1::new(start.yaw_acceleration),
                ],
                [
                    Vector1::new(end_yaw),
                    Vector1::new(end.yaw_rate),
                    Vector1::new(end.yaw_acceleration),
                ],
                duration,
            )?,
        })
    }

    /// The plan's duration, s.
    pub fn duration(&self) -> T {
        self.position.duration()
    }

    /// The desired state `t` seconds after the plan's start (clamped to its end).
    pub fn sample(&self, t: T) -> TaskState<T> {
        let [p, v, a] = self.position.sample(t);
        let [y, yd, ydd] = self.yaw.sample(t);
        TaskState {
            position: p,
            velocity: v,
            acceleration: a,
            yaw: y.x,
            yaw_rate: yd.x,
            yaw_acceleration: ydd.x,
        }
    }

    /// Whether the path keeps within the task-space limits at every sample.
    pub fn within_task_limits(&self, limits: &InterceptLimits<T>) -> bool {
        sample_times(self.duration(), limits.samples).all(|t| {
            let s = self.sample(t);
            s.velocity.norm() <= limits.max_speed_m_s
                && s.acceleration.norm() <= limits.max_acceleration_m_s2
                && s.yaw_rate.abs() <= limits.max_yaw_rate_rad_s
        })
    }

    /// Proves the path in joint space from `q_start` (see [`check_joint_limits`]).
    pub fn check_joint_limits(
        &self,
        robot: &Puma560<T>,
        q_start: &JointVector<T>,
        samples: usize,
        fraction: T,
    ) -> Result<JointVector<T>, PlanError> {
        check_joint_limits(self, robot, q_start, samples, fraction)
    }

    /// Proves the path in joint space from `q_start` within `limits`: its
    /// samples, joint speed and torque fraction and joint position margin
    /// (see [`check_joint_limits_with_margin`]).
    pub fn check_within(
        &self,
        robot: &Puma560<T>,
        q_start: &JointVector<T>,
        limits: &InterceptLimits<T>,
    ) -> Result<JointVector<T>, PlanError> {
        check_joint_limits_with_margin(
            self,
            robot,
            q_start,
            limits.samples,
            limits.joint_limit_fraction,
            limits.joint_position_margin_rad,
        )
    }
}

impl<T: RealField + Copy> TaskPath<T> for InterceptPlan<T> {
    fn duration(&self) -> T {
        InterceptPlan::duration(self)
    }

    fn sample(&self, t: T) -> TaskState<T> {
        InterceptPlan::sample(self, t)
    }
}

/// The earliest feasible intercept of `target_after(d)` (the target's state `d`
/// seconds from now) from `start`, proven in joint space from `q_start`.
pub fn plan_intercept<T: RealField + Copy>(
    start: &TaskState<T>,
    target_after: impl Fn(T) -> TaskState<T>,
    limits: &InterceptLimits<T>,
    robot: &Puma560<T>,
    q_start: &JointVector<T>,
) -> Result<InterceptPlan<T>, PlanError> {
    plan_intercept_where(start, target_after, |_| true, limits, robot, q_start)
}

/// [`plan_intercept`] among the durations `d` for which `admissible(d)` holds
/// (e.g. "the part stays within reach for the grasp that follows").
pub fn plan_intercept_where<T: RealField + Copy>(
    start: &TaskState<T>,
    target_after: impl Fn(T) -> TaskState<T>,
    admissible: impl Fn(T) -> bool,
    limits: &InterceptLimits<T>,
    robot: &Puma560<T>,
    q_start: &JointVector<T>,
) -> Result<InterceptPlan<T>, PlanError> {
    validate(limits)?;
    if !start.is_finite() || !q_start.iter().all(|x| x.is_finite()) {
        return Err(PlanError::NonFinite {
            what: "intercept start state",
        });
    }
    let candidate = |d: T| -> Result<InterceptPlan<T>, PlanError> {
        let end = target_after(d);
        if !end.is_finite() {
            return Err(PlanError::NonFinite {
                what: "intercept target state",
            });
        }
        InterceptPlan::between(start, &end, d, limits.yaw_symmetry_rad)
    };
    let mut previous_failed = None;
    let steps = scan_steps(limits)?;
    for step in 0..=steps {
        let d = limits.min_duration_s + limits.duration_step_s * convert::<f64, T>(step as f64);
        if !admissible(d) {
            previous_failed = Some(d);
            continue;
        }
        let plan = candidate(d)?;
        if plan.within_task_limits(limits) && plan.check_within(robot, q_start, limits).is_ok() {
            return Ok(refine(
                previous_failed,
                plan,
                d,
                &|mid| {
                    if admissible(mid) {
                        candidate(mid)
                    } else {
                        Err(PlanError::NoFeasibleIntercept)
                    }
                },
                limits,
                robot,
                q_start,
            ));
        }
        previous_failed = Some(d);
    }
    Err(PlanError::NoFeasibleIntercept)
}

/// Most candidate durations one plan may try: each costs an IK solve per sample.
const MAX_SCAN_STEPS: usize = 1000;

/// How many steps of the duration scan: counted, so a step too small for the
/// scalar's resolution cannot stall the loop.
fn scan_steps<T: RealField + Copy>(limits: &InterceptLimits<T>) -> Result<usize, PlanError> {
    let span: f64 = nalgebra::try_convert(
        (limits.max_duration_s - limits.min_duration_s) / limits.duration_step_s,
    )
    .unwrap_or(f64::INFINITY);
    if !(span.is_finite() && span <= MAX_SCAN_STEPS as f64) {
        return Err(PlanError::InvalidLimits {
            what: "duration_step_s too small: more than 1000 candidate durations",
        });
    }
    // Non-negative (validated max >= min), so truncation is the floor.
    Ok(span as usize)
}

/// Bisects between the last failing and the first feasible duration.
fn refine<T: RealField + Copy>(
    failed: Option<T>,
    feasible: InterceptPlan<T>,
    feasible_d: T,
    candidate: &impl Fn(T) -> Result<InterceptPlan<T>, PlanError>,
    limits: &InterceptLimits<T>,
    robot: &Puma560<T>,
    q_start: &JointVector<T>,
) -> InterceptPlan<T> {
    let Some(mut lo) = failed else {
        return feasible;
    };
    let mut hi = feasible_d;
    let mut best = feasible;
    let half: T = convert(0.5);
    for _ in 0..5 {
        let mid = (lo + hi) * half;
        match candidate(mid) {
            Ok(plan)
                if plan.within_task_limits(limits)
                    && plan.check_within(robot, q_start, limits).is_ok() =>
            {
                best = plan;
                hi = mid;
            }
            _ => lo = mid,
        }
    }
    best
}

fn validate<T: RealField + Copy>(limits: &InterceptLimits<T>) -> Result<(), PlanError> {
    let positive = |x: T| x.is_finite() && x > T::zero();
    if !positive(limits.max_speed_m_s)
        || !positive(limits.max_acceleration_m_s2)
        || !positive(limits.max_yaw_rate_rad_s)
    {
        return Err(PlanError::InvalidLimits {
            what: "speed, acceleration and yaw-rate limits must be positive",
        });
    }
    if !positive(limits.min_duration_s)
        || !positive(limits.duration_step_s)
        || !positive(limits.max_duration_s)
        || limits.max_duration_s < limits.min_duration_s
    {
        return Err(PlanError::InvalidLimits {
            what: "durations must be positive with min <= max",
        });
    }
    if !positive(limits.joint_limit_fraction) || limits.joint_limit_fraction > T::one() {
        return Err(PlanError::InvalidLimits {
            what: "joint_limit_fraction must be in (0, 1]",
        });
    }
    if limits.samples < 2 {
        return Err(PlanError::InvalidLimits {
            what: "at least 2 samples per path",
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fusion::part_motion_in_base;
    use crate::planning::{solve_ik, IkConfig};

    fn qn() -> JointVector<f64> {
        crate::planning::grasp_pose::ready_posture()
    }

    /// A part on a disc centred 0.65 m in front of the robot, 0.3 m above the base
    /// origin, turning at `omega`; the gripper aims 0.1 m above it.
    fn part_after(omega: f64, theta0: f64) -> impl Fn(f64) -> TaskState<f64> {
        move |d: f64| {
            let m = part_motion_in_base(
                0.3,
                &Vector3::new(0.65, 0.0, 0.3),
                &Vector3::new(0.2, 0.05, 0.04),
                0.2,
                theta0 + omega * d,
                omega,
                0.0,
            );
            TaskState {
                position: m.position_base + Vector3::new(0.0, 0.0, 0.1),
                velocity: m.velocity_base,
                acceleration: m.acceleration_base,
                yaw: m.yaw_base,
                yaw_rate: m.yaw_rate,
                yaw_acceleration: m.yaw_acceleration,
            }
        }
    }

    fn start() -> (Puma560<f64>, JointVector<f64>, TaskState<f64>) {
        let robot = Puma560::<f64>::new();
        let home = TaskState::at_rest(Vector3::new(0.45, -0.2, 0.6), 0.0);
        let q = solve_ik(&robot, &home.pose(), &qn(), &IkConfig::default()).unwrap();
        (robot, q, home)
    }

    #[test]
    fn meets_the_moving_part_with_matching_motion_within_limits() {
        let (robot, q, home) = start();
        let target = part_after(0.5, 1.0);
        let limits = InterceptLimits::default();
        let plan = plan_intercept(&home, &target, &limits, &robot, &q).unwrap();
        let d = plan.duration();
        let end = plan.sample(d);
        let want = target(d);
        assert!((end.position - want.position).norm() < 1e-9);
        assert!((end.velocity - want.velocity).norm() < 1e-9);
        assert!((end.acceleration - want.acceleration).norm() < 1e-9);
        assert!((end.yaw_rate - 0.5).abs() < 1e-9);
        // Yaw equivalent modulo the gripper's symmetry.
        let k = (end.yaw - want.yaw) / core::f64::consts::PI;
        assert!((k - k.round()).abs() < 1e-9);
        assert!(plan.within_task_limits(&limits));
        plan.check_joint_limits(&robot, &q, 48, 1.0).unwrap();
        // Time-optimal-ish: a slightly shorter quintic breaks a limit.
        let shorter =
            InterceptPlan::between(&home, &target(d - 0.05), d - 0.05, core::f64::consts::PI)
                .unwrap();
        assert!(
            !shorter.within_task_limits(&limits)
                || shorter.check_joint_limits(&robot, &q, 24, 0.7).is_err()
        );
    }

    #[test]
    fn a_part_out_of_reach_has_no_intercept() {
        let (robot, q, home) = start();
        let far = |_d: f64| TaskState::at_rest(Vector3::new(2.5, 0.0, 0.3), 0.0);
        let limits = InterceptLimits {
            max_duration_s: 1.0,
            ..InterceptLimits::default()
        };
        assert_eq!(
            plan_intercept(&home, far, &limits, &robot, &q),
            Err(PlanError::NoFeasibleIntercept)
        );
    }

    #[test]
    fn refuses_bad_limits_and_nan_states() {
        let (robot, q, home) = start();
        let target = part_after(0.5, 0.0);
        let tiny_step = InterceptLimits {
            duration_step_s: 1e-9,
            ..InterceptLimits::default()
        };
        assert!(matches!(
            plan_intercept(&home, &target, &tiny_step, &robot, &q),
            Err(PlanError::InvalidLimits { .. })
        ));
        let bad = InterceptLimits {
            samples: 1,
            ..InterceptLimits::default()
        };
        assert!(matches!(
            plan_intercept(&home, &target, &bad, &robot, &q),
            Err(PlanError::InvalidLimits { .. })
        ));
        let mut nan = home;
        nan.yaw = f64::NAN;
        assert!(matches!(
            plan_intercept(&nan, &target, &InterceptLimits::default(), &robot, &q),
            Err(PlanError::NonFinite { .. })
        ));
    }
}
