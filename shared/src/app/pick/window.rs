//! The grasp window: what the arm does after the intercept arrives over the
//! part, checked in joint space before the planner commits to the intercept.
//!
//! After the intercept the arm rides with the part (track at hover height,
//! descend, settle, close the gripper) and then lifts it, still carried on by
//! the part's speed (`route::lift`). The part moves with the disc all the
//! while (Eq 1), so a grasp that is reachable where the intercept meets the
//! part may drive a joint onto its stop a few seconds later: behind the
//! robot, joint 1's angle is the part's azimuth plus the shoulder's offset
//! (`asin((d2 + d3) / r)`, up to 15 degrees), not the azimuth itself; near full
//! stretch, a lift asks the elbow for speeds a reach check does not see. The
//! window is checked as the controller will run it: the same height profiles
//! and the same lift quintic, inverse kinematics at every sample, each joint
//! [`WINDOW_JOINT_MARGIN_RAD`] inside its range and within
//! [`WINDOW_SPEED_FRACTION`] of its speed limit (`J^-1 v`), for the shortest
//! track and settle (`track_settle_s`, `grasp_settle_s`) and the longest
//! ones the pick allows (`track_window_s`, and `grasp_settle_max_s` where
//! the window holds for it, `grasp_settle_s` otherwise: a fast disc's
//! window may not hold for the longer settle). This runs in the worker's plan job, never in the
//! control period.

use super::estimate::CellEstimate;
use super::motion::{flange_over, height_profile, Motion, Prediction};
use super::route;
use super::settings::PickSettings;
use crate::app::pick::jobs::MIN_RADIUS_FROM_BASE_AXIS_M;
use crate::planning::{
    gripper_yaw, nearest_equivalent_yaw, solve_ik, well_conditioned, within_reach, IkConfig,
    InterceptLimits, TaskState,
};
use crate::robot::{JointVector, Puma560};

/// How far inside its range every joint stays through the grasp window, rad
/// (4 degrees: the base calibration's azimuth error, Eq 23's tracking error
/// and the lift's overshoot, with room to spare).
pub const WINDOW_JOINT_MARGIN_RAD: f32 = 0.07;

/// Fraction of the joint speed limits the grasp window may ask for, as the
/// plans (`InterceptLimits::joint_limit_fraction`): room for Eq 23's feedback.
pub const WINDOW_SPEED_FRACTION: f32 = 0.7;

/// Seconds between two checked samples of the window.
const WINDOW_SAMPLE_S: f32 = 0.2;

/// Samples of the lift (both ends included).
const LIFT_SAMPLES: u16 = 7;

/// Whether every joint of `q` is [`WINDOW_JOINT_MARGIN_RAD`] inside its range
/// (the inverse kinematics clamp to the range, so a solution on a stop would
/// otherwise pass).
pub fn inside_with_margin(robot: &Puma560<f32>, q: &JointVector<f32>) -> bool {
    let limits = robot.joint_limits();
    q.iter()
        .zip(limits.position_min.iter().zip(limits.position_max.iter()))
        .all(|(x, (lo, hi))| {
            *x >= *lo + WINDOW_JOINT_MARGIN_RAD && *x <= *hi - WINDOW_JOINT_MARGIN_RAD
        })
}

/// The flange reference while riding with the part, `in_follow_s` after the
/// intercept's end (`tau_end_s` after the plan's start), the track lasting
/// `track_s`: hover, then the descent, then at the grasp point.
fn follow_state(
    part_at: &impl Fn(f32) -> TaskState<f32>,
    tau_end_s: f32,
    in_follow_s: f32,
    track_s: f32,
    settings: &PickSettings,
) -> TaskState<f32> {
    let part = part_at(tau_end_s + in_follow_s);
    let in_descent = in_follow_s - track_s;
    if in_descent <= 0.0 {
        return flange_over(&part, settings.hover_height_m);
    }
    let Some(profile) = height_profile(settings.hover_height_m, 0.0, settings.descend_s) else {
        return flange_over(&part, 0.0);
    };
    let [h, hd, hdd] = profile.sample(in_descent.min(settings.descend_s));
    let mut state = flange_over(&part, h.x);
    state.velocity.z += hd.x;
    state.acceleration.z += hdd.x;
    state
}

/// Checks one state of the window from the joint angles `q` of the sample
/// before; returns the joint angles at this one.
fn check_state(
    state: &TaskState<f32>,
    q: &JointVector<f32>,
    robot: &Puma560<f32>,
) -> Option<JointVector<f32>> {
    if state.position.xy().norm() < MIN_RADIUS_FROM_BASE_AXIS_M
        || !within_reach(robot, &state.position)
    {
        return None;
    }
    let q = solve_ik(robot, &state.pose(), q, &IkConfig::default()).ok()?;
    if !well_conditioned(robot, &q) {
        return None;
    }
    if !inside_with_margin(robot, &q) {
        return None;
    }
    let limits = robot.joint_limits();
    let qd = robot.jacobian(&q).lu().solve(&state.twist())?;
    let fast = qd
        .iter()
        .zip(limits.velocity_max.iter())
        .any(|(v, limit)| !(v.is_finite() && v.abs() <= *limit * WINDOW_SPEED_FRACTION));
    (!fast).then_some(q)
}

/// One course of the window, the track lasting `track_s` and the settle
/// `settle_s`: riding with the
/// part from the intercept's end (`tau_end_s` after the plan's start) to the
/// lift, then the lift. Returns false at the first sample that fails.
fn course_holds(
    part_at: &impl Fn(f32) -> TaskState<f32>,
    tau_end_s: f32,
    (track_s, settle_s): (f32, f32),
    q_seed: &JointVector<f32>,
    settings: &PickSettings,
    robot: &Puma560<f32>,
) -> bool {
    let lift_at_s = track_s + settings.descend_s + settle_s + settings.grasp_close_s;
    let span = lift_at_s.max(0.0);
    let steps = libm::ceilf(span / WINDOW_SAMPLE_S).clamp(1.0, 64.0) as u16;
    let mut q = *q_seed;
    for k in 0..=steps {
        let t = span * f32::from(k) / f32::from(steps);
        let state = follow_state(part_at, tau_end_s, t, track_s, settings);
        match check_state(&state, &q, robot) {
            Some(next) => q = next,
            None => return false,
        }
    }
    // The lift, exactly as the pick will start it: from the reference that
    // rides with the part at the grasp point.
    let start = follow_state(part_at, tau_end_s, lift_at_s, track_s, settings);
    let Ok(Motion::Quintic { path, .. }) = route::lift(&start, settings, 0.0) else {
        return false;
    };
    let duration = path.duration();
    (1..LIFT_SAMPLES).all(|k| {
        let t = duration * f32::from(k) / f32::from(LIFT_SAMPLES - 1);
        match check_state(&path.sample(t), &q, robot) {
            Some(next) => {
                q = next;
                true
            }
            None => false,
        }
    })
}

/// Whether the grasp window after an intercept that ends `tau_end_s` after
/// the plan's start holds (see the module's doc): riding with the part,
/// descending, grasping and lifting it, for the shortest and the longest
/// track and settle, the longest settle lasting `longest_settle_s`, every
/// joint inside its range with margin and within its speed limits.
/// `q_seed` seeds the inverse kinematics (the arm's joints at the plan's
/// start, joint 1 turned towards the part).
pub fn grasp_window_holds(
    estimate: &CellEstimate,
    prediction: &Prediction,
    tau_end_s: f32,
    q_seed: &JointVector<f32>,
    (settings, longest_settle_s): (&PickSettings, f32),
    robot: &Puma560<f32>,
) -> bool {
    let raw_at = |tau: f32| {
        estimate.grasp_point(
            prediction.theta_at_start + prediction.omega * tau,
            prediction.omega,
            0.0,
        )
    };
    // The intercept ends at the gripper's yaw nearest the arm's (modulo the
    // gripper's half-turn symmetry, `InterceptPlan::between`), and the ride
    // keeps it: the window is checked at that yaw.
    let offset = yaw_offset_from(q_seed, raw_at(tau_end_s).yaw, robot);
    let part_at = |tau: f32| {
        let mut state = raw_at(tau);
        state.yaw += offset;
        state
    };
    let shortest = settings.track_settle_s;
    let longest = settings.track_window_s.max(shortest);
    // First the end of the longest course's lift alone (one inverse
    // kinematics): where the part goes furthest, and where most windows that
    // fail, fail; then both courses sample by sample.
    let longest_settle = longest_settle_s.max(settings.grasp_settle_s);
    let lift_at_s = longest + settings.descend_s + longest_settle + settings.grasp_close_s;
    let lift_start = follow_state(&part_at, tau_end_s, lift_at_s, longest, settings);
    let lift_end = match route::lift(&lift_start, settings, 0.0) {
        Ok(Motion::Quintic { path, .. }) => path.sample(path.duration()),
        _ => return false,
    };
    if check_state(&lift_end, q_seed, robot).is_none() {
        return false;
    }
    let longest_course = (longest, longest_settle);
    let shortest_course = (shortest, settings.grasp_settle_s);
    course_holds(&part_at, tau_end_s, longest_course, q_seed, settings, robot)
        && course_holds(
            &part_at,
            tau_end_s,
            shortest_course,
            q_seed,
            settings,
            robot,
        )
}

/// What to add to a grasp yaw `yaw` for the gripper's equivalent yaw
/// (modulo its half-turn symmetry) nearest the tool's at joints `q`: the yaw
/// an intercept from `q` ends at ([`crate::planning::InterceptPlan`] turns
/// the wrist no further than it must). An arm whose search turned the wrist
/// half a turn (seed 14 cell 882 through images) had every window checked
/// at the other yaw, a half turn of joint 6 away, and stopped with
/// `PartOutOfReach`.
pub fn yaw_offset_from(q: &JointVector<f32>, yaw: f32, robot: &Puma560<f32>) -> f32 {
    let tool = gripper_yaw(&robot.forward_kinematics(q).rotation);
    let symmetry = InterceptLimits::<f32>::default().yaw_symmetry_rad;
    nearest_equivalent_yaw(tool, yaw, symmetry) - yaw
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::angle::wrap_pi;

    #[test]
    fn the_windows_yaw_is_the_equivalent_nearest_the_wrist() {
        let robot = Puma560::<f32>::new();
        let q = JointVector::from([0.3, 0.9, -2.6, 0.0, -0.9, 0.2]);
        let tool = gripper_yaw(&robot.forward_kinematics(&q).rotation);
        let mut turned = q;
        turned.b += core::f32::consts::PI;
        let tool_turned = gripper_yaw(&robot.forward_kinematics(&turned).rotation);
        for yaw in [-3.0_f32, -1.2, 0.0, 0.4, 2.9] {
            for (q, tool) in [(&q, tool), (&turned, tool_turned)] {
                let offset = yaw_offset_from(q, yaw, &robot);
                let half_turns = offset / core::f32::consts::PI;
                assert!((half_turns - half_turns.round()).abs() < 1e-4, "{offset}");
                assert!(
                    wrap_pi(yaw + offset - tool).abs() <= core::f32::consts::FRAC_PI_2 + 1e-4,
                    "yaw {yaw}: {} from the tool's {tool}",
                    yaw + offset
                );
            }
        }
    }
}
