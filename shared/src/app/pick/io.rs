//! What the controller's callers see: sensor samples in and actuator
//! commands out (in lock step, a repeated sample answered without a second
//! period), news from the pairer and the worker in, events for them out,
//! faults from the board's supervisor in, and the pick's state read back.

use heapless::Vec;
use nalgebra::Vector6;

use super::estimate::CellEstimate;
use super::handoff::{ControlEvent, Sighting, VisionNews};
use super::step::Step;
use super::{PickController, PickCounters, MAX_TICK_MESSAGES};
use crate::planning::TaskState;
use crate::protocol::{
    ActuatorCommand, CalibrationReport, FaultCause, GripperCommand, Message, PickPhase,
    SensorSample,
};

impl PickController {
    /// The reported phase.
    pub fn phase(&self) -> PickPhase {
        self.step.phase()
    }

    /// The fault the pick stopped for, if any.
    pub fn fault(&self) -> Option<FaultCause> {
        self.fault
    }

    /// The gripper is commanded closed or its switch saw a part at the last
    /// sample: a new configuration would open it
    /// (`crate::safety::reconfigure`).
    pub fn gripper_holds(&self) -> bool {
        self.gripper == GripperCommand::Close || self.part_in_gripper
    }

    /// The estimate in use, once there is one.
    pub fn estimate(&self) -> Option<&CellEstimate> {
        self.estimate.as_ref()
    }

    /// What the controller refused or clipped so far.
    pub fn counters(&self) -> PickCounters {
        self.counters
    }

    /// Seconds since the first sensor sample.
    pub fn time_s(&self) -> f32 {
        self.now_s
    }

    /// News from the pairer or the worker; the firmware delivers it before
    /// the next sensor sample, the simulator at once (the same thing: nothing
    /// here depends on the time between).
    pub fn on_news(&mut self, news: &VisionNews) {
        match news {
            VisionNews::Paired { sighting, view } => {
                self.counters.frames_paired = self.counters.frames_paired.saturating_add(1);
                if view.is_some_and(|view| view.reference_px.is_some()) {
                    self.counters.reference_frames =
                        self.counters.reference_frames.saturating_add(1);
                }
                self.last_paired_s = self.now_s;
                if let (Some(view), true) = (view, self.step.watches_view()) {
                    if let Some(cause) = self.view.check(view) {
                        self.raise(cause);
                    }
                }
                if let Some(sighting) = sighting {
                    self.on_sighting(sighting);
                }
                if view.is_some_and(|view| view.part_seen) {
                    self.sightings.part_seen();
                }
            }
            VisionNews::Unpaired => {
                self.counters.frames_unpaired = self.counters.frames_unpaired.saturating_add(1);
            }
            VisionNews::Refused => {
                self.counters.frames_refused = self.counters.frames_refused.saturating_add(1);
            }
            VisionNews::Result(result) => {
                if self.jobs.accept(result, self.now_s) {
                    self.counters.late_results = self.counters.late_results.saturating_add(1);
                }
            }
        }
    }

    /// The camera saw the marks: counted, and kept by the sightings.
    fn on_sighting(&mut self, sighting: &Sighting) {
        self.counters.effector_sightings = self.counters.effector_sightings.saturating_add(1);
        self.sightings.record(sighting, self.now_s);
        match self.step {
            Step::SearchApproach => self.route.seen_in(0, sighting.flange_direction_xy),
            Step::SearchSweep(leg) | Step::SearchShift(leg) => {
                self.route.seen_in(leg, sighting.flange_direction_xy)
            }
            _ => {}
        }
    }

    /// The next event for the pairer or the worker, oldest first. Drain them
    /// all after every sensor sample.
    pub fn pop_event(&mut self) -> Option<ControlEvent> {
        self.outbox.pop_front()
    }

    /// Whether the period of a sample stamped `time_us` fires the camera: a
    /// board that latches its encoders at the trigger edge asks before it
    /// reads them, so the period's sample is the latched one.
    pub fn camera_trigger_due(&self, time_us: u64) -> bool {
        let start_us = self.start_time_us.unwrap_or(time_us);
        let now_s = crate::kernels::micros_to_seconds(time_us.saturating_sub(start_us));
        self.camera_trigger.due(now_s)
    }

    /// True when the sample at `time_us` is due to apply a job's result that
    /// has not come yet. A lock-step caller (the emulated board) waits for the
    /// worker before such a sample, so the run is the same at any speed; a
    /// real-time caller does not, and the result is applied late.
    pub fn awaits_result(&self, time_us: u64) -> bool {
        let now_s = match self.start_time_us {
            Some(start) => time_us.saturating_sub(start) as f32 * 1e-6,
            None => 0.0,
        };
        self.jobs.awaits(now_s)
    }

    /// Whether `sample` is the last period's sample sent again: in lock step a
    /// host that lost the command (a corrupt frame on the link) repeats the
    /// sample, and the plant has not moved, so the period must not run twice.
    pub fn repeats(&self, sample: &SensorSample) -> bool {
        self.last_command.is_some_and(|c| c.seq == sample.seq)
            && sample.time_us == self.last_time_us
    }

    /// The number of frames the link's decoder refused so far, reported in
    /// telemetry (the link task owns the decoder; it hands the count over).
    pub fn set_link_frames_rejected(&mut self, frames: u32) {
        self.link_frames_rejected = frames;
    }

    /// One control period: the sensor sample in, the actuator command (and any
    /// telemetry) out. A repeated sample ([`Self::repeats`]) is answered with
    /// the same command and nothing else; no period runs.
    pub fn on_sensor_sample(
        &mut self,
        sample: &SensorSample,
        out: &mut Vec<Message, MAX_TICK_MESSAGES>,
    ) -> ActuatorCommand {
        if let (true, Some(command)) = (self.repeats(sample), self.last_command) {
            return command;
        }
        let command = self.run_period(sample, out);
        self.last_command = Some(command);
        command
    }

    /// A fault the board's supervisor found (link lost, a board error): the
    /// same controlled stop as the pick's own faults (decelerate, then hold),
    /// reported with its cause. Nothing happens if the pick already stopped.
    pub fn stop(&mut self, cause: FaultCause) {
        self.raise(cause);
    }

    /// The board has put the arm on its holding brakes (a parked board,
    /// `shared::safety::parking`): nothing the controller commands moves it
    /// any more. Eq 23 must then neither integrate the error the brakes hold
    /// in place (its integral would wind up) nor feed the joint observer the
    /// accelerations it commands: an observer that expects the commanded
    /// motion from a braked arm drifts from the encoders until it refuses
    /// them (a `JointEncoder` fault after a finished pick). Latched until the
    /// controller is replaced by a new configuration, as the parking is.
    pub fn on_brakes(&mut self) {
        self.on_brakes = true;
    }

    /// A job request could not be handed to the worker (its queue was full):
    /// its result would never come, so stop rather than wait.
    pub fn on_job_lost(&mut self) {
        self.raise(FaultCause::Timeout);
    }

    /// The latest calibration report and its serial number (one more per estimate).
    pub fn calibration_report(&self) -> Option<(u32, CalibrationReport)> {
        self.estimate
            .as_ref()
            .map(|e| (self.estimate_serial, e.report))
    }

    /// The serial of the estimate in use (changes with each new estimate).
    pub fn estimate_serial(&self) -> Option<u32> {
        self.estimate.as_ref().map(|_| self.estimate_serial)
    }

    /// The flange reference Eq 23 follows (`Y^d` of Fig 3).
    pub fn reference(&self) -> TaskState<f32> {
        self.reference
    }

    /// The commanded twist's norm, for tests.
    #[doc(hidden)]
    pub fn twist_norm(&self) -> f32 {
        let twist: Vector6<f32> = self.reference.twist();
        twist.norm()
    }
}
