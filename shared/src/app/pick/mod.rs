//! The pick: the controller application's state machine (paper Fig 3), run at
//! control rate by the firmware and by the in-process simulator alike.
//!
//! Nothing is known at the start but the cell configuration (intrinsics, the
//! reference radius, encoder scales, the drop-off). The controller:
//! 1. sweeps the gripper's two marks round the robot at travel height while the
//!    disc turns, until the camera has seen them (the disc's and the camera's
//!    pose come from the reference mark's ellipse, Section 2.1);
//! 2. estimates a first calibration (Sections 2 and 3), then shows the marks at
//!    poses chosen over the disc, in view, and estimates again: `base_from_disc`
//!    (Eqs 10 to 15) and the part in the rotating frame (Eqs 3 to 8);
//! 3. waits for a steady conveyor, plans the earliest smooth intercept that the
//!    joints can follow and after which the part stays in reach, and meets the
//!    part (Eq 1 fused at control rate with the conveyor encoder);
//! 4. tracks it, descends, grasps, lifts, carries it to the drop-off round the
//!    base axis, releases it and returns to the start pose.
//!
//! Every phase has a timeout; a fault (calibration refused, marks never seen,
//! vision stale, encoder jump, tracking error, part out of reach, control
//! failure) brings the arm to a controlled stop (decelerate, then hold) and is
//! reported with its cause.
//!
//! Here is the state machine: its steps (`step`), what entering each one
//! sets going and when each ends. Its parts answer it: the period's
//! measurements and Eq 23 (`period`), the `supervisor`'s checks, where
//! each step goes (`route`, `stop`), the job in flight (`job_slot`), the
//! marks' `sightings`, the `telemetry`, the construction (`build`).

pub mod brake;
mod build;
mod camera_trigger;
pub mod cell;
pub mod drop_off;
mod early;
pub mod estimate;
pub mod handoff;
mod io;
mod job_slot;
pub mod jobs;
pub mod motion;
#[cfg(test)]
mod on_brakes_tests;
pub mod pace;
pub mod pairing;
mod period;
mod refresh;
mod route;
pub mod search;
pub mod settings;
mod sightings;
mod step;
mod stop;
mod supervisor;
#[cfg(test)]
mod sure_tests;
mod telemetry;
#[cfg(test)]
mod trigger_due_tests;
pub mod view_monitor;
pub mod window;
pub mod worker;

use heapless::{Deque, Vec};
use nalgebra::Vector3;

pub use self::build::PickParts;

use self::brake::JointBrake;
use self::camera_trigger::CameraTrigger;
use self::cell::Cell;
use self::early::EarlyFinish;
use self::estimate::CellEstimate;
use self::handoff::{ControlEvent, JobOutcome, JobRequest};
use self::job_slot::{JobKind, JobSlot};
use self::jobs::{ConveyorSnapshot, MAX_CALIBRATION_POSES, SAME_HEIGHT_M};
use self::motion::Motion;
use self::pace::CalibrationPose;
use self::refresh::Refresh;
use self::route::{travel_z, Route};
use self::settings::PickSettings;
use self::sightings::Sightings;
use self::step::Step;
use self::stop::{stop_motion, stop_start, Measured};
use self::supervisor::Supervisor;
use self::view_monitor::ViewMonitor;
use super::joint_observer::JointObserver;
use super::joint_speed::JointSpeedWindow;
use super::tool::TOOL_LENGTH_M;
use crate::calibration::SelfCalibrator;
use crate::control::TaskSpaceController;
use crate::fusion::{ConveyorFilter, ConveyorMeanSpeed, ConveyorState};
use crate::planning::{ArcLimits, ArcPoint, PlanError, TaskPath, TaskState};
use crate::protocol::{ActuatorCommand, CalibrationReport, FaultCause, GripperCommand};
use crate::robot::{JointVector, Puma560};

/// The controller's calibrator, the same in the firmware and in the simulator:
/// 256 frames and 128 sightings of the marks, enough to keep every frame of a
/// calibration (about 215 in 43 s at 5 Hz) and every sighting instead of
/// thinning them. The store's size is the pick's accuracy: with 96 frames and
/// 64 sightings the part is 7.1 mm and 0.80 deg off at the 95th percentile
/// over 1,000 workcells, with 256 and 128 4.2 mm and 0.43 deg. Frames are
/// packed with a budget of [`PICK_PIXELS_PER_FRAME`] pixels a frame on
/// average (17.7 KiB in all): all 256 for a part of up to three features, 128
/// for one of eight.
pub type PickCalibrator = SelfCalibrator<256, 128, PICK_PIXELS_PER_FRAME>;

/// The pick calibrator's pixel budget a frame: the disc centre, the reference
/// point and three part features (the experiments' parts have three).
pub const PICK_PIXELS_PER_FRAME: usize = 5;

/// Events one control tick may leave for the pairer and the worker (a trigger
/// and a job request at most; room for one tick not drained).
pub const MAX_CONTROL_EVENTS: usize = 4;

/// An intercept plan that comes later than this after its due start is
/// dropped: the part has moved on by `omega r` times the lateness (5 mm at
/// 0.5 rad/s and 1 m of radius), more than the track step should have to
/// take up.
const LATE_PLAN_S: f32 = 0.01;

/// Messages one control tick may emit besides its actuator command.
pub const MAX_TICK_MESSAGES: usize = 3;

/// Counters of what the controller refused or clipped.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PickCounters {
    /// Camera frames paired with their trigger's encoder values.
    pub frames_paired: u32,
    /// Camera frames that matched no trigger.
    pub frames_unpaired: u32,
    /// Paired frames refused (bad labels) or that the calibrator refused
    /// (invalid detections, time going back).
    pub frames_refused: u32,
    /// Job results that came after their due time (the worker was too slow).
    pub late_results: u32,
    /// Intercept plans that came too late to start on time, dropped and
    /// planned again with a longer lead.
    pub late_plans_dropped: u32,
    /// Control periods whose torques Eq 23 had to clip to the joints' ratings.
    pub saturated_ticks: u32,
    /// Frames in which the camera saw the gripper's marks.
    pub effector_sightings: u32,
    /// Paired frames that showed the disc's reference mark.
    pub reference_frames: u32,
    /// Gaps between control periods longer than the stall limit.
    pub stalls: u32,
    /// Times the joint brake took over from Eq 23.
    pub brakes: u32,
}

/// The pick's control loop: fusion (Eq 1), the state machine and Eq 23, once
/// per sensor sample. Its vision and background work are the [`pairing::FramePairer`]'s
/// and the [`worker::PickWorker`]'s, reached through [`ControlEvent`]s and
/// [`handoff::VisionNews`].
#[derive(Debug, Clone)]
pub struct PickController {
    // The cell and the laws that run in it.
    /// The configuration, checked.
    cell: Cell,
    /// The pick's tuning.
    settings: PickSettings,
    /// The dynamic model of Eq 23 and of the supervisor's limits.
    model: Puma560<f32>,
    /// Eq 23.
    controller: TaskSpaceController<f32>,
    /// Eq 23's commanded joint accelerations (the observer's input).
    qdd_commanded: JointVector<f32>,
    /// When Eq 23's integral was last cleared (a stall).
    integral_reset_s: f32,
    /// Engaged when the task-space stop cannot be trusted; then for good.
    brake: Option<JointBrake>,
    /// The board's holding brakes hold the arm ([`Self::on_brakes`]).
    on_brakes: bool,

    // The period's clock.
    /// The first sample's time, microseconds.
    start_time_us: Option<u64>,
    /// The last sample's time, microseconds.
    last_time_us: u64,
    /// Seconds since the first sample.
    now_s: f32,
    /// Periods run.
    ticks: u64,

    // What the sensors say.
    /// Joint angles and speeds from the encoders and the commanded accelerations.
    observer: JointObserver,
    /// Joint speeds from the encoders alone, for the speed supervisor.
    speed_window: JointSpeedWindow,
    /// Eq 1's theta from the conveyor encoder.
    conveyor: ConveyorFilter<f32>,
    /// The filter's last state.
    conveyor_state: Option<ConveyorState<f32>>,
    /// The conveyor's mean speed over the last seconds: the intercept's
    /// prediction (see [`ConveyorMeanSpeed`]).
    conveyor_mean: ConveyorMeanSpeed,
    /// The flange's position measured through the joint encoders.
    flange_measured: Vector3<f32>,
    /// The grasp point measured through the joint encoders.
    tool_measured: Vector3<f32>,
    /// The flange's yaw measured through the joint encoders.
    tool_yaw_measured: f32,
    /// The gripper's part-present switch at the last sample.
    part_in_gripper: bool,
    /// When a frame was last paired with its trigger.
    last_paired_s: f32,
    /// The marks' sightings: where the disc is, which heights are clear.
    sightings: Sightings,
    /// The camera's view checked against the final calibration.
    view: ViewMonitor,

    // The state machine.
    /// The step the pick is in.
    step: Step,
    /// When `step` was entered.
    step_started_s: f32,
    /// What the gripper is being asked to do.
    motion: Motion,
    /// Eq 23's reference (`Y^d`), the flange's.
    reference: TaskState<f32>,
    /// The gripper's command.
    gripper: GripperCommand,
    /// The first fault raised, if any.
    fault: Option<FaultCause>,
    /// Where each step goes.
    route: Route,
    /// The checks of every period.
    supervisor: Supervisor,
    /// The calibration in use, once there is one.
    estimate: Option<CellEstimate>,
    /// One more for every estimate.
    estimate_serial: u32,
    /// The estimate refreshed during the intercept, and the blend to it.
    refresh: Refresh,
    /// The poses the marks are shown at.
    poses: Vec<CalibrationPose, MAX_CALIBRATION_POSES>,
    /// Rounds of calibration poses shown.
    calibration_rounds: u8,
    /// The early estimates of the calibration (see [`early`]).
    early: EarlyFinish,
    /// The final calibration was accepted (the pick may go down to the part).
    calibration_accepted: bool,
    /// The earliest time of the next intercept plan's request.
    next_plan_attempt_s: f32,
    /// How long after its request an intercept plan starts: the settings'
    /// budget, lengthened when a plan came too late to start on time.
    plan_lead_s: f32,
    /// Intercepts planned for the part so far.
    intercept_attempts: u8,
    /// When the grasp point was last further than `close_tolerance_m` from
    /// its reference (or the step began), s.
    last_unsettled_s: f32,
    /// The conveyor speed the running intercept's grasp window was proven
    /// at (`window::grasp_window_holds`), rad/s.
    window_omega: f32,
    /// The longest settle before the close that window was proven for, s,
    /// plus the track's spare time once the track has settled.
    window_settle_max_s: f32,

    // What goes out and comes back.
    /// The job in flight.
    jobs: JobSlot,
    /// Events for the pairer and the worker, drained after every sample.
    outbox: Deque<ControlEvent, MAX_CONTROL_EVENTS>,
    /// The camera's trigger clock.
    camera_trigger: CameraTrigger,
    /// The last period's command: the answer to a sample sent again because
    /// the host lost its command on a noisy link (lock step).
    last_command: Option<ActuatorCommand>,
    /// What the controller refused or clipped.
    counters: PickCounters,
    /// Frames the link's decoder refused, for telemetry (set by the link's owner).
    link_frames_rejected: u32,
}

impl PickController {
    /// The lowest flange height a motion may go to before the calibration
    /// is accepted (`PickSettings::max_descent_step_m` below the known-clear height).
    fn safe_floor_z(&self) -> f32 {
        self.sightings
            .safe_floor_z(self.settings.max_descent_step_m)
    }

    /// The first sample: remember where the arm starts and hold it there.
    fn begin(&mut self, flange: &nalgebra::Isometry3<f32>) {
        let x_axis = flange.rotation * Vector3::x();
        let yaw = libm::atan2f(x_axis.y, x_axis.x);
        let position = flange.translation.vector;
        let planned = self.route.start_from(
            ArcPoint::from_position(&position, yaw),
            &self.model,
            &self.observer.q(),
            &position,
            &self.settings,
        );
        self.reference = TaskState::at_rest(position, yaw);
        self.motion = Motion::Hold(self.reference);
        self.last_paired_s = self.now_s;
        // Until the camera has seen the marks: where the arm stands, or the
        // travel height (declared clear of any disc and part) if lower.
        self.sightings
            .start_at(position.z, travel_z(&self.settings));
        match planned {
            Ok(()) => self.enter(Step::SearchApproach),
            // The settings' travel height is beyond the arm's reach: no search.
            Err(_) => {
                self.step = Step::SearchApproach;
                self.step_started_s = self.now_s;
                self.raise(FaultCause::BadConfig);
            }
        }
    }

    /// Stops trusting the task space: the joint brake takes over for good.
    fn engage_brake(&mut self) {
        if self.brake.is_none() {
            self.brake = Some(JointBrake::new());
            self.counters.brakes = self.counters.brakes.saturating_add(1);
        }
        if self.fault.is_none() {
            self.fault = Some(FaultCause::ControlFailure);
        }
        self.jobs.cancel();
        self.step = Step::Faulted;
        self.step_started_s = self.now_s;
    }

    /// Stops the pick for `cause`: the first cause is the one reported.
    fn raise(&mut self, cause: FaultCause) {
        if self.step.stopping() {
            return;
        }
        if self.step == Step::Done {
            // The part is placed and the arm holds at rest at its start pose:
            // there is no motion to stop. The cause is reported; a stop
            // started here would be a new motion, and a fault must never
            // start one.
            if self.fault.is_none() {
                self.fault = Some(cause);
            }
            return;
        }
        self.fault = Some(cause);
        self.jobs.cancel();
        self.enter(Step::Stopping);
    }

    /// An arc from the present reference (at rest) to `target`.
    fn arc_to(&self, target: ArcPoint<f32>) -> Result<Motion, PlanError> {
        self.route
            .arc(&self.reference, target, self.now_s, &ArcLimits::default())
    }

    /// Where the flange was when the camera saw the marks on sweep `leg`
    /// (the look passes over it), or, if it saw none there, the first
    /// mark's mean direction over the whole search.
    fn seen_azimuth(&self, leg: u8) -> f32 {
        self.route
            .seen_azimuth(leg)
            .unwrap_or_else(|| self.sightings.azimuth())
    }

    /// An arc of the search: no faster than `search_speed_m_s`, so the marks
    /// stay in the camera's view for enough frames to be labelled.
    fn search_arc_to(&self, target: ArcPoint<f32>) -> Result<Motion, PlanError> {
        self.search_arc_at(target, self.settings.search_speed_m_s)
    }

    /// An arc no faster than `max_speed_m_s`.
    fn search_arc_at(
        &self,
        target: ArcPoint<f32>,
        max_speed_m_s: f32,
    ) -> Result<Motion, PlanError> {
        let limits = ArcLimits {
            max_speed_m_s,
            ..ArcLimits::default()
        };
        self.route.arc(&self.reference, target, self.now_s, &limits)
    }

    /// How long the step's motion has left `in_step` into the step, s
    /// (negative: how long it has held its end; a hold has no length).
    fn motion_left_s(&self, in_step: f32) -> f32 {
        self.motion.duration_s().unwrap_or(0.0) - in_step
    }

    /// Asks the worker for `request` (a job of `kind`), its outcome applied
    /// `budget_s` from now.
    fn request(&mut self, request: JobRequest, kind: JobKind, budget_s: f32) {
        let ticket = self.jobs.open(request, kind, self.now_s + budget_s);
        self.post(ControlEvent::Job(ticket));
    }

    /// Leaves an event for the caller to hand on. The outbox is drained after
    /// every tick and one tick posts two events at most, so it never overflows;
    /// if a caller forgot to drain it, the oldest event is the one dropped.
    fn post(&mut self, event: ControlEvent) {
        if self.outbox.is_full() {
            let _ = self.outbox.pop_front();
        }
        let _ = self.outbox.push_back(event);
    }

    /// Why a search that ended without enough sightings failed: the vision
    /// stage labels the gripper's marks against the disc it has identified
    /// (images seed 11, cells 264 and 460: the part's features crowded the
    /// reference mark and the disc was never identified); with no frame of
    /// the reference mark at all, that is the cause to report.
    fn search_failure(&self) -> FaultCause {
        if self.counters.reference_frames == 0 {
            FaultCause::DiscNotSeen
        } else {
            FaultCause::EffectorNotSeen
        }
    }

    /// The reference, at rest, as an arc's start point.
    fn resting_point(&self) -> ArcPoint<f32> {
        ArcPoint::from_position(&self.reference.position, self.reference.yaw)
    }

    fn hold_here(&mut self) {
        self.motion = Motion::Hold(TaskState::at_rest(
            self.reference.position,
            self.reference.yaw,
        ));
    }

    /// Enters `step`, setting the motion it starts with.
    fn enter(&mut self, step: Step) {
        self.step = step;
        self.step_started_s = self.now_s;
        self.last_unsettled_s = self.now_s;
        let settings = self.settings;
        let drop_off = self.cell.drop_off_base;
        let motion = match step {
            Step::Start | Step::Done | Step::Faulted => {
                self.hold_here();
                return;
            }
            Step::SearchApproach | Step::SearchShift(_) => {
                let leg = match step {
                    Step::SearchShift(leg) => leg,
                    _ => 0,
                };
                match self.route.sweep_start(leg) {
                    Some(target) => self.search_arc_to(target),
                    None => Err(PlanError::InvalidLimits {
                        what: "the search has no such sweep",
                    }),
                }
            }
            Step::SearchSweep(leg) => {
                self.route.sweeping(leg);
                match self.route.sweep_end(leg) {
                    Some(target) => self.search_arc_to(target),
                    None => Err(PlanError::InvalidLimits {
                        what: "the search has no such sweep",
                    }),
                }
            }
            Step::SearchReturn => {
                // Back to where the marks were seen: over the disc, near the part.
                let leg = self.route.sweep();
                // (Towards the first mark's mean direction over the whole
                // search: returning over the flange's on this sweep instead
                // changed every cell's first estimate and measured no
                // better, part at the grasp 2.37 against 2.24 mm at the
                // 95th percentile through images, seed 11.)
                match self.route.search_return(leg, self.sightings.azimuth()) {
                    Some(target) => {
                        let motion = self.arc_to(target);
                        // Seen often enough already: the preliminary estimate
                        // is made while the arm goes back, not after.
                        if motion.is_ok()
                            && self.counters.effector_sightings >= settings.min_effector_sightings
                            && self.jobs.is_idle()
                        {
                            let request = self.estimate_request(true, target);
                            self.request(
                                request,
                                JobKind::PreliminaryOnTheWay,
                                settings.estimate_budget_s,
                            );
                        }
                        motion
                    }
                    None => Err(PlanError::InvalidLimits {
                        what: "the search has no such sweep",
                    }),
                }
            }
            Step::SearchLook(pass) => {
                let leg = self.route.sweep();
                let half_width = settings.search_look_half_width_m;
                match self
                    .route
                    .search_look(leg, self.seen_azimuth(leg), pass, half_width)
                {
                    Some(target) => self.search_arc_at(target, settings.search_look_speed_m_s),
                    None => Err(PlanError::InvalidLimits {
                        what: "the search has no such sweep",
                    }),
                }
            }
            Step::EstimatePreliminary | Step::EstimateFinal => {
                self.hold_here();
                let preliminary = step == Step::EstimatePreliminary;
                if preliminary && self.jobs.holds(JobKind::PreliminaryOnTheWay) {
                    // Asked for on the way back; it lands here.
                    return;
                }
                // An early estimate still in flight is replaced: this one
                // has every pose's frames.
                let request = self.estimate_request(preliminary, self.resting_point());
                self.request(request, JobKind::Estimate, settings.estimate_budget_s);
                return;
            }
            Step::CalibrateMove(i) => match self.poses.get(usize::from(i)).copied() {
                Some(CalibrationPose {
                    point: target,
                    min_duration_s,
                }) => {
                    // A height not yet confirmed clear by a sighting from above
                    // is shown at the lowest one that is: seen there, the marks
                    // clear the next step down. (Skipping it instead left every
                    // pose below a search that had looked from high up: no pose
                    // at all, and a base known from the search's sightings alone.)
                    let floor = self.safe_floor_z();
                    let raised = target.z_m < floor;
                    let target = ArcPoint {
                        z_m: target.z_m.max(floor),
                        ..target
                    };
                    // At the pace the worker proved for the joints' speeds (a
                    // raised pose keeps its own height's pace; the supervisor
                    // checks the live reference's joint speeds every period).
                    let planned = pace::calibration_arc(
                        &self.resting_point(),
                        &target,
                        self.route.waist_centre_azimuth(),
                        min_duration_s,
                    )
                    .map(|path| Motion::Arc {
                        path,
                        start_s: self.now_s,
                    });
                    // Reach is checked for a raised pose only (a pose at its own
                    // height was planned reachable with the estimate): the trig
                    // and the reach test cost the period a few hundred instructions.
                    if raised
                        && (planned.is_err()
                            || !crate::planning::within_reach(
                                &self.model,
                                &Vector3::new(
                                    target.radius_m * libm::cosf(target.azimuth_rad),
                                    target.radius_m * libm::sinf(target.azimuth_rad),
                                    target.z_m,
                                ),
                            ))
                    {
                        // Out of reach raised: the next pose.
                        self.enter(Step::CalibrateMove(i.saturating_add(1)));
                        return;
                    }
                    planned
                }
                None => {
                    self.enter(Step::EstimateFinal);
                    return;
                }
            },
            Step::CalibrateDwell(_) => {
                self.hold_here();
                return;
            }
            Step::Locate => {
                // A fresh look for a steady conveyor and a new plan.
                self.next_plan_attempt_s = self.now_s;
                self.route.locating_from(&self.reference);
                self.hold_here();
                return;
            }
            Step::Release => {
                self.hold_here();
                self.gripper = GripperCommand::Open;
                return;
            }
            Step::Intercept => return,
            Step::Relocate => match self.route.locate_pose() {
                Some(target) => self.arc_to(target),
                None => {
                    self.enter(Step::Locate);
                    return;
                }
            },
            Step::Track | Step::Descend | Step::GraspSettle => {
                route::follow(step, &settings, self.now_s)
            }
            Step::GraspClose => {
                self.gripper = GripperCommand::Close;
                return;
            }
            Step::Lift => route::lift(&self.reference, &settings, self.now_s),
            Step::PlaceTransfer => {
                let target = self
                    .route
                    .carry_to(&drop_off, self.reference.position.z, &settings);
                self.arc_to(target)
            }
            Step::PlaceLower => self.arc_to(self.route.lower_onto(&drop_off)),
            Step::ReturnRaise => self.arc_to(self.route.raise_from(&drop_off)),
            Step::ReturnTransfer => self.arc_to(self.route.home()),
            Step::Stopping | Step::InterceptAbandoned | Step::SearchHalt => self.decelerate(),
        };
        match motion {
            Ok(motion) => self.motion = motion,
            // No task-space stop could be planned: the joint brake stops the
            // arm instead. (Holding the reference here would leave the pick
            // in `Stopping` for good: a hold never finishes.)
            Err(_)
                if matches!(
                    step,
                    Step::Stopping | Step::InterceptAbandoned | Step::SearchHalt
                ) =>
            {
                self.engage_brake()
            }
            Err(_) => self.raise(FaultCause::PartUnreachable),
        }
    }

    /// To rest from the present reference (its speeds capped: [`stop_start`]),
    /// rising clear of the part when near it.
    fn decelerate(&self) -> Result<Motion, PlanError> {
        let measured = Measured {
            flange: self.flange_measured,
            yaw: self.tool_yaw_measured,
            reference_speed_ratio: self.supervisor.reference_speed_ratio(),
        };
        let start = stop_start(&self.reference, &measured, &self.settings);
        // An arc (a search sweep, a carry) with at most `stop_s` left comes
        // to rest sooner than a stop would, and where it was planned to end:
        // inside the joint ranges. A stop's quintic runs on for half its
        // start speed times `stop_s`; from a sweep cruising towards its end
        // that carried joint 1 to 0.5 deg of its stop.
        if let Motion::Arc { path, start_s } = self.motion {
            let left_s = start_s + path.duration() - self.now_s;
            if start == self.reference && left_s <= self.settings.stop_s {
                return Ok(self.motion);
            }
        }
        let near_part = matches!(
            self.motion,
            Motion::Follow { .. } | Motion::Intercept { .. }
        );
        stop_motion(
            &start,
            near_part,
            self.calibration_accepted,
            &self.model,
            &self.settings,
            self.now_s,
        )
    }

    /// Transitions of the state machine at this tick.
    fn advance(&mut self) {
        let now = self.now_s;
        let in_step = now - self.step_started_s;
        let finished = self.motion.finished(now);
        let settings = self.settings;
        match self.step {
            Step::Intercept => self.ask_refresh(in_step),
            Step::Track => self.take_refresh(),
            Step::CalibrateMove(_) | Step::CalibrateDwell(_) => self.take_early_estimate(),
            _ => {}
        }
        self.refresh.expire(now, settings.estimate_fade_s);
        match self.step {
            Step::Start | Step::Done | Step::Faulted => {}
            // Seen often enough, the arm has crossed the camera's view and
            // the camera has shown the part: the search halts there and
            // comes back over the sightings, instead of sweeping on to the
            // range's end first. (Holding over the disc for the part instead
            // hid the disc from the camera.)
            // A halt runs on half its start speed times `stop_s`: within the
            // last `stop_s` of a sweep it would carry joint 1 past the sweep's
            // end towards its stop (0.5 deg from it), so there the sweep ends.
            Step::SearchApproach | Step::SearchSweep(_) | Step::SearchShift(_)
                if self.counters.effector_sightings >= settings.min_effector_sightings
                    && self.sightings.unseen_for(now) >= settings.search_out_of_view_s
                    && self.sightings.part_frames() >= settings.min_part_frames
                    && (finished || self.motion_left_s(in_step) >= settings.stop_s) =>
            {
                self.enter(Step::SearchHalt)
            }
            Step::SearchHalt if finished => {
                if let Some(most_seen) = self.route.most_seen_sweep() {
                    self.route.return_to(most_seen);
                }
                self.enter(Step::SearchReturn)
            }
            Step::SearchApproach if finished => self.enter(Step::SearchSweep(0)),
            Step::SearchShift(leg) if finished => self.enter(Step::SearchSweep(leg)),
            Step::SearchSweep(leg) if finished => {
                let next = leg.saturating_add(1);
                if self.counters.effector_sightings >= settings.min_effector_sightings {
                    // Seen often enough: back over the marks once the camera
                    // has shown the part (held here, clear of the disc), or
                    // after `part_wait_s` (the estimate then says what it lacks).
                    // (The marks may still be in view here: the halt above,
                    // which waits for them to leave it, would never come.)
                    let held_s = -self.motion_left_s(in_step);
                    if self.sightings.part_frames() >= settings.min_part_frames
                        || held_s >= settings.part_wait_s
                    {
                        self.enter(Step::SearchReturn);
                    }
                } else if self.route.sweep_start(next).is_some() {
                    // Not seen (often enough) at this radius: the next one.
                    self.enter(Step::SearchShift(next));
                } else if let Some(most_seen) = self.route.most_seen_sweep() {
                    // Seen, but in passing (a narrow view at the band's
                    // edge): back over where, to hold there and look.
                    self.route.return_to(most_seen);
                    self.enter(Step::SearchReturn);
                } else if self.route.next_search_round() {
                    // Every radius swept and the camera never saw the
                    // gripper's marks together: again, the wrist turned.
                    self.enter(Step::SearchShift(0));
                } else {
                    // Every radius swept over joint 1's whole range, the
                    // wrist turned every way, and the camera never saw the
                    // gripper: it cannot, from where it stands.
                    self.raise(self.search_failure());
                }
            }
            Step::SearchReturn if finished => {
                if self.counters.effector_sightings >= settings.min_effector_sightings {
                    self.enter(Step::EstimatePreliminary);
                } else {
                    self.enter(Step::SearchLook(0));
                }
            }
            Step::SearchLook(pass) if finished => {
                let next = pass.saturating_add(1);
                if self.counters.effector_sightings >= settings.min_effector_sightings {
                    self.enter(Step::EstimatePreliminary);
                } else if next < settings.search_look_passes {
                    self.enter(Step::SearchLook(next));
                } else if self.route.next_search_round() {
                    // Passed slowly over where the marks were seen, and
                    // still too few: the sweeps again, the wrist turned.
                    self.enter(Step::SearchShift(0));
                } else {
                    // Passed slowly over where the marks were seen, and
                    // still too few, in the last round.
                    self.raise(self.search_failure());
                }
            }
            Step::EstimatePreliminary | Step::EstimateFinal => self.on_estimate(in_step),
            // Known well enough before the last pose: the calibration ends
            // at the pose the arm is at or on its way to. (Brought to rest
            // where it was, the arm could stop between poses with its
            // wrist near the singularity the poses keep clear of, and no
            // intercept could be planned from there: 5 cells of 1,000
            // through images.)
            Step::CalibrateMove(_) if finished && self.early.met() => self.accept_calibration(),
            Step::CalibrateDwell(_) if self.early.met() => self.accept_calibration(),
            Step::CalibrateMove(i) if finished => {
                // At the pose: the estimate is asked for as the marks are
                // shown there, and lands on the way to the next.
                self.ask_early_estimate(usize::from(i).saturating_add(1));
                self.enter(Step::CalibrateDwell(i))
            }
            Step::CalibrateDwell(i) if in_step >= settings.calibration_dwell_s => {
                self.enter(Step::CalibrateMove(i.saturating_add(1)))
            }
            Step::Locate => self.locate(in_step),
            Step::Intercept if finished => self.enter(Step::Track),
            Step::InterceptAbandoned if finished => self.enter(Step::Relocate),
            Step::Relocate if finished => self.enter(Step::Locate),
            Step::Track => {
                let error = self.tool_error_m();
                if in_step >= settings.track_settle_s && error <= settings.track_tolerance_m {
                    // The window was proven for a track of `track_window_s`
                    // and the ride is the same whatever splits it: the
                    // track's spare time may go to the settle.
                    self.window_settle_max_s += (settings.track_window_s - in_step).max(0.0);
                    self.enter(Step::Descend);
                } else if in_step >= settings.track_window_s {
                    // Not settled within the track the plan's grasp window
                    // allowed for: the part is leaving the checked window.
                    if self.intercept_attempts >= settings.max_intercept_attempts {
                        self.raise(FaultCause::TrackingError);
                    } else {
                        self.enter(Step::InterceptAbandoned);
                    }
                }
            }
            Step::Descend if in_step >= settings.descend_s => self.enter(Step::GraspSettle),
            Step::GraspSettle => {
                if self.tool_error_m() > settings.close_tolerance_m {
                    self.last_unsettled_s = now;
                }
                let settled = now - self.last_unsettled_s >= settings.close_hold_s;
                if (in_step >= settings.grasp_settle_s && settled)
                    || in_step >= self.window_settle_max_s
                {
                    self.enter(Step::GraspClose);
                }
            }
            Step::GraspClose if in_step >= settings.grasp_close_s => {
                if self.part_in_gripper {
                    self.enter(Step::Lift);
                } else {
                    self.raise(FaultCause::GraspMissed);
                }
            }
            // Carrying: a part that slips out is reported, not carried on as if held.
            Step::Lift | Step::PlaceTransfer | Step::PlaceLower if !self.part_in_gripper => {
                self.raise(FaultCause::GraspMissed)
            }
            Step::Lift if finished => self.enter(Step::PlaceTransfer),
            Step::PlaceTransfer if finished => self.enter(Step::PlaceLower),
            Step::PlaceLower if finished => self.enter(Step::Release),
            Step::Release if in_step >= settings.release_s => self.enter(Step::ReturnRaise),
            Step::ReturnRaise if finished => self.enter(Step::ReturnTransfer),
            Step::ReturnTransfer if finished => self.enter(Step::Done),
            Step::Stopping if finished => self.enter(Step::Faulted),
            // Every stop ends within its stated time: a stop still running
            // past it (it cannot, with the quintic it plans; this is the
            // guarantee, not the plan) is taken over by the joint brake.
            Step::Stopping if in_step > settings.stop_s + settings.motion_timeout_margin_s => {
                self.engage_brake()
            }
            _ => {}
        }
    }

    /// How far the grasp point, measured through the joint encoders, is from
    /// its reference, m.
    fn tool_error_m(&self) -> f32 {
        let tool_reference = self.reference.position - Vector3::new(0.0, 0.0, TOOL_LENGTH_M as f32);
        (self.tool_measured - tool_reference).norm()
    }

    /// An estimate came: a preliminary one sets the calibration poses; a
    /// final one unsure of the base shows the marks again, otherwise it is
    /// accepted and the pick locates the part.
    fn on_estimate(&mut self, in_step: f32) {
        let preliminary = self.step == Step::EstimatePreliminary;
        let on_the_way = self.jobs.holds(JobKind::PreliminaryOnTheWay);
        match self.jobs.take_ready(self.now_s) {
            // Asked for on the way back, from the sightings before it, and
            // refused: asked again from all of them, the arm at rest.
            Some(JobOutcome::Estimate(Err(_))) if preliminary && on_the_way => {
                let request = self.estimate_request(true, self.resting_point());
                self.request(request, JobKind::Estimate, self.settings.estimate_budget_s);
                self.step_started_s = self.now_s;
            }
            Some(JobOutcome::Estimate(Ok((estimate, poses)))) => {
                self.estimate = Some(estimate);
                self.estimate_serial = self.estimate_serial.wrapping_add(1);
                let unsure = !self.sure_to_grasp(&estimate.report);
                if preliminary {
                    self.poses = poses;
                    self.calibration_rounds = 1;
                    self.early = EarlyFinish::new();
                    self.enter(Step::CalibrateMove(0));
                } else if unsure
                    && self.calibration_rounds < self.settings.max_calibration_rounds
                    && !self.poses.is_empty()
                {
                    // Not sure enough of the base yet: show the marks again (the
                    // poses in reverse, so the arm does not travel back first).
                    self.calibration_rounds = self.calibration_rounds.saturating_add(1);
                    pace::reversed(&mut self.poses);
                    self.enter(Step::CalibrateMove(0));
                } else {
                    self.accept_calibration();
                }
            }
            Some(JobOutcome::Estimate(Err(cause))) => self.raise(cause),
            Some(JobOutcome::Plan(_)) => self.raise(FaultCause::Timeout),
            None if in_step > self.settings.estimate_timeout_s => self.raise(FaultCause::Timeout),
            None => {}
        }
    }

    /// The estimate in use is the calibration: the view monitor is armed
    /// with it and the pick locates the part.
    fn accept_calibration(&mut self) {
        let Some(estimate) = self.estimate else {
            // Accepted only with an estimate in use; never locate without one.
            self.raise(FaultCause::CalibrationFailed);
            return;
        };
        self.calibration_accepted = true;
        self.view.arm(
            &estimate,
            &self.cell.log_header().camera,
            self.cell.config.reference_radius_m,
        );
        self.enter(Step::Locate);
    }

    /// The worker's estimate job for the pick as it stands, the arm to be
    /// at rest at `from` when its result is applied.
    fn estimate_request(&self, preliminary: bool, from: ArcPoint<f32>) -> JobRequest {
        JobRequest::Estimate {
            preliminary,
            time_us: self.last_time_us,
            start_pose: self.route.wrist_as_seen(),
            q_now: self.observer.q(),
            from,
            waist_centre_azimuth: self.route.waist_centre_azimuth(),
        }
    }

    /// Asks for an early estimate made from the poses before `next` (the
    /// arm has reached the one before), when one is due (see [`early`]).
    fn ask_early_estimate(&mut self, next: usize) {
        let lowest = |poses: &[CalibrationPose]| {
            poses
                .iter()
                .map(|pose| pose.point.z_m)
                .fold(f32::INFINITY, f32::min)
        };
        let shown = self.poses.get(..next).unwrap_or(&[]);
        let lowest_shown = lowest(shown) <= lowest(&self.poses) + SAME_HEIGHT_M;
        let due = self.early.due(
            self.jobs.is_idle(),
            next,
            self.poses.len(),
            self.settings.early_estimate_after_poses,
            lowest_shown,
        );
        if due {
            let request = self.estimate_request(false, self.resting_point());
            self.request(request, JobKind::Early, self.settings.estimate_budget_s);
        }
    }

    /// Takes an early estimate that has come: it becomes the estimate in use
    /// only if it meets the target and the pick is sure of it; a failed one
    /// (too few sightings yet, the part's path out of reach) only means the
    /// poses go on to the final estimate, which judges for itself.
    fn take_early_estimate(&mut self) {
        if !self.jobs.holds(JobKind::Early) {
            return;
        }
        match self.jobs.take_ready(self.now_s) {
            Some(JobOutcome::Estimate(Ok((estimate, _)))) => {
                let met = early::meets_target(&estimate.report, &self.settings)
                    && self.sure_to_grasp(&estimate.report);
                self.early.landed(met);
                if met {
                    self.estimate = Some(estimate);
                    self.estimate_serial = self.estimate_serial.wrapping_add(1);
                }
            }
            Some(_) => self.early.landed(false),
            None => {}
        }
    }

    /// Asks for the intercept's refresh of the estimate when it is due: the
    /// estimate's budget before the intercept ends (see [`refresh`]).
    fn ask_refresh(&mut self, in_step: f32) {
        let remaining_s = self.motion_left_s(in_step);
        let lead_s = self.settings.estimate_budget_s;
        let track_s = self.settings.track_settle_s;
        if self.jobs.is_idle() && self.refresh.due(remaining_s, lead_s, track_s) {
            self.refresh.asked();
            let request = self.estimate_request(false, self.resting_point());
            self.request(request, JobKind::Refresh, lead_s);
        }
    }

    /// Adopts the refreshed estimate if it has come, is sure of the part and
    /// agrees with the estimate in use; otherwise the pick keeps that one.
    fn take_refresh(&mut self) {
        let Some(JobOutcome::Estimate(Ok((fresh, _)))) = self.jobs.take_ready(self.now_s) else {
            return;
        };
        let (Some(old), Some(conveyor)) = (self.estimate, self.conveyor_state) else {
            return;
        };
        let agrees = refresh::agrees(
            &old,
            &fresh,
            conveyor.theta_wrapped,
            self.settings.refresh_max_shift_m,
        );
        if agrees && self.sure_to_grasp(&fresh.report) {
            self.refresh.replaced(old, self.now_s);
            self.estimate = Some(fresh);
            self.estimate_serial = self.estimate_serial.wrapping_add(1);
        }
    }

    /// Whether the estimate's own uncertainty of the part in the base frame
    /// leaves it well inside the gripper's capture: a wrong part position is
    /// a missed grasp, and more data is what shrinks it.
    fn sure_to_grasp(&self, report: &CalibrationReport) -> bool {
        let settings = &self.settings;
        let config = &self.cell.config;
        let [horizontal_m, vertical_m] = config.grasp_capture_m;
        let within = |sigma: f32, capture: f32, sigmas: f32| sigma * sigmas <= capture;
        within(
            report.sigma_grasp_horizontal_m,
            horizontal_m,
            settings.sure_horizontal_sigmas,
        ) && within(
            report.sigma_grasp_vertical_m,
            vertical_m,
            settings.sure_axis_sigmas,
        ) && within(
            report.sigma_grasp_yaw_rad,
            config.grasp_capture_yaw_rad,
            settings.sure_axis_sigmas,
        )
    }

    /// The speed the intercept predicts the part with: the conveyor's mean
    /// over the last seconds, which a speed ripple leaves alone, unless the
    /// present speed `omega_now` is further from it than an intercept
    /// tolerates (`Supervisor::intercept_departed`): then the disc changed
    /// speed and the mean still lags it.
    fn prediction_speed(&self, omega_now: f32) -> f32 {
        let tolerance = |mean: f32| {
            self.settings
                .max_conveyor_speed_change_rad_s
                .max(self.settings.max_conveyor_speed_change_fraction * libm::fabsf(mean))
        };
        self.conveyor_mean
            .mean_rad_s()
            .filter(|mean| libm::fabsf(omega_now - mean) <= tolerance(*mean))
            .unwrap_or(omega_now)
    }

    /// Waits for a steady conveyor, asks for an intercept, and starts it.
    fn locate(&mut self, in_step: f32) {
        let late_by_s = self.jobs.ready_late_by_s(self.now_s);
        match self.jobs.take_ready(self.now_s) {
            Some(JobOutcome::Plan(Ok(_))) if late_by_s.is_some_and(|s| s > LATE_PLAN_S) => {
                // Planned for a start that has passed: the part has moved on
                // by the lateness. Plan again, with the lead this one needed.
                let needed_s = self.plan_lead_s + late_by_s.unwrap_or(0.0);
                self.plan_lead_s = (1.5 * needed_s).min(self.settings.max_plan_lead_s);
                self.counters.late_plans_dropped =
                    self.counters.late_plans_dropped.saturating_add(1);
                self.next_plan_attempt_s = self.now_s;
            }
            Some(JobOutcome::Plan(Ok((plan, prediction)))) => {
                self.intercept_attempts = self.intercept_attempts.saturating_add(1);
                self.refresh.rearm();
                self.window_omega = prediction.omega;
                self.window_settle_max_s = prediction.settle_max_s;
                self.motion = Motion::Intercept {
                    plan,
                    start_s: self.now_s,
                    prediction,
                };
                self.controller.reset();
                self.step = Step::Intercept;
                self.step_started_s = self.now_s;
                return;
            }
            Some(JobOutcome::Plan(Err(PlanError::NoGraspWindow))) => {
                self.raise(FaultCause::PartOutOfReach);
                return;
            }
            Some(JobOutcome::Plan(Err(_))) => {
                self.next_plan_attempt_s = self.now_s + 0.5;
            }
            Some(JobOutcome::Estimate(_)) | None => {}
        }
        if in_step > self.settings.locate_timeout_s {
            self.raise(FaultCause::PartUnreachable);
            return;
        }
        let Some(state) = self.conveyor_state else {
            return;
        };
        // Steady: no faster change than a speed ripple of the conveyor's own
        // drive, which scales with its speed (10 % at 0.3 Hz is 0.19 omega
        // rad/s^2: at 1 rad/s a fixed 0.2 rad/s^2 flapped on the ripple's
        // peaks and locating could wait out its timeout).
        let steady = state.alpha.abs()
            <= self
                .settings
                .steady_alpha_rad_s2
                .max(self.settings.steady_alpha_per_omega * state.omega.abs());
        let Some(estimate) = self.estimate else {
            // Locate is only entered with an estimate; never plan without one.
            self.raise(FaultCause::CalibrationFailed);
            return;
        };
        if self.jobs.is_idle() && steady && self.now_s >= self.next_plan_attempt_s {
            let start = TaskState::at_rest(self.reference.position, self.reference.yaw);
            let request = JobRequest::Plan {
                start,
                q_start: self.observer.q(),
                conveyor: ConveyorSnapshot {
                    theta: state.theta_wrapped,
                    omega: self.prediction_speed(state.omega),
                    lead_s: self.plan_lead_s,
                },
                estimate,
            };
            self.request(request, JobKind::Plan, self.plan_lead_s);
        }
    }
}
