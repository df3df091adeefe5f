//! The pick's supervision: every period it checks what the state machine
//! cannot see from its plans (a stalled loop, a reference that leaps, joints
//! too fast, a part out of reach, a conveyor that left the intercept's
//! prediction, a reference below the known-clear height, a stale camera,
//! tracking that diverges) and answers with the fault to raise, if any. The
//! state machine decides what a fault does (stop, brake, plan again).

use nalgebra::Vector3;

use super::settings::{at_most, PickSettings};
use super::step::Step;
use crate::angle::wrap_pi;
use crate::planning::{within_stretch, TaskState};
use crate::protocol::FaultCause;
use crate::robot::{JointVector, Puma560};

/// A fault that may also need the joint brake: the task-space stop is not
/// to be trusted with it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Trip {
    /// The fault to raise.
    pub cause: FaultCause,
    /// Whether the joint brake takes over from Eq 23.
    pub brake: bool,
}

/// The checks, and the one measurement a stop needs from them: how far over
/// the joints' speed limits the last reference asked them to go.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Supervisor {
    /// The worst `|J^+ Yd_dot| / limit` over the joints at the last period.
    reference_speed_ratio: f32,
}

/// The worst `|v| / max` over the joints, taken in joint order: a ratio
/// replaces the worst so far unless it is [`at_most`] it (so a NaN ratio does).
fn worst_ratio(speeds: &JointVector<f32>, limits: &JointVector<f32>) -> f32 {
    speeds
        .iter()
        .zip(limits.iter())
        .map(|(v, max)| v.abs() / *max)
        .fold(
            0.0_f32,
            |worst, ratio| {
                if at_most(ratio, worst) {
                    worst
                } else {
                    ratio
                }
            },
        )
}

impl Supervisor {
    /// No reference checked yet.
    pub(super) fn new() -> Self {
        Self {
            reference_speed_ratio: 0.0,
        }
    }

    /// The worst reference joint speed over its limit at the last period.
    pub(super) fn reference_speed_ratio(&self) -> f32 {
        self.reference_speed_ratio
    }

    /// Periods did not come for longer than the stall limit.
    pub(super) fn stalled(dt_s: f32, settings: &PickSettings) -> bool {
        dt_s > settings.stall_limit_s
    }

    /// A motion's reference moves continuously; a leap (a phase handing over
    /// to a motion that starts elsewhere) would be a step Eq 23 answers with
    /// saturated torques: `next` further from `reference` than the pick's
    /// fastest motion goes in `dt_s` (with a margin) is refused.
    pub(super) fn reference_leap(
        reference: &TaskState<f32>,
        next: &TaskState<f32>,
        dt_s: f32,
        settings: &PickSettings,
    ) -> Option<FaultCause> {
        let step = (next.position - reference.position).norm();
        let turn = libm::fabsf(wrap_pi(next.yaw - reference.yaw));
        let leaps = !at_most(
            step,
            settings.stop_max_speed_m_s * dt_s + settings.reference_step_m,
        ) || !at_most(
            turn,
            settings.stop_max_yaw_rate_rad_s * dt_s + settings.reference_step_rad,
        );
        leaps.then_some(FaultCause::ReferenceJump)
    }

    /// Joint speeds (from the encoders) against the limits: near a limit the
    /// pick stops along its path; well over it (the stop is not slowing the
    /// arm) the joint brake takes over.
    pub(super) fn joint_speed(
        qd: &JointVector<f32>,
        model: &Puma560<f32>,
        settings: &PickSettings,
    ) -> Option<Trip> {
        let worst = worst_ratio(qd, &model.joint_limits().velocity_max);
        if !at_most(worst, settings.overspeed_brake_factor) {
            Some(Trip {
                cause: FaultCause::JointOverspeed,
                brake: true,
            })
        } else if !at_most(worst, settings.overspeed_stop_factor) {
            Some(Trip {
                cause: FaultCause::JointOverspeed,
                brake: false,
            })
        } else {
            None
        }
    }

    /// While the arm follows the part, the part must stay where the arm can
    /// reach it gripper-down (a reversed or runaway disc carries it off):
    /// chasing it out of reach drives the arm into its singularities.
    pub(super) fn reach(
        step: Step,
        reference: &Vector3<f32>,
        model: &Puma560<f32>,
        settings: &PickSettings,
    ) -> Option<FaultCause> {
        if !step.follows_part() {
            return None;
        }
        let radius = reference.xy().norm();
        let reachable = within_stretch(model, reference, settings.max_follow_stretch)
            && radius >= settings.min_follow_radius_m;
        (!reachable).then_some(FaultCause::PartUnreachable)
    }

    /// No reference may ask a joint for more than its speed limit: the plans
    /// check their paths, but the live parts of a reference (the intercept's
    /// correction, following the part) are checked here, every period, at
    /// the measured configuration. A stop or an abandoned intercept is
    /// exempt: it slows the arm from a start scaled within the limits.
    pub(super) fn reference_speed(
        &mut self,
        qd_reference: &JointVector<f32>,
        step: Step,
        model: &Puma560<f32>,
        settings: &PickSettings,
    ) -> Option<FaultCause> {
        let ratio = worst_ratio(qd_reference, &model.joint_limits().velocity_max);
        self.reference_speed_ratio = ratio;
        let decelerating = step.stopping() || step == Step::InterceptAbandoned;
        (!decelerating && !at_most(ratio, settings.reference_speed_factor))
            .then_some(FaultCause::JointOverspeed)
    }

    /// The intercept's live correction absorbs small departures of the part
    /// from the plan's prediction; a conveyor that stopped, sped up or
    /// reversed under the plan takes the part where the plan never checked
    /// reach or joint speeds. True when the `live` part is further from the
    /// `assumed` one than the correction may take, or the conveyor's speed
    /// has changed too much from the plan's ([`Self::conveyor_departed`]).
    pub(super) fn intercept_departed(
        live: &TaskState<f32>,
        assumed: &TaskState<f32>,
        omega_now: f32,
        omega_planned: f32,
        settings: &PickSettings,
    ) -> bool {
        let moved = (live.position - assumed.position).norm();
        !at_most(moved, settings.max_intercept_correction_m)
            || Self::conveyor_departed(omega_now, omega_planned, settings)
    }

    /// The grasp window (track, descend, settle, close, lift) was proven at
    /// the plan's conveyor speed `omega_planned`: riding with the part at a
    /// speed `omega_now` further from it than the settings tolerate carries
    /// the arm where the proof never went (a disc that sped up under a
    /// descent drives joint 1 past its stop by the lift).
    pub(super) fn conveyor_departed(
        omega_now: f32,
        omega_planned: f32,
        settings: &PickSettings,
    ) -> bool {
        let speed_change = libm::fabsf(omega_now - omega_planned);
        !at_most(
            speed_change,
            settings
                .max_conveyor_speed_change_rad_s
                .max(settings.max_conveyor_speed_change_fraction * libm::fabsf(omega_planned)),
        )
    }

    /// Before the calibration is accepted, nothing goes more than
    /// `max_descent_step_m` below the known-clear height (`safe_floor_z`),
    /// whatever the estimate says.
    pub(super) fn height(
        step: Step,
        calibration_accepted: bool,
        reference_z: f32,
        safe_floor_z: f32,
    ) -> Option<FaultCause> {
        let before_acceptance = !calibration_accepted
            && !matches!(
                step,
                Step::Start | Step::Stopping | Step::Faulted | Step::Done
            );
        // A centimetre for the arcs' rounding between two admitted heights.
        (before_acceptance && reference_z < safe_floor_z - 0.01)
            .then_some(FaultCause::BelowSafeHeight)
    }

    /// Steps that need the camera fault when no frame has been paired for
    /// longer than `vision_stale_s`.
    pub(super) fn vision(
        step: Step,
        since_paired_s: f32,
        settings: &PickSettings,
    ) -> Option<FaultCause> {
        (step.needs_vision() && since_paired_s > settings.vision_stale_s)
            .then_some(FaultCause::VisionStale)
    }

    /// Eq 23's position error past the tracking limit: the arm is not
    /// following its reference. A stop that lags its own path twice as far is
    /// not converging, and the joint brake takes over.
    pub(super) fn tracking(error_m: f32, step: Step, settings: &PickSettings) -> Option<Trip> {
        if error_m > settings.tracking_error_limit_m {
            Some(Trip {
                cause: FaultCause::TrackingError,
                brake: step.stopping() && error_m > 2.0 * settings.tracking_error_limit_m,
            })
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> Puma560<f32> {
        Puma560::<f64>::new().cast::<f32>()
    }

    fn at(x: f32, y: f32, z: f32) -> TaskState<f32> {
        TaskState::at_rest(Vector3::new(x, y, z), 0.0)
    }

    #[test]
    fn joint_speed_stops_near_the_limit_and_brakes_well_over_it() {
        let (model, settings) = (model(), PickSettings::default());
        let limits = model.joint_limits().velocity_max;
        assert_eq!(
            Supervisor::joint_speed(&(limits * 0.5), &model, &settings),
            None
        );
        let stop = Supervisor::joint_speed(&(limits * 1.0), &model, &settings);
        assert_eq!(
            stop,
            Some(Trip {
                cause: FaultCause::JointOverspeed,
                brake: false
            })
        );
        let brake = Supervisor::joint_speed(&(limits * 1.5), &model, &settings);
        assert!(brake.is_some_and(|trip| trip.brake));
        let nan = limits.map(|_| f32::NAN);
        assert!(Supervisor::joint_speed(&nan, &model, &settings).is_some_and(|trip| trip.brake));
    }

    #[test]
    fn reach_is_checked_only_while_following_the_part() {
        let (model, settings) = (model(), PickSettings::default());
        let on_the_axis = Vector3::new(0.0, 0.0, 0.3);
        assert_eq!(
            Supervisor::reach(Step::Locate, &on_the_axis, &model, &settings),
            None
        );
        assert_eq!(
            Supervisor::reach(Step::Track, &on_the_axis, &model, &settings),
            Some(FaultCause::PartUnreachable)
        );
        let far = Vector3::new(5.0, 0.0, 0.3);
        assert_eq!(
            Supervisor::reach(Step::Descend, &far, &model, &settings),
            Some(FaultCause::PartUnreachable)
        );
    }

    #[test]
    fn a_leaping_reference_is_refused() {
        let settings = PickSettings::default();
        let here = at(0.5, 0.0, 0.4);
        assert_eq!(
            Supervisor::reference_leap(&here, &here, 1e-3, &settings),
            None
        );
        let there = at(0.5, 0.3, 0.4);
        assert_eq!(
            Supervisor::reference_leap(&here, &there, 1e-3, &settings),
            Some(FaultCause::ReferenceJump)
        );
        let mut turned = here;
        turned.yaw = 1.0;
        assert_eq!(
            Supervisor::reference_leap(&here, &turned, 1e-3, &settings),
            Some(FaultCause::ReferenceJump)
        );
    }

    #[test]
    fn the_reference_speed_is_recorded_and_a_stop_is_exempt() {
        let (model, settings) = (model(), PickSettings::default());
        let limits = model.joint_limits().velocity_max;
        let mut supervisor = Supervisor::new();
        let fast = limits * 1.2;
        assert_eq!(
            supervisor.reference_speed(&fast, Step::Track, &model, &settings),
            Some(FaultCause::JointOverspeed)
        );
        assert!((supervisor.reference_speed_ratio() - 1.2).abs() < 1e-6);
        assert_eq!(
            supervisor.reference_speed(&fast, Step::Stopping, &model, &settings),
            None
        );
        assert_eq!(
            supervisor.reference_speed(&fast, Step::InterceptAbandoned, &model, &settings),
            None
        );
    }

    #[test]
    fn an_intercept_departs_when_the_part_or_the_conveyor_leaves_the_plan() {
        let settings = PickSettings::default();
        let part = at(0.6, 0.1, 0.0);
        assert!(!Supervisor::intercept_departed(
            &part, &part, 0.6, 0.6, &settings
        ));
        let moved = at(0.6, 0.3, 0.0);
        assert!(Supervisor::intercept_departed(
            &moved, &part, 0.6, 0.6, &settings
        ));
        assert!(Supervisor::intercept_departed(
            &part, &part, -0.6, 0.6, &settings
        ));
        assert!(!Supervisor::conveyor_departed(0.65, 0.6, &settings));
        assert!(Supervisor::conveyor_departed(0.85, 0.5, &settings));
        assert!(Supervisor::conveyor_departed(0.0, 0.6, &settings));
    }

    #[test]
    fn nothing_goes_below_the_safe_floor_before_the_calibration_is_accepted() {
        let below = Supervisor::height(Step::CalibrateMove(0), false, 0.1, 0.2);
        assert_eq!(below, Some(FaultCause::BelowSafeHeight));
        assert_eq!(
            Supervisor::height(Step::CalibrateMove(0), false, 0.195, 0.2),
            None
        );
        assert_eq!(Supervisor::height(Step::Descend, true, 0.1, 0.2), None);
        assert_eq!(Supervisor::height(Step::Stopping, false, 0.1, 0.2), None);
    }

    #[test]
    fn tracking_brakes_only_a_stop_that_lags_twice_the_limit() {
        let settings = PickSettings::default();
        let limit = settings.tracking_error_limit_m;
        assert_eq!(
            Supervisor::tracking(0.5 * limit, Step::Track, &settings),
            None
        );
        let lagging = Supervisor::tracking(3.0 * limit, Step::Track, &settings);
        assert!(lagging.is_some_and(|trip| !trip.brake));
        let stop = Supervisor::tracking(3.0 * limit, Step::Stopping, &settings);
        assert!(stop.is_some_and(|trip| trip.brake && trip.cause == FaultCause::TrackingError));
    }

    #[test]
    fn vision_goes_stale_only_where_the_step_needs_it() {
        let settings = PickSettings::default();
        let long = settings.vision_stale_s + 1.0;
        assert_eq!(
            Supervisor::vision(Step::Track, long, &settings),
            Some(FaultCause::VisionStale)
        );
        assert_eq!(Supervisor::vision(Step::Lift, long, &settings), None);
        assert_eq!(Supervisor::vision(Step::Track, 0.0, &settings), None);
    }
}
