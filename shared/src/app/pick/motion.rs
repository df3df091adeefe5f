//! What the gripper is being asked to do at this instant: hold, follow a planned
//! path, meet the part, or ride along with it at an offset.
//!
//! Every reference is a flange [`TaskState`] (gripper down): position, velocity
//! and acceleration, as Eq 23's outer loop takes them (`Y^d`, `Y^d-dot`,
//! `Y^d-ddot` of Fig 3). Paths start from the previous reference, so the
//! reference never jumps.

use nalgebra::{convert, Vector1, Vector3};

use crate::app::tool::TOOL_LENGTH_M;
use crate::planning::{
    nearest_equivalent_yaw, ArcMove, InterceptPlan, Quintic, TaskPath, TaskState,
};

/// The part's grasp point as the conveyor predicts it: Eq 1 with theta
/// extrapolated at constant speed from the plan's start.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prediction {
    /// The conveyor angle when the plan starts, rad.
    pub theta_at_start: f32,
    /// The conveyor speed the plan assumes, rad/s.
    pub omega: f32,
    /// The longest settle before the close the plan's grasp window was
    /// proven for, s (`PickSettings::grasp_settle_max_s`, or
    /// `grasp_settle_s` where the longer one does not hold).
    pub settle_max_s: f32,
}

/// The gripper's current task.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Motion {
    /// At rest at this state.
    Hold(TaskState<f32>),
    /// An arc round the base axis (see [`ArcMove`]).
    Arc {
        /// The arc.
        path: ArcMove<f32>,
        /// When it started, s.
        start_s: f32,
    },
    /// A quintic between two task states (a lift, a stop).
    Quintic {
        /// The quintic.
        path: InterceptPlan<f32>,
        /// When it started, s.
        start_s: f32,
    },
    /// The intercept: the planned quintic plus the difference between the
    /// part's live fused motion and the motion the plan assumed, blended in
    /// from 0 to 1 over the plan, so the path ends exactly on the live part
    /// however the conveyor's speed wandered meanwhile.
    Intercept {
        /// The planned quintic.
        plan: InterceptPlan<f32>,
        /// When it started, s.
        start_s: f32,
        /// The conveyor's motion the plan assumed.
        prediction: Prediction,
    },
    /// Riding with the part, `offset` above its grasp point (a quintic in height).
    Follow {
        /// The height above the grasp point over time.
        offset: Quintic<f32, 1>,
        /// When it started, s.
        start_s: f32,
    },
}

/// The flange state that puts the grasp point `height_above` over `grasp`.
pub fn flange_over(grasp: &TaskState<f32>, height_above: f32) -> TaskState<f32> {
    TaskState {
        position: grasp.position + Vector3::new(0.0, 0.0, TOOL_LENGTH_M as f32 + height_above),
        ..*grasp
    }
}

/// Smoothstep of degree 5 and its first two derivatives in `tau`.
fn smoothstep(tau: f32) -> (f32, f32, f32) {
    let t = tau.clamp(0.0, 1.0);
    let (t2, t3) = (t * t, t * t * t);
    (
        t3 * (10.0 - 15.0 * t + 6.0 * t2),
        30.0 * t2 * (1.0 - 2.0 * t + t2),
        60.0 * t - 180.0 * t2 + 120.0 * t3,
    )
}

impl Motion {
    /// Seconds the motion lasts (None: until told otherwise).
    pub fn duration_s(&self) -> Option<f32> {
        match self {
            Self::Hold(_) | Self::Follow { .. } => None,
            Self::Arc { path, .. } => Some(path.duration()),
            Self::Quintic { path, .. } | Self::Intercept { plan: path, .. } => {
                Some(path.duration())
            }
        }
    }

    /// When the motion started, if it is a timed one.
    pub fn start_s(&self) -> Option<f32> {
        match self {
            Self::Hold(_) => None,
            Self::Arc { start_s, .. }
            | Self::Quintic { start_s, .. }
            | Self::Intercept { start_s, .. }
            | Self::Follow { start_s, .. } => Some(*start_s),
        }
    }

    /// Whether a timed motion has run its course at `now_s`.
    pub fn finished(&self, now_s: f32) -> bool {
        match (self.start_s(), self.duration_s()) {
            (Some(start), Some(duration)) => now_s - start >= duration,
            _ => false,
        }
    }

    /// The flange reference at `now_s`. `part` is the grasp point's live fused
    /// state (Eq 1), `predicted` the one the intercept assumed (both `None`
    /// before calibration; following then holds), `previous_yaw` keeps the
    /// wrist from flipping between yaw equivalents.
    pub fn reference(
        &self,
        now_s: f32,
        part: Option<&TaskState<f32>>,
        predicted: impl Fn(f32) -> Option<TaskState<f32>>,
        hover_height_m: f32,
        previous: &TaskState<f32>,
    ) -> TaskState<f32> {
        let half_turn = core::f32::consts::PI;
        match self {
            Self::Hold(state) => *state,
            Self::Arc { path, start_s } => path.sample(now_s - start_s),
            Self::Quintic { path, start_s } => path.sample(now_s - start_s),
            Self::Intercept { plan, start_s, .. } => {
                let t = now_s - start_s;
                let planned = plan.sample(t);
                let (Some(live), Some(assumed)) = (part, predicted(t)) else {
                    return planned;
                };
                let duration = plan.duration().max(1e-3);
                let (s, ds, dds) = smoothstep(t / duration);
                let (ds, dds) = (ds / duration, dds / (duration * duration));
                let live = flange_over(live, hover_height_m);
                let assumed = flange_over(&assumed, hover_height_m);
                let dp = live.position - assumed.position;
                let dv = live.velocity - assumed.velocity;
                let da = live.acceleration - assumed.acceleration;
                let dyaw = nearest_equivalent_yaw(0.0, live.yaw - assumed.yaw, half_turn);
                let dyaw_rate = live.yaw_rate - assumed.yaw_rate;
                let dyaw_acc = live.yaw_acceleration - assumed.yaw_acceleration;
                let two: f32 = convert(2.0);
                TaskState {
                    position: planned.position + dp * s,
                    velocity: planned.velocity + dv * s + dp * ds,
                    acceleration: planned.acceleration + da * s + dv * (two * ds) + dp * dds,
                    yaw: planned.yaw + dyaw * s,
                    yaw_rate: planned.yaw_rate + dyaw_rate * s + dyaw * ds,
                    yaw_acceleration: planned.yaw_acceleration
                        + dyaw_acc * s
                        + dyaw_rate * (two * ds)
                        + dyaw * dds,
                }
            }
            Self::Follow { offset, start_s } => {
                let Some(live) = part else {
                    return TaskState::at_rest(previous.position, previous.yaw);
                };
                let [h, hd, hdd] = offset.sample(now_s - start_s);
                let mut state = flange_over(live, h.x);
                state.velocity.z += hd.x;
                state.acceleration.z += hdd.x;
                state.yaw = nearest_equivalent_yaw(previous.yaw, live.yaw, half_turn);
                state
            }
        }
    }
}

/// A height profile from `from` to `to` metres over `duration_s`, at rest at both ends.
pub fn height_profile(from: f32, to: f32, duration_s: f32) -> Option<Quintic<f32, 1>> {
    let zero = Vector1::new(0.0);
    Quintic::new(
        [Vector1::new(from), zero, zero],
        [Vector1::new(to), zero, zero],
        duration_s,
    )
    .ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn moving(t: f32) -> TaskState<f32> {
        TaskState {
            position: Vector3::new(0.6 + 0.1 * t, 0.1, 0.2),
            velocity: Vector3::new(0.1, 0.0, 0.0),
            acceleration: Vector3::zeros(),
            yaw: 0.3,
            yaw_rate: 0.0,
            yaw_acceleration: 0.0,
        }
    }

    #[test]
    fn the_intercept_ends_on_the_live_part_even_when_the_prediction_was_off() {
        let start = TaskState::at_rest(Vector3::new(0.5, -0.2, 0.6), 0.0);
        let hover = 0.06;
        // The plan was made for a part 2 cm further along y than it really is.
        let assumed = |t: f32| {
            let mut s = moving(t);
            s.position.y += 0.02;
            s
        };
        let plan = InterceptPlan::between(
            &start,
            &flange_over(&assumed(1.5), hover),
            1.5,
            core::f32::consts::PI,
        )
        .unwrap();
        let motion = Motion::Intercept {
            plan,
            start_s: 10.0,
            prediction: Prediction {
                theta_at_start: 0.0,
                omega: 0.0,
                settle_max_s: 0.15,
            },
        };
        let at = |t: f32| {
            motion.reference(
                10.0 + t,
                Some(&moving(t)),
                |tt| Some(assumed(tt)),
                hover,
                &start,
            )
        };
        let begin = at(0.0);
        assert!(
            (begin.position - start.position).norm() < 1e-5,
            "starts where the arm is"
        );
        let end = at(1.5);
        let target = flange_over(&moving(1.5), hover);
        assert!((end.position - target.position).norm() < 1e-5);
        assert!((end.velocity - target.velocity).norm() < 1e-5);
        // The blended reference stays smooth: finite differences match its velocity.
        let h = 1e-3;
        for k in 1..14 {
            let t = k as f32 * 0.1;
            let fd = (at(t + h).position - at(t - h).position) / (2.0 * h);
            assert!((fd - at(t).velocity).norm() < 2e-3, "t = {t}");
        }
    }

    #[test]
    fn following_rides_with_the_part_at_the_offset_and_holds_without_one() {
        let offset = height_profile(0.06, 0.0, 1.0).unwrap();
        let motion = Motion::Follow {
            offset,
            start_s: 0.0,
        };
        let previous = TaskState::at_rest(Vector3::new(0.5, 0.0, 0.5), 0.3 + core::f32::consts::PI);
        let r = motion.reference(1.0, Some(&moving(1.0)), |_| None, 0.06, &previous);
        let expected = moving(1.0).position + Vector3::new(0.0, 0.0, TOOL_LENGTH_M as f32);
        assert!((r.position - expected).norm() < 1e-6);
        assert!(
            (r.yaw - previous.yaw).abs() < 1e-6,
            "same yaw modulo pi: no wrist flip"
        );
        let held = motion.reference(1.0, None, |_| None, 0.06, &previous);
        assert_eq!(held.position, previous.position);
        assert!(!motion.finished(100.0));
    }
}
