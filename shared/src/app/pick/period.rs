//! One control period: the sample's measurements (the joint observer, the
//! conveyor filter of Eq 1, the flange through the encoders), the state
//! machine's tick, the supervisor's checks, Eq 23 towards the reference (or
//! the joint brake), the camera trigger and the telemetry.

use heapless::Vec;

use super::handoff::{ControlEvent, TriggerRecord};
use super::motion::Motion;
use super::step::Step;
use super::supervisor::{Supervisor, Trip};
use super::telemetry::{self, TelemetryInputs};
use super::{PickController, MAX_TICK_MESSAGES};
use crate::app::tool::tool_point_base;
use crate::control::{TaskKinematics, TaskReference, TaskSpaceModel};
use crate::fusion::LatchedSample;
use crate::kernels::micros_to_seconds;
use crate::planning::TaskState;
use crate::protocol::{ActuatorCommand, FaultCause, Message, SensorSample};
use crate::robot::{JointTrig, JointVector};

impl PickController {
    /// The period for `sample`; its command, and any telemetry in `out`.
    pub(super) fn run_period(
        &mut self,
        sample: &SensorSample,
        out: &mut Vec<Message, MAX_TICK_MESSAGES>,
    ) -> ActuatorCommand {
        let start_us = *self.start_time_us.get_or_insert(sample.time_us);
        let dt_s = if self.ticks == 0 {
            0.0
        } else {
            micros_to_seconds(sample.time_us.saturating_sub(self.last_time_us))
        };
        self.now_s = micros_to_seconds(sample.time_us.saturating_sub(start_us));
        self.last_time_us = sample.time_us;
        self.ticks = self.ticks.saturating_add(1);
        self.part_in_gripper = sample.part_in_gripper;
        let stalled = Supervisor::stalled(dt_s, &self.settings);
        if stalled {
            self.observer.restart();
            self.speed_window.restart();
            self.qdd_commanded = JointVector::zeros();
        }

        let q_measured = self.cell.joint_angles(&sample.joint_counts);
        if self
            .observer
            .update(&q_measured, &self.qdd_commanded, dt_s)
            .is_err()
            && self.ticks > 1
        {
            // The observer refuses a reading it cannot explain; frozen, it would
            // leave Eq 23 blind. Restart it on the reading and stop in joint
            // space, holding where the encoders say the arm is.
            self.raise(FaultCause::JointEncoder);
            self.engage_brake();
            self.observer.restart();
            let _ = self
                .observer
                .update(&q_measured, &JointVector::zeros(), dt_s);
        }
        match self.conveyor.update(sample.conveyor_counts, sample.time_us) {
            Ok(state) => {
                self.conveyor_state = Some(state);
                self.conveyor_mean
                    .push(sample.time_us, self.conveyor.total_counts());
            }
            Err(_) => self.raise(FaultCause::ConveyorEncoder),
        }
        let encoder_speed = self.speed_window.push(&q_measured, sample.time_us);
        let q = self.observer.q();
        // One configuration (sines, cosines) and one frame chain per period,
        // for the measured tool point here and for Eq 23 below.
        let configuration = TaskSpaceModel::configuration(&self.model, &q);
        let kinematics =
            TaskSpaceModel::task_kinematics(&self.model, &configuration, &self.observer.qd());
        let flange = kinematics.base_from_flange;
        self.tool_measured = tool_point_base(&flange);
        self.flange_measured = flange.translation.vector;
        self.tool_yaw_measured = crate::planning::gripper_yaw(&flange.rotation);

        if stalled {
            self.on_stall(&flange);
        }

        let camera_trigger = self.camera_trigger(sample, &q_measured);
        if self.step == Step::Start {
            self.begin(&flange);
        }
        self.advance();
        let stale = Supervisor::vision(self.step, self.now_s - self.last_paired_s, &self.settings);
        if let Some(cause) = stale {
            self.raise(cause);
        }

        let part = self.part_now();
        let estimate = self.estimate;
        let prediction = match self.motion {
            Motion::Intercept { prediction, .. } => Some(prediction),
            _ => None,
        };
        let predicted = |t: f32| {
            let (estimate, p) = (estimate.as_ref()?, prediction?);
            Some(estimate.grasp_point(p.theta_at_start + p.omega * t, p.omega, 0.0))
        };
        let reference = self.motion.reference(
            self.now_s,
            part.as_ref(),
            predicted,
            self.settings.hover_height_m,
            &self.reference,
        );
        // A leap is refused, and the stop starts from the last good reference;
        // a stall or a stop already under way is not checked.
        let guarded = !stalled && !self.step.stopping();
        let leap = (guarded && self.ticks > 1)
            .then(|| Supervisor::reference_leap(&self.reference, &reference, dt_s, &self.settings))
            .flatten();
        match leap {
            Some(cause) => self.raise(cause),
            None => self.reference = reference,
        }

        self.supervise(encoder_speed.as_ref(), part.as_ref());
        let tau = self.control(
            &q,
            &q_measured,
            encoder_speed.as_ref(),
            (&configuration, &kinematics),
            dt_s,
        );
        self.emit_telemetry(part.as_ref(), out);
        ActuatorCommand {
            seq: sample.seq,
            joint_torque_nm: tau,
            gripper: self.gripper,
            camera_trigger,
        }
    }

    /// Eq 23 towards the reference; faults on divergence or a failed law.
    /// The brake works on the encoders alone (`q_measured` and their
    /// differenced speeds), not on the observer that feeds Eq 23.
    fn control(
        &mut self,
        q: &JointVector<f32>,
        q_measured: &JointVector<f32>,
        encoder_speed: Option<&JointVector<f32>>,
        (configuration, kinematics): (&JointTrig<f32>, &TaskKinematics<f32>),
        dt_s: f32,
    ) -> [f32; 6] {
        let qd = self.observer.qd();
        if let Some(brake) = self.brake.as_mut() {
            self.qdd_commanded = JointVector::zeros();
            return brake.torque(&self.model, q_measured, encoder_speed.unwrap_or(&qd));
        }
        let reference = TaskReference {
            base_from_flange: self.reference.pose(),
            twist: self.reference.twist(),
            acceleration: self.reference.acceleration6(),
        };
        let dt = if dt_s > 0.0 { dt_s } else { 1e-3 };
        // Holding after a stop: once the integral has settled the stop's
        // residual, keep it, so the hold does not hunt in the joints'
        // friction (stick-slip).
        let settled_since = self.step_started_s.max(self.integral_reset_s);
        self.controller.freeze_integral(
            self.on_brakes
                || (self.step == Step::Faulted
                    && self.now_s - settled_since > self.settings.hold_settle_s),
        );
        let output = self.controller.step_with(
            &self.model,
            q,
            &qd,
            configuration,
            kinematics,
            &reference,
            dt,
        );
        if output.fallback.is_some() {
            self.raise(FaultCause::ControlFailure);
            self.engage_brake();
        }
        let settings = self.settings;
        let overspeed = self.supervisor.reference_speed(
            &output.reference_joint_speed,
            self.step,
            &self.model,
            &settings,
        );
        if let Some(cause) = overspeed {
            self.raise(cause);
        }
        if output.saturated {
            self.counters.saturated_ticks = self.counters.saturated_ticks.saturating_add(1);
        }
        // On the brakes the arm does not follow Eq 23 (see `on_brakes`).
        self.qdd_commanded = if !self.on_brakes && output.qdd.iter().all(|x| x.is_finite()) {
            output.qdd
        } else {
            JointVector::zeros()
        };
        let error = output.position_error.norm();
        if let Some(trip) = Supervisor::tracking(error, self.step, &settings) {
            // The brake first: a stop that does not converge is the control's failure.
            if trip.brake {
                self.engage_brake();
            }
            self.raise(trip.cause);
        }
        let mut tau = [0.0_f32; 6];
        for (t, value) in tau.iter_mut().zip(output.tau.iter()) {
            *t = *value;
        }
        tau
    }

    /// Fires the camera every period and latches the encoders with the trigger.
    fn camera_trigger(&mut self, sample: &SensorSample, q: &JointVector<f32>) -> Option<u32> {
        let period_s = f32::from(self.cell.config.camera_period_ms) * 1e-3;
        let trigger_id = self.camera_trigger.fire(self.now_s, period_s)?;
        let mut joint_q = [0.0_f32; 6];
        for (slot, value) in joint_q.iter_mut().zip(q.iter()) {
            *slot = *value;
        }
        let record = TriggerRecord {
            latched: LatchedSample {
                trigger_id,
                conveyor_counts: self.conveyor.total_counts(),
                time_us: sample.time_us,
                joint_q,
            },
            start_time_us: self.start_time_us.unwrap_or(sample.time_us),
            feeds_calibrator: self.step.part_on_disc() && !self.step.stopping(),
        };
        self.post(ControlEvent::Trigger(record));
        Some(trigger_id)
    }

    /// The grasp point's live state (Eq 1 with the conveyor filter), once calibrated.
    fn part_now(&self) -> Option<TaskState<f32>> {
        let estimate = self.estimate.as_ref()?;
        let state = self.conveyor_state?;
        Some(self.refresh.grasp_point(
            estimate,
            [state.theta_wrapped, state.omega, state.alpha],
            self.now_s,
            self.settings.estimate_fade_s,
        ))
    }

    /// The period's telemetry, when it is due.
    fn emit_telemetry(
        &self,
        part: Option<&TaskState<f32>>,
        out: &mut Vec<Message, MAX_TICK_MESSAGES>,
    ) {
        if !telemetry::due(self.ticks, self.cell.config.telemetry_period_ticks) {
            return;
        }
        let telemetry = TelemetryInputs {
            time_us: self.last_time_us,
            phase: self.phase(),
            fault: self.fault,
            conveyor: self.conveyor_state,
            part,
            estimate: self.estimate.as_ref(),
            tool_measured: &self.tool_measured,
            tool_yaw_measured: self.tool_yaw_measured,
            reference: &self.reference,
            counters: &self.counters,
            link_frames_rejected: self.link_frames_rejected,
        }
        .message();
        // The outbox holds MAX_TICK_MESSAGES; telemetry is dropped, never the command.
        let _ = out.push(Message::Telemetry(telemetry));
    }

    /// Periods did not come for longer than the stall limit. The arm is where
    /// the drives' watchdog left it, not where the plan says: stop from there
    /// (a controlled stop from rest, rising clear of the part when near it).
    fn on_stall(&mut self, flange: &nalgebra::Isometry3<f32>) {
        self.counters.stalls = self.counters.stalls.saturating_add(1);
        self.reference = TaskState::at_rest(flange.translation.vector, self.tool_yaw_measured);
        // The motion in progress ran on through the gap without the arm: a
        // stop must not take up what is left of it (an arc's last part is
        // otherwise kept as its own stop, see `decelerate`), but start from here.
        self.hold_here();
        self.controller.reset();
        self.integral_reset_s = self.now_s;
        match self.step {
            Step::Start | Step::Done | Step::Faulted => self.hold_here(),
            Step::Stopping => self.enter(Step::Faulted),
            _ => self.raise(FaultCause::ControlStall),
        }
    }

    /// The supervisor's checks of the period, in order: each sees the step
    /// the one before it left.
    fn supervise(
        &mut self,
        encoder_speed: Option<&JointVector<f32>>,
        part: Option<&TaskState<f32>>,
    ) {
        let settings = self.settings;
        if let Some(qd) = encoder_speed {
            if let Some(trip) = Supervisor::joint_speed(qd, &self.model, &settings) {
                self.trip(trip);
            }
        }
        let reach = Supervisor::reach(self.step, &self.reference.position, &self.model, &settings);
        match reach {
            // Still on its way to the part: the intercept's correction
            // followed a part the conveyor's ripple carried elsewhere than
            // the plan's prediction, towards the edge of reach. Abandon it
            // and plan again from rest (up to `max_intercept_attempts`), as
            // for a part that departed from the plan.
            Some(_)
                if self.step == Step::Intercept
                    && self.intercept_attempts < self.settings.max_intercept_attempts =>
            {
                self.enter(Step::InterceptAbandoned);
            }
            Some(cause) => self.raise(cause),
            None => {}
        }
        self.check_intercept(part);
        let floor = self.safe_floor_z();
        let height = Supervisor::height(
            self.step,
            self.calibration_accepted,
            self.reference.position.z,
            floor,
        );
        if let Some(cause) = height {
            self.raise(cause);
        }
    }

    /// An intercept the conveyor left (see [`Supervisor::intercept_departed`]),
    /// or a ride with the part at a conveyor speed its grasp window was not
    /// proven for ([`Supervisor::conveyor_departed`]), is abandoned (rising
    /// clear of the part) and planned again, up to `max_intercept_attempts`.
    /// Once the gripper closes, it holds or misses the part: abandoning then
    /// would carry a half-gripped part away, so the close runs its short course.
    fn check_intercept(&mut self, part: Option<&TaskState<f32>>) {
        let omega_now = self.conveyor_state.map(|c| c.omega);
        let departed = match (self.step, self.motion) {
            (
                Step::Intercept,
                Motion::Intercept {
                    start_s,
                    prediction,
                    ..
                },
            ) => {
                let (Some(live), Some(estimate)) = (part, self.estimate.as_ref()) else {
                    return;
                };
                let t = self.now_s - start_s;
                let assumed = estimate.grasp_point(
                    prediction.theta_at_start + prediction.omega * t,
                    prediction.omega,
                    0.0,
                );
                Supervisor::intercept_departed(
                    live,
                    &assumed,
                    omega_now.unwrap_or(prediction.omega),
                    prediction.omega,
                    &self.settings,
                )
            }
            (Step::Track | Step::Descend | Step::GraspSettle, _) => {
                omega_now.is_some_and(|omega| {
                    Supervisor::conveyor_departed(omega, self.window_omega, &self.settings)
                })
            }
            _ => return,
        };
        if !departed {
            return;
        }
        if self.intercept_attempts >= self.settings.max_intercept_attempts {
            self.raise(FaultCause::PartUnreachable);
        } else {
            self.enter(Step::InterceptAbandoned);
        }
    }

    /// Raises the trip's fault, then hands over to the joint brake if it asks.
    fn trip(&mut self, trip: Trip) {
        self.raise(trip.cause);
        if trip.brake {
            self.engage_brake();
        }
    }
}
