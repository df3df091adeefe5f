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

pub mod brake;
pub mod cell;
pub mod estimate;
pub mod handoff;
pub mod jobs;
pub mod motion;
pub mod pairing;
pub mod settings;
pub mod view_monitor;
pub mod worker;

use heapless::{Deque, Vec};
use nalgebra::{Vector3, Vector6};

use self::brake::JointBrake;
use self::cell::{Cell, ConfigError};
use self::estimate::CellEstimate;
use self::handoff::{
    ControlEvent, JobOutcome, JobRequest, JobResult, JobTicket, Sighting, TriggerRecord, VisionNews,
};
use self::jobs::{yaw_at_azimuth, ConveyorSnapshot, MAX_CALIBRATION_POSES};
use self::motion::{height_profile, Motion};
use self::pairing::FramePairer;
use self::settings::{at_most, PickSettings};
use self::view_monitor::{ViewLimits, ViewMonitor};
use self::worker::PickWorker;
use super::joint_observer::JointObserver;
use super::joint_speed::JointSpeedWindow;
use super::tool::{tool_point_base, EFFECTOR_MARKS_FLANGE_M, TOOL_LENGTH_M};
use crate::calibration::SelfCalibrator;
use crate::control::{
    ControllerConfig, TaskKinematics, TaskReference, TaskSpaceController, TaskSpaceModel,
};
use crate::fusion::conveyor::wrap_pi;
use crate::fusion::{ConveyorFilter, ConveyorState, LatchedSample};
use crate::kernels::micros_to_seconds;
use crate::planning::{
    within_reach, within_stretch, ArcLimits, ArcMove, ArcPoint, InterceptPlan, PlanError, TaskState,
};
use crate::protocol::{
    ActuatorCommand, CellConfig, FaultCause, GripperCommand, Message, PickPhase, PickTelemetry,
    SensorSample,
};
use crate::robot::{DriveOptions, JointTrig, JointVector, Puma560, SIMULATOR_COULOMB_WIDTH};

/// The controller's calibrator, the same in the firmware and in the simulator:
/// 256 frames and 128 sightings of the marks, enough to keep every frame of a
/// calibration (about 215 in 43 s at 5 Hz) and every sighting instead of
/// thinning them. The store's size is the pick's accuracy: 96 frames and 64
/// sightings left the part 7.1 mm and 0.80 deg off at the 95th percentile over
/// 1,000 workcells, 256 and 128 4.2 mm and 0.43 deg. Frames are packed with a
/// budget of [`PICK_PIXELS_PER_FRAME`] pixels a frame on average (17.7 KiB in
/// all): all 256 for a part of up to three features, 128 for one of eight.
pub type PickCalibrator = SelfCalibrator<256, 128, PICK_PIXELS_PER_FRAME>;

/// The pick calibrator's pixel budget a frame: the disc centre, the reference
/// point and three part features (the experiments' parts have three).
pub const PICK_PIXELS_PER_FRAME: usize = 5;

/// Events one control tick may leave for the pairer and the worker (a trigger
/// and a job request at most; room for one tick not drained).
pub const MAX_CONTROL_EVENTS: usize = 4;

/// How far the gripper's marks sit below the flange with the gripper down.
const MARK_BELOW_FLANGE_M: f32 = EFFECTOR_MARKS_FLANGE_M[0][2] as f32;

/// Messages one control tick may emit besides its actuator command.
pub const MAX_TICK_MESSAGES: usize = 3;

/// The fine-grained steps behind the reported [`PickPhase`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Step {
    Start,
    SearchApproach,
    SearchSweep,
    SearchReturn,
    EstimatePreliminary,
    CalibrateMove(u8),
    CalibrateDwell(u8),
    EstimateFinal,
    Locate,
    Intercept,
    /// The conveyor left the intercept's prediction: the arm comes to rest,
    /// returns to where the part was first located from, and locates it again.
    InterceptAbandoned,
    Relocate,
    Track,
    Descend,
    GraspSettle,
    GraspClose,
    Lift,
    PlaceTransfer,
    PlaceLower,
    Release,
    ReturnRaise,
    ReturnTransfer,
    Done,
    Stopping,
    Faulted,
}

impl Step {
    fn phase(self) -> PickPhase {
        match self {
            Self::Start => PickPhase::Idle,
            Self::SearchApproach | Self::SearchSweep | Self::SearchReturn => {
                PickPhase::SearchEffector
            }
            Self::CalibrateMove(_) | Self::CalibrateDwell(_) => PickPhase::CalibrateBase,
            Self::EstimatePreliminary | Self::EstimateFinal => PickPhase::Estimating,
            Self::Locate | Self::InterceptAbandoned | Self::Relocate => PickPhase::Locate,
            Self::Intercept => PickPhase::Intercept,
            Self::Track => PickPhase::Track,
            Self::Descend => PickPhase::Descend,
            Self::GraspSettle | Self::GraspClose => PickPhase::Grasp,
            Self::Lift => PickPhase::Lift,
            Self::PlaceTransfer | Self::PlaceLower => PickPhase::Place,
            Self::Release => PickPhase::Release,
            Self::ReturnRaise | Self::ReturnTransfer => PickPhase::Return,
            Self::Done => PickPhase::Done,
            Self::Stopping => PickPhase::Stopping,
            Self::Faulted => PickPhase::Faulted,
        }
    }

    /// Steps that need fresh camera frames (before the grasp).
    fn needs_vision(self) -> bool {
        matches!(
            self,
            Self::SearchApproach
                | Self::SearchSweep
                | Self::SearchReturn
                | Self::CalibrateMove(_)
                | Self::CalibrateDwell(_)
                | Self::Locate
                | Self::Intercept
                | Self::InterceptAbandoned
                | Self::Relocate
                | Self::Track
                | Self::Descend
        )
    }

    /// Steps in which the view monitor checks the camera and the encoder
    /// against the final calibration: from it to the grasp.
    fn watches_view(self) -> bool {
        matches!(
            self,
            Self::Locate
                | Self::Intercept
                | Self::InterceptAbandoned
                | Self::Relocate
                | Self::Track
                | Self::Descend
                | Self::GraspSettle
        )
    }

    /// Steps whose observations may feed the calibrator: the part still sits on the disc.
    fn part_on_disc(self) -> bool {
        !matches!(
            self,
            Self::GraspClose
                | Self::Lift
                | Self::PlaceTransfer
                | Self::PlaceLower
                | Self::Release
                | Self::ReturnRaise
                | Self::ReturnTransfer
                | Self::Done
        )
    }
}

/// A job in flight: requested, maybe computed, applied at `apply_at_s` (a
/// fixed delay after the request, so the run does not depend on how fast the
/// worker is, as long as it is done by then).
#[derive(Debug, Clone, PartialEq)]
struct Job {
    job_id: u32,
    outcome: Option<JobOutcome>,
    apply_at_s: f32,
}

/// Counters of what the controller refused or clipped.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PickCounters {
    pub frames_paired: u32,
    pub frames_unpaired: u32,
    /// Paired frames refused (bad labels) or that the calibrator refused
    /// (invalid detections, time going back).
    pub frames_refused: u32,
    /// Job results that came after their due time (the worker was too slow).
    pub late_results: u32,
    pub saturated_ticks: u32,
    pub effector_sightings: u32,
    /// Gaps between control periods longer than the stall limit.
    pub stalls: u32,
    /// Times the joint brake took over from Eq 23.
    pub brakes: u32,
}

/// The pick's control loop: fusion (Eq 1), the state machine and Eq 23, once
/// per sensor sample. Its vision and background work are the [`FramePairer`]'s
/// and the [`PickWorker`]'s, reached through [`ControlEvent`]s and
/// [`VisionNews`].
#[derive(Debug, Clone)]
pub struct PickController {
    cell: Cell,
    settings: PickSettings,
    model: Puma560<f32>,
    controller: TaskSpaceController<f32>,
    observer: JointObserver,
    conveyor: ConveyorFilter<f32>,
    conveyor_state: Option<ConveyorState<f32>>,
    session: u32,
    next_job_id: u32,
    outbox: Deque<ControlEvent, MAX_CONTROL_EVENTS>,
    start_time_us: Option<u64>,
    last_time_us: u64,
    now_s: f32,
    ticks: u64,
    next_trigger_s: f32,
    next_trigger_id: u32,
    last_paired_s: f32,
    step: Step,
    step_started_s: f32,
    motion: Motion,
    reference: TaskState<f32>,
    gripper: GripperCommand,
    fault: Option<FaultCause>,
    start_pose: ArcPoint<f32>,
    estimate: Option<CellEstimate>,
    poses: Vec<ArcPoint<f32>, MAX_CALIBRATION_POSES>,
    job: Option<Job>,
    next_plan_attempt_s: f32,
    transfer_z: f32,
    /// Sum of the unit vectors towards the marks where the camera saw them (their
    /// mean direction is where the disc is, roughly).
    sighting_direction: [f32; 2],
    calibration_rounds: u8,
    estimate_serial: u32,
    qdd_commanded: JointVector<f32>,
    tool_measured: Vector3<f32>,
    tool_yaw_measured: f32,
    counters: PickCounters,
    view: ViewMonitor,
    /// The flange's position measured through the joint encoders.
    flange_measured: Vector3<f32>,
    /// The gripper's part-present switch at the last sample.
    part_in_gripper: bool,
    /// Joint speeds from the encoders alone, for the speed supervisor.
    speed_window: JointSpeedWindow,
    /// Engaged when the task-space stop cannot be trusted; then for good.
    brake: Option<JointBrake>,
    /// When Eq 23's integral was last cleared (a stall).
    integral_reset_s: f32,
    /// The last period's command: the answer to a sample sent again because
    /// the host lost its command on a noisy link (lock step).
    last_command: Option<ActuatorCommand>,
    /// Frames the link's decoder refused, for telemetry (set by the link's owner).
    link_frames_rejected: u32,
    /// The worst `|J^+ Yd_dot| / limit` over the joints at the last period.
    reference_speed_ratio: f32,
    /// Intercepts planned for the part so far.
    intercept_attempts: u8,
    /// Where the arm stood when the part was first located (the last
    /// calibration pose): an abandoned intercept returns there to plan again.
    locate_pose: Option<ArcPoint<f32>>,
    /// The lowest flange height known to be clear: where the arm started,
    /// until the camera has seen the marks; then the lowest height at which
    /// it saw them.
    known_clear_flange_z: f32,
    seen_marks: bool,
    /// The final calibration was accepted (the pick may go down to the part).
    calibration_accepted: bool,
}

/// Eq 23's gains for the pick (see [`ControllerConfig::puma560`]).
fn controller_config() -> Result<ControllerConfig<f32>, ConfigError> {
    ControllerConfig::puma560().map_err(|_| ConfigError {
        field: "controller gains",
    })
}

/// The pick's three parts for one cell configuration.
#[derive(Debug, Clone)]
pub struct PickParts {
    pub control: PickController,
    pub pairer: FramePairer,
    pub worker: PickWorker,
}

impl PickParts {
    /// The parts for the cell `config`, with the pick's default settings.
    /// `session` tells this configuration's job results from an older one's.
    pub fn new(config: &CellConfig, session: u32) -> Result<Self, ConfigError> {
        Self::with_settings(config, PickSettings::default(), session)
    }

    pub fn with_settings(
        config: &CellConfig,
        settings: PickSettings,
        session: u32,
    ) -> Result<Self, ConfigError> {
        Ok(Self {
            control: PickController::new(config, settings, session)?,
            pairer: FramePairer::for_config(config),
            worker: PickWorker::new(config, settings)?,
        })
    }
}

/// The controller's dynamic model for Eq 23 (and for the planner's torque
/// check): the nominal PUMA 560 with armature and smoothed friction, in `f32`.
fn controller_model() -> Result<Puma560<f32>, ConfigError> {
    Ok(Puma560::<f64>::new()
        .with_drive(DriveOptions {
            armature: true,
            friction: true,
        })
        .try_with_coulomb_smoothing(SIMULATOR_COULOMB_WIDTH)
        .map_err(|_| ConfigError {
            field: "controller model",
        })?
        .cast::<f32>())
}

/// `previous`'s dynamic model, or a new one. Out of line: with the choice
/// inlined, the firmware's build of [`PickController::replacing`] held two
/// copies of the controller's construction (4 KB more flash).
#[inline(never)]
fn model_of(previous: Option<&PickController>) -> Result<Puma560<f32>, ConfigError> {
    match previous {
        Some(previous) => Ok(previous.model),
        None => controller_model(),
    }
}

impl PickController {
    /// The control loop for the cell `config`; `session` tells this
    /// configuration's job results from an older one's.
    pub fn new(
        config: &CellConfig,
        settings: PickSettings,
        session: u32,
    ) -> Result<Self, ConfigError> {
        Self::replacing(None, config, settings, session)
    }

    /// The control loop for the cell `config`, as [`PickController::new`]
    /// makes it, with `previous`'s dynamic model if there is one (no
    /// configuration changes the model): the firmware reconfigures this way so
    /// that building the model (`controller_model` and `Puma560::new`, 7.6 KB
    /// of stack) is not on the control loop's stack while the worker may be
    /// deep in a job.
    pub fn replacing(
        previous: Option<&PickController>,
        config: &CellConfig,
        settings: PickSettings,
        session: u32,
    ) -> Result<Self, ConfigError> {
        let cell = Cell::new(config)?;
        let conveyor = ConveyorFilter::new(config.conveyor_counts_per_rev, cell.counter_width, 1.0)
            .map_err(|_| ConfigError {
                field: "conveyor_counts_per_rev",
            })?;
        let model = model_of(previous)?;
        let controller =
            TaskSpaceController::new(controller_config()?).map_err(|_| ConfigError {
                field: "controller gains",
            })?;
        let rest = TaskState::at_rest(Vector3::zeros(), 0.0);
        Ok(PickController {
            cell,
            settings,
            model,
            controller,
            observer: JointObserver::new(150.0, 0.05),
            conveyor,
            conveyor_state: None,
            session,
            next_job_id: 1,
            outbox: Deque::new(),
            start_time_us: None,
            last_time_us: 0,
            now_s: 0.0,
            ticks: 0,
            next_trigger_s: 0.0,
            next_trigger_id: 1,
            last_paired_s: 0.0,
            step: Step::Start,
            step_started_s: 0.0,
            motion: Motion::Hold(rest),
            reference: rest,
            gripper: GripperCommand::Open,
            fault: None,
            start_pose: ArcPoint {
                radius_m: 0.0,
                azimuth_rad: 0.0,
                z_m: 0.0,
                yaw_rad: 0.0,
            },
            estimate: None,
            poses: Vec::new(),
            job: None,
            next_plan_attempt_s: 0.0,
            transfer_z: 0.0,
            sighting_direction: [0.0; 2],
            calibration_rounds: 0,
            estimate_serial: 0,
            qdd_commanded: JointVector::zeros(),
            tool_measured: Vector3::zeros(),
            tool_yaw_measured: 0.0,
            counters: PickCounters::default(),
            view: ViewMonitor::new(ViewLimits {
                residual_px: settings.view_residual_px,
                strikes: settings.view_strikes,
                slip_tolerance_m: settings.slip_tolerance_m,
                pixel_sigma_px: config.pixel_sigma_px,
            }),
            flange_measured: Vector3::zeros(),
            part_in_gripper: false,
            speed_window: JointSpeedWindow::new(),
            brake: None,
            integral_reset_s: 0.0,
            last_command: None,
            link_frames_rejected: 0,
            reference_speed_ratio: 0.0,
            intercept_attempts: 0,
            locate_pose: None,
            known_clear_flange_z: f32::INFINITY,
            seen_marks: false,
            calibration_accepted: false,
        })
    }

    pub fn phase(&self) -> PickPhase {
        self.step.phase()
    }

    pub fn fault(&self) -> Option<FaultCause> {
        self.fault
    }

    /// The gripper is commanded closed or its switch saw a part at the last
    /// sample: a new configuration would open it
    /// (`crate::safety::reconfigure`).
    pub fn gripper_holds(&self) -> bool {
        self.gripper == GripperCommand::Close || self.part_in_gripper
    }

    pub fn estimate(&self) -> Option<&CellEstimate> {
        self.estimate.as_ref()
    }

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
                self.last_paired_s = self.now_s;
                if let (Some(view), true) = (view, self.step.watches_view()) {
                    if let Some(cause) = self.view.check(view) {
                        self.raise(cause);
                    }
                }
                if let Some(sighting) = sighting {
                    self.on_sighting(sighting);
                }
            }
            VisionNews::Unpaired => {
                self.counters.frames_unpaired = self.counters.frames_unpaired.saturating_add(1);
            }
            VisionNews::Refused => {
                self.counters.frames_refused = self.counters.frames_refused.saturating_add(1);
            }
            VisionNews::Result(result) => self.on_result(result),
        }
    }

    /// The camera saw the marks: the disc is that way round the base axis,
    /// and the flange has been this low in the camera's view.
    fn on_sighting(&mut self, sighting: &Sighting) {
        self.counters.effector_sightings = self.counters.effector_sightings.saturating_add(1);
        let [x, y] = sighting.direction_xy;
        let [sx, sy] = self.sighting_direction;
        self.sighting_direction = [sx + x, sy + y];
        // The marks sit MARK_BELOW_FLANGE_M under the flange, gripper down.
        let flange_z = sighting.mark_z_m + MARK_BELOW_FLANGE_M;
        if flange_z.is_finite() {
            if !self.seen_marks || flange_z < self.known_clear_flange_z {
                self.known_clear_flange_z = flange_z;
            }
            self.seen_marks = true;
        }
    }

    /// The lowest flange height a motion may go to before the calibration
    /// is accepted (`PickSettings::max_descent_step_m` below the known-clear height).
    fn safe_floor_z(&self) -> f32 {
        self.known_clear_flange_z - self.settings.max_descent_step_m
    }

    fn on_result(&mut self, result: &JobResult) {
        if result.session != self.session {
            return;
        }
        let Some(job) = self.job.as_mut() else {
            return;
        };
        if job.job_id != result.job_id || job.outcome.is_some() {
            return;
        }
        if self.now_s > job.apply_at_s {
            self.counters.late_results = self.counters.late_results.saturating_add(1);
        }
        job.outcome = Some(result.outcome.clone());
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
        self.trigger_due_at(micros_to_seconds(time_us.saturating_sub(start_us)))
    }

    /// The one trigger rule, for [`Self::camera_trigger_due`] and the period.
    fn trigger_due_at(&self, now_s: f32) -> bool {
        now_s + 1e-6 >= self.next_trigger_s
    }

    /// True when the sample at `time_us` is due to apply a job's result that
    /// has not come yet. A lock-step caller (the emulated board) waits for the
    /// worker before such a sample, so the run is the same at any speed; a
    /// real-time caller does not, and the result is applied late.
    pub fn awaits_result(&self, time_us: u64) -> bool {
        let Some(job) = self.job.as_ref() else {
            return false;
        };
        let now_s = match self.start_time_us {
            Some(start) => time_us.saturating_sub(start) as f32 * 1e-6,
            None => 0.0,
        };
        job.outcome.is_none() && now_s >= job.apply_at_s
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

    fn run_period(
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
        let stalled = dt_s > self.settings.stall_limit_s;
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
            Ok(state) => self.conveyor_state = Some(state),
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
        let x_axis = flange.rotation * Vector3::x();
        self.tool_yaw_measured = libm::atan2f(x_axis.y, x_axis.x);

        if stalled {
            self.on_stall(&flange);
        }

        let camera_trigger = self.camera_trigger(sample, &q_measured);
        if self.step == Step::Start {
            self.begin(&flange);
        }
        self.advance();
        if self.step.needs_vision()
            && self.now_s - self.last_paired_s > self.settings.vision_stale_s
        {
            self.raise(FaultCause::VisionStale);
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
        // A motion's reference moves continuously; a leap (a phase handing over
        // to a motion that starts elsewhere) would be a step Eq 23 answers with
        // saturated torques. Refuse it and stop from the last good reference.
        let guarded = !stalled && !matches!(self.step, Step::Stopping | Step::Faulted);
        if guarded && self.ticks > 1 && self.reference_leaps(&reference, dt_s) {
            self.raise(FaultCause::ReferenceJump);
        } else {
            self.reference = reference;
        }

        if let Some(qd) = encoder_speed {
            self.supervise_speed(&qd);
        }
        self.guard_reach();
        self.guard_intercept(part.as_ref());
        self.guard_height();
        let tau = self.control(
            &q,
            &q_measured,
            encoder_speed.as_ref(),
            (&configuration, &kinematics),
            dt_s,
        );
        self.emit_telemetry(&part, out);
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
            self.step == Step::Faulted && self.now_s - settled_since > self.settings.hold_settle_s,
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
        self.guard_reference_speed(&output.reference_joint_speed);
        if output.saturated {
            self.counters.saturated_ticks = self.counters.saturated_ticks.saturating_add(1);
        }
        self.qdd_commanded = if output.qdd.iter().all(|x| x.is_finite()) {
            output.qdd
        } else {
            JointVector::zeros()
        };
        let error = output.position_error.norm();
        if error > self.settings.tracking_error_limit_m {
            // A stop that lags its own path this far is not converging.
            let stopping = matches!(self.step, Step::Stopping | Step::Faulted);
            if stopping && error > 2.0 * self.settings.tracking_error_limit_m {
                self.engage_brake();
            }
            self.raise(FaultCause::TrackingError);
        }
        let mut tau = [0.0_f32; 6];
        for (t, value) in tau.iter_mut().zip(output.tau.iter()) {
            *t = *value;
        }
        tau
    }

    /// Fires the camera every period and latches the encoders with the trigger.
    fn camera_trigger(&mut self, sample: &SensorSample, q: &JointVector<f32>) -> Option<u32> {
        if !self.trigger_due_at(self.now_s) {
            return None;
        }
        let period_s = f32::from(self.cell.config.camera_period_ms) * 1e-3;
        self.next_trigger_s += period_s;
        if self.next_trigger_s <= self.now_s {
            self.next_trigger_s = self.now_s + period_s;
        }
        let trigger_id = self.next_trigger_id;
        self.next_trigger_id = self.next_trigger_id.wrapping_add(1);
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
            feeds_calibrator: self.step.part_on_disc()
                && !matches!(self.step, Step::Stopping | Step::Faulted),
        };
        self.post(ControlEvent::Trigger(record));
        Some(trigger_id)
    }

    /// The grasp point's live state (Eq 1 with the conveyor filter), once calibrated.
    fn part_now(&self) -> Option<TaskState<f32>> {
        let estimate = self.estimate.as_ref()?;
        let state = self.conveyor_state?;
        Some(estimate.grasp_point(state.theta_wrapped, state.omega, state.alpha))
    }

    /// The first sample: remember where the arm starts and hold it there.
    fn begin(&mut self, flange: &nalgebra::Isometry3<f32>) {
        let x_axis = flange.rotation * Vector3::x();
        let yaw = libm::atan2f(x_axis.y, x_axis.x);
        let position = flange.translation.vector;
        self.start_pose = ArcPoint::from_position(&position, yaw);
        self.reference = TaskState::at_rest(position, yaw);
        self.motion = Motion::Hold(self.reference);
        self.last_paired_s = self.now_s;
        if !self.seen_marks {
            // Until the camera has seen the marks: where the arm stands, or
            // the travel height (declared clear of any disc and part) if lower.
            let travel_z = self.settings.search_tool_height_m + TOOL_LENGTH_M as f32;
            self.known_clear_flange_z = position.z.min(travel_z);
        }
        self.enter(Step::SearchApproach);
    }

    /// A fault the board's supervisor found (link lost, a board error): the
    /// same controlled stop as the pick's own faults (decelerate, then hold),
    /// reported with its cause. Nothing happens if the pick already stopped.
    pub fn stop(&mut self, cause: FaultCause) {
        self.raise(cause);
    }

    /// A job request could not be handed to the worker (its queue was full):
    /// its result would never come, so stop rather than wait.
    pub fn on_job_lost(&mut self) {
        self.raise(FaultCause::Timeout);
    }

    /// Periods did not come for longer than the stall limit. The arm is where
    /// the drives' watchdog left it, not where the plan says: stop from there
    /// (a controlled stop from rest, rising clear of the part when near it).
    fn on_stall(&mut self, flange: &nalgebra::Isometry3<f32>) {
        self.counters.stalls = self.counters.stalls.saturating_add(1);
        self.reference = TaskState::at_rest(flange.translation.vector, self.tool_yaw_measured);
        self.controller.reset();
        self.integral_reset_s = self.now_s;
        match self.step {
            Step::Start | Step::Done | Step::Faulted => self.hold_here(),
            Step::Stopping => self.enter(Step::Faulted),
            _ => self.raise(FaultCause::ControlStall),
        }
    }

    /// Whether `next` is further from the present reference than the pick's
    /// fastest motion goes in `dt_s` (with a margin).
    fn reference_leaps(&self, next: &TaskState<f32>, dt_s: f32) -> bool {
        let settings = self.settings;
        let step = (next.position - self.reference.position).norm();
        let turn = libm::fabsf(wrap_pi(next.yaw - self.reference.yaw));
        !at_most(
            step,
            settings.stop_max_speed_m_s * dt_s + settings.reference_step_m,
        ) || !at_most(
            turn,
            settings.stop_max_yaw_rate_rad_s * dt_s + settings.reference_step_rad,
        )
    }

    /// Joint speeds (from the encoders) against the limits: near a limit the
    /// pick stops along its path; well over it (the stop is not slowing the
    /// arm) the joint brake takes over.
    fn supervise_speed(&mut self, qd: &JointVector<f32>) {
        let settings = self.settings;
        let worst = qd
            .iter()
            .zip(self.model.joint_limits().velocity_max.iter())
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
            );
        if !at_most(worst, settings.overspeed_brake_factor) {
            self.raise(FaultCause::JointOverspeed);
            self.engage_brake();
        } else if !at_most(worst, settings.overspeed_stop_factor) {
            self.raise(FaultCause::JointOverspeed);
        }
    }

    /// While the arm follows the part, the part must stay where the arm can
    /// reach it gripper-down (a reversed or runaway disc carries it off):
    /// chasing it out of reach drives the arm into its singularities.
    fn guard_reach(&mut self) {
        let following = matches!(
            self.step,
            Step::Intercept | Step::Track | Step::Descend | Step::GraspSettle | Step::GraspClose
        );
        if !following {
            return;
        }
        let position = self.reference.position;
        let radius = position.xy().norm();
        let reachable = within_stretch(&self.model, &position, self.settings.max_follow_stretch)
            && radius >= self.settings.min_follow_radius_m;
        if !reachable {
            self.raise(FaultCause::PartUnreachable);
        }
    }

    /// No reference may ask a joint for more than its speed limit: the plans
    /// check their paths, but the live parts of a reference (the intercept's
    /// correction, following the part) are checked here, every period, at
    /// the measured configuration. A stop or an abandoned intercept is
    /// exempt: it slows the arm from a start scaled within the limits.
    fn guard_reference_speed(&mut self, qd_reference: &JointVector<f32>) {
        let ratio = qd_reference
            .iter()
            .zip(self.model.joint_limits().velocity_max.iter())
            .map(|(v, max)| v.abs() / *max)
            .fold(
                0.0_f32,
                |worst, r| if at_most(r, worst) { worst } else { r },
            );
        self.reference_speed_ratio = ratio;
        let decelerating = matches!(
            self.step,
            Step::Stopping | Step::Faulted | Step::InterceptAbandoned
        );
        if !decelerating && !at_most(ratio, self.settings.reference_speed_factor) {
            self.raise(FaultCause::JointOverspeed);
        }
    }

    /// The intercept's live correction absorbs small departures of the part
    /// from the plan's prediction; a conveyor that stopped, sped up or
    /// reversed under the plan takes the part where the plan never checked
    /// reach or joint speeds: abandon the intercept and plan again.
    fn guard_intercept(&mut self, part: Option<&TaskState<f32>>) {
        let (
            Step::Intercept,
            Motion::Intercept {
                start_s,
                prediction,
                ..
            },
        ) = (self.step, self.motion)
        else {
            return;
        };
        let (Some(live), Some(estimate)) = (part, self.estimate.as_ref()) else {
            return;
        };
        let t = self.now_s - start_s;
        let assumed = estimate.grasp_point(
            prediction.theta_at_start + prediction.omega * t,
            prediction.omega,
            0.0,
        );
        let settings = self.settings;
        let moved = (live.position - assumed.position).norm();
        let omega_now = self.conveyor_state.map_or(prediction.omega, |c| c.omega);
        let speed_change = libm::fabsf(omega_now - prediction.omega);
        let changed = !at_most(
            speed_change,
            settings
                .max_conveyor_speed_change_rad_s
                .max(settings.max_conveyor_speed_change_fraction * libm::fabsf(prediction.omega)),
        );
        if at_most(moved, settings.max_intercept_correction_m) && !changed {
            return;
        }
        if self.intercept_attempts >= settings.max_intercept_attempts {
            self.raise(FaultCause::PartUnreachable);
        } else {
            self.enter(Step::InterceptAbandoned);
        }
    }

    /// Before the calibration is accepted, nothing goes more than
    /// `max_descent_step_m` below the known-clear height (see
    /// [`Self::safe_floor_z`]), whatever the estimate says.
    fn guard_height(&mut self) {
        let before_acceptance = !self.calibration_accepted
            && !matches!(
                self.step,
                Step::Start | Step::Stopping | Step::Faulted | Step::Done
            );
        // A centimetre for the arcs' rounding between two admitted heights.
        if before_acceptance && self.reference.position.z < self.safe_floor_z() - 0.01 {
            self.raise(FaultCause::BelowSafeHeight);
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
        self.job = None;
        self.step = Step::Faulted;
        self.step_started_s = self.now_s;
    }

    fn raise(&mut self, cause: FaultCause) {
        if matches!(self.step, Step::Stopping | Step::Faulted) {
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
        self.job = None;
        self.enter(Step::Stopping);
    }

    /// An azimuth equivalent to `azimuth` within half a turn of the start's, so
    /// arcs never swing the waist through the back of the robot.
    fn azimuth_near_start(&self, azimuth: f32) -> f32 {
        self.start_pose.azimuth_rad + wrap_pi(azimuth - self.start_pose.azimuth_rad)
    }

    /// An arc from the present reference (at rest) to `target`.
    fn arc_to(&mut self, target: ArcPoint<f32>) -> Result<Motion, PlanError> {
        let mut from = ArcPoint::from_position(&self.reference.position, self.reference.yaw);
        from.azimuth_rad = self.azimuth_near_start(from.azimuth_rad);
        let path = ArcMove::new(&from, &target, &ArcLimits::default())?;
        Ok(Motion::Arc {
            path,
            start_s: self.now_s,
        })
    }

    /// The flange arc point over `tool` (a grasp-point position), wrist as at the start.
    fn arc_point_over(&self, tool: &Vector3<f32>, z_flange: f32) -> ArcPoint<f32> {
        let mut point = ArcPoint::from_position(tool, 0.0);
        point.azimuth_rad = self.azimuth_near_start(point.azimuth_rad);
        point.yaw_rad = yaw_at_azimuth(&self.start_pose, point.azimuth_rad);
        point.z_m = z_flange;
        point
    }

    fn request(&mut self, request: JobRequest, budget_s: f32) {
        let job_id = self.next_job_id;
        self.next_job_id = self.next_job_id.wrapping_add(1);
        self.job = Some(Job {
            job_id,
            outcome: None,
            apply_at_s: self.now_s + budget_s,
        });
        self.post(ControlEvent::Job(JobTicket {
            session: self.session,
            job_id,
            request,
        }));
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

    /// The job's outcome once its delay has passed.
    fn take_outcome(&mut self) -> Option<JobOutcome> {
        let ready = self
            .job
            .as_ref()
            .is_some_and(|job| job.outcome.is_some() && self.now_s >= job.apply_at_s);
        if ready {
            self.job.take().and_then(|job| job.outcome)
        } else {
            None
        }
    }

    fn hold_here(&mut self) {
        self.motion = Motion::Hold(TaskState::at_rest(
            self.reference.position,
            self.reference.yaw,
        ));
    }

    /// Where a controlled stop starts: the reference, unless the arm is not
    /// following it (then where the arm is), with its speeds capped to what
    /// the pick ever commands, so a corrupt estimate cannot fling the stop.
    fn stop_start(&self) -> TaskState<f32> {
        let settings = self.settings;
        let mut start = self.reference;
        let lag = (start.position - self.flange_measured).norm();
        if !at_most(lag, settings.tracking_error_limit_m) {
            start = TaskState::at_rest(self.flange_measured, self.tool_yaw_measured);
        }
        // A reference that asked a joint for more than its limit: the stop
        // starts from a speed scaled back within the limits.
        let ratio = self.reference_speed_ratio;
        let within = 0.9 * settings.reference_speed_factor;
        if !at_most(ratio, within) {
            let scale = if ratio.is_finite() {
                within / ratio
            } else {
                0.0
            };
            start.velocity *= scale;
            start.yaw_rate *= scale;
            start.acceleration = Vector3::zeros();
            start.yaw_acceleration = 0.0;
        }
        let speed = start.velocity.norm();
        if !at_most(speed, settings.stop_max_speed_m_s) {
            start.velocity = if speed.is_finite() {
                start.velocity * (settings.stop_max_speed_m_s / speed)
            } else {
                Vector3::zeros()
            };
        }
        if !at_most(start.yaw_rate.abs(), settings.stop_max_yaw_rate_rad_s) {
            start.yaw_rate = 0.0;
        }
        if !at_most(
            start.acceleration.norm(),
            settings.stop_max_acceleration_m_s2,
        ) {
            start.acceleration = Vector3::zeros();
        }
        if !start.yaw_acceleration.is_finite() {
            start.yaw_acceleration = 0.0;
        }
        start
    }

    /// Enters `step`, setting the motion it starts with.
    fn enter(&mut self, step: Step) {
        self.step = step;
        self.step_started_s = self.now_s;
        let settings = self.settings;
        let travel_z = settings.search_tool_height_m + TOOL_LENGTH_M as f32;
        let motion = match step {
            Step::Start | Step::Done | Step::Faulted => {
                self.hold_here();
                return;
            }
            Step::SearchApproach | Step::SearchSweep => {
                let side = if step == Step::SearchApproach {
                    -1.0
                } else {
                    1.0
                };
                let azimuth = self.start_pose.azimuth_rad + side * settings.search_half_sweep_rad;
                self.arc_to(ArcPoint {
                    radius_m: settings.search_radius_m,
                    azimuth_rad: azimuth,
                    z_m: travel_z,
                    yaw_rad: yaw_at_azimuth(&self.start_pose, azimuth),
                })
            }
            Step::SearchReturn => {
                // Back to where the marks were seen: over the disc, near the part.
                let [sx, sy] = self.sighting_direction;
                let azimuth = self.azimuth_near_start(libm::atan2f(sy, sx));
                self.arc_to(ArcPoint {
                    radius_m: settings.search_radius_m,
                    azimuth_rad: azimuth,
                    z_m: travel_z,
                    yaw_rad: yaw_at_azimuth(&self.start_pose, azimuth),
                })
            }
            Step::EstimatePreliminary | Step::EstimateFinal => {
                self.hold_here();
                let preliminary = step == Step::EstimatePreliminary;
                let request = JobRequest::Estimate {
                    preliminary,
                    time_us: self.last_time_us,
                    start_pose: self.start_pose,
                    q_now: self.observer.q(),
                };
                self.request(request, settings.estimate_budget_s);
                return;
            }
            Step::CalibrateMove(i) => match self.poses.get(usize::from(i)).copied() {
                Some(target) if target.z_m < self.safe_floor_z() => {
                    // Not yet confirmed by a sighting from above (the marks
                    // were not seen at the pose before): skip it.
                    self.enter(Step::CalibrateMove(i.saturating_add(1)));
                    return;
                }
                Some(mut target) => {
                    target.azimuth_rad = self.azimuth_near_start(target.azimuth_rad);
                    self.arc_to(target)
                }
                None => {
                    self.enter(Step::EstimateFinal);
                    return;
                }
            },
            Step::CalibrateDwell(_) | Step::Locate | Step::Release => {
                if step == Step::Locate {
                    // A fresh look for a steady conveyor and a new plan.
                    self.next_plan_attempt_s = self.now_s;
                    if self.locate_pose.is_none() {
                        self.locate_pose = Some(ArcPoint::from_position(
                            &self.reference.position,
                            self.reference.yaw,
                        ));
                    }
                }
                self.hold_here();
                if step == Step::Release {
                    self.gripper = GripperCommand::Open;
                }
                return;
            }
            Step::Intercept => return,
            Step::Relocate => match self.locate_pose {
                Some(mut target) => {
                    target.azimuth_rad = self.azimuth_near_start(target.azimuth_rad);
                    self.arc_to(target)
                }
                None => {
                    self.enter(Step::Locate);
                    return;
                }
            },
            Step::Track | Step::Descend | Step::GraspSettle => {
                let (from, to, duration) = match step {
                    Step::Descend => (settings.hover_height_m, 0.0, settings.descend_s),
                    Step::Track => (settings.hover_height_m, settings.hover_height_m, 1.0),
                    _ => (0.0, 0.0, 1.0),
                };
                match height_profile(from, to, duration) {
                    Some(offset) => Ok(Motion::Follow {
                        offset,
                        start_s: self.now_s,
                    }),
                    None => Err(PlanError::InvalidDuration),
                }
            }
            Step::GraspClose => {
                self.gripper = GripperCommand::Close;
                return;
            }
            Step::Lift => {
                let start = self.reference;
                let mut end = TaskState::at_rest(
                    start.position
                        + start.velocity * (0.5 * settings.lift_s)
                        + Vector3::new(0.0, 0.0, settings.lift_height_m),
                    start.yaw,
                );
                end.yaw = start.yaw + start.yaw_rate * (0.5 * settings.lift_s);
                InterceptPlan::between(&start, &end, settings.lift_s, core::f32::consts::PI).map(
                    |path| Motion::Quintic {
                        path,
                        start_s: self.now_s,
                    },
                )
            }
            Step::PlaceTransfer => {
                let drop_hover_z =
                    self.cell.drop_off_base.z + TOOL_LENGTH_M as f32 + settings.drop_hover_m;
                self.transfer_z = self.reference.position.z.max(drop_hover_z);
                let target = self.arc_point_over(&self.cell.drop_off_base.clone(), self.transfer_z);
                self.arc_to(target)
            }
            Step::PlaceLower => {
                let z = self.cell.drop_off_base.z + TOOL_LENGTH_M as f32;
                let target = self.arc_point_over(&self.cell.drop_off_base.clone(), z);
                self.arc_to(target)
            }
            Step::ReturnRaise => {
                let target = self.arc_point_over(&self.cell.drop_off_base.clone(), self.transfer_z);
                self.arc_to(target)
            }
            Step::ReturnTransfer => {
                let mut target = self.start_pose;
                target.azimuth_rad = self.azimuth_near_start(target.azimuth_rad);
                self.arc_to(target)
            }
            Step::Stopping | Step::InterceptAbandoned => self.decelerate(),
        };
        match motion {
            Ok(motion) => self.motion = motion,
            // No task-space stop could be planned: the joint brake stops the
            // arm instead. (Holding the reference here would leave the pick
            // in `Stopping` for good: a hold never finishes.)
            Err(_) if matches!(step, Step::Stopping | Step::InterceptAbandoned) => {
                self.engage_brake()
            }
            Err(_) => self.raise(FaultCause::PartUnreachable),
        }
    }

    /// To rest over `stop_s` from the present reference (its speeds capped:
    /// [`Self::stop_start`]), rising clear of the part when near it, and
    /// never ending lower than it starts before the calibration is accepted.
    fn decelerate(&self) -> Result<Motion, PlanError> {
        let settings = self.settings;
        let start = self.stop_start();
        let near_part = matches!(
            self.motion,
            Motion::Follow { .. } | Motion::Intercept { .. }
        );
        let rise = if near_part { settings.stop_rise_m } else { 0.0 };
        let mut end = TaskState::at_rest(
            start.position
                + start.velocity * (0.5 * settings.stop_s)
                + Vector3::new(0.0, 0.0, rise),
            start.yaw + start.yaw_rate * (0.5 * settings.stop_s),
        );
        if !self.calibration_accepted && end.position.z < start.position.z {
            end.position.z = start.position.z;
        }
        if !within_reach(&self.model, &end.position) {
            end.position = start.position;
        }
        InterceptPlan::between(&start, &end, settings.stop_s, core::f32::consts::PI).map(|path| {
            Motion::Quintic {
                path,
                start_s: self.now_s,
            }
        })
    }

    /// Transitions of the state machine at this tick.
    fn advance(&mut self) {
        let now = self.now_s;
        let in_step = now - self.step_started_s;
        let finished = self.motion.finished(now);
        let settings = self.settings;
        match self.step {
            Step::Start | Step::Done | Step::Faulted => {}
            Step::SearchApproach if finished => self.enter(Step::SearchSweep),
            Step::SearchSweep if finished => {
                if self.counters.effector_sightings < settings.min_effector_sightings {
                    self.raise(FaultCause::EffectorNotSeen);
                } else {
                    self.enter(Step::SearchReturn);
                }
            }
            Step::SearchReturn if finished => self.enter(Step::EstimatePreliminary),
            Step::EstimatePreliminary | Step::EstimateFinal => self.on_estimate(in_step),
            Step::CalibrateMove(i) if finished => self.enter(Step::CalibrateDwell(i)),
            Step::CalibrateDwell(i) if in_step >= settings.calibration_dwell_s => {
                self.enter(Step::CalibrateMove(i.saturating_add(1)))
            }
            Step::Locate => self.locate(in_step),
            Step::Intercept if finished => self.enter(Step::Track),
            Step::InterceptAbandoned if finished => self.enter(Step::Relocate),
            Step::Relocate if finished => self.enter(Step::Locate),
            Step::Track => {
                let error = (self.tool_measured
                    - (self.reference.position - Vector3::new(0.0, 0.0, TOOL_LENGTH_M as f32)))
                .norm();
                if in_step >= settings.track_settle_s && error <= settings.track_tolerance_m {
                    self.enter(Step::Descend);
                } else if in_step >= settings.track_timeout_s {
                    self.raise(FaultCause::TrackingError);
                }
            }
            Step::Descend if in_step >= settings.descend_s => self.enter(Step::GraspSettle),
            Step::GraspSettle if in_step >= settings.grasp_settle_s => self.enter(Step::GraspClose),
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

    fn on_estimate(&mut self, in_step: f32) {
        let preliminary = self.step == Step::EstimatePreliminary;
        match self.take_outcome() {
            Some(JobOutcome::Estimate(Ok((estimate, poses)))) => {
                self.estimate = Some(estimate);
                self.estimate_serial = self.estimate_serial.wrapping_add(1);
                let unsure = estimate.report.sigma_base_m > self.settings.confident_base_sigma_m;
                if preliminary {
                    self.poses = poses;
                    self.calibration_rounds = 1;
                    self.enter(Step::CalibrateMove(0));
                } else if unsure
                    && self.calibration_rounds < self.settings.max_calibration_rounds
                    && !self.poses.is_empty()
                {
                    // Not sure enough of the base yet: show the marks again (the
                    // poses in reverse, so the arm does not travel back first).
                    self.calibration_rounds = self.calibration_rounds.saturating_add(1);
                    self.poses.reverse();
                    self.enter(Step::CalibrateMove(0));
                } else {
                    self.calibration_accepted = true;
                    self.view.arm(
                        &estimate,
                        &self.cell.log_header().camera,
                        self.cell.config.reference_radius_m,
                    );
                    self.enter(Step::Locate);
                }
            }
            Some(JobOutcome::Estimate(Err(cause))) => self.raise(cause),
            Some(JobOutcome::Plan(_)) => self.raise(FaultCause::Timeout),
            None if in_step > 4.0 * self.settings.estimate_budget_s + 1.0 => {
                self.raise(FaultCause::Timeout)
            }
            None => {}
        }
    }

    /// Waits for a steady conveyor, asks for an intercept, and starts it.
    fn locate(&mut self, in_step: f32) {
        match self.take_outcome() {
            Some(JobOutcome::Plan(Ok((plan, prediction)))) => {
                self.intercept_attempts = self.intercept_attempts.saturating_add(1);
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
        let steady = state.alpha.abs() <= self.settings.steady_alpha_rad_s2;
        let Some(estimate) = self.estimate else {
            // Locate is only entered with an estimate; never plan without one.
            self.raise(FaultCause::CalibrationFailed);
            return;
        };
        if self.job.is_none() && steady && self.now_s >= self.next_plan_attempt_s {
            let start = TaskState::at_rest(self.reference.position, self.reference.yaw);
            let request = JobRequest::Plan {
                start,
                q_start: self.observer.q(),
                conveyor: ConveyorSnapshot {
                    theta: state.theta_wrapped,
                    omega: state.omega,
                    lead_s: self.settings.plan_budget_s,
                },
                estimate,
            };
            self.request(request, self.settings.plan_budget_s);
        }
    }

    fn emit_telemetry(
        &self,
        part: &Option<TaskState<f32>>,
        out: &mut Vec<Message, MAX_TICK_MESSAGES>,
    ) {
        let period = u64::from(self.cell.config.telemetry_period_ticks);
        if period == 0 || !(self.ticks - 1).is_multiple_of(period) {
            return;
        }
        let state = self.conveyor_state;
        let tool_reference = self.reference.position - Vector3::new(0.0, 0.0, TOOL_LENGTH_M as f32);
        let telemetry = PickTelemetry {
            time_us: self.last_time_us,
            phase: self.phase(),
            fault: self.fault,
            theta_rad: state.map_or(0.0, |s| s.theta_wrapped),
            omega_rad_s: state.map_or(0.0, |s| s.omega),
            sigma_theta_rad: state.map_or(0.0, |s| s.sigma_theta()),
            sigma_omega_rad_s: state.map_or(0.0, |s| s.sigma_omega()),
            part_base_m: part.map(|p| [p.position.x, p.position.y, p.position.z]),
            part_yaw_base_rad: part.map_or(0.0, |p| p.yaw),
            part_velocity_base_m_s: part
                .map_or([0.0; 3], |p| [p.velocity.x, p.velocity.y, p.velocity.z]),
            part_sigma_m: self.estimate.map_or(0.0, |e| e.report.sigma_part_m),
            tool_base_m: [
                self.tool_measured.x,
                self.tool_measured.y,
                self.tool_measured.z,
            ],
            tool_reference_base_m: [tool_reference.x, tool_reference.y, tool_reference.z],
            tool_yaw_rad: self.tool_yaw_measured,
            tool_reference_yaw_rad: wrap_pi(self.reference.yaw),
            frames_paired: self.counters.frames_paired,
            frames_unpaired: self.counters.frames_unpaired,
            saturated_ticks: self.counters.saturated_ticks,
            frames_rejected: self.link_frames_rejected,
        };
        // The outbox holds MAX_TICK_MESSAGES; telemetry is dropped, never the command.
        let _ = out.push(Message::Telemetry(telemetry));
    }

    /// The latest calibration report and its serial number (one more per estimate).
    pub fn calibration_report(&self) -> Option<(u32, crate::protocol::CalibrationReport)> {
        self.estimate
            .as_ref()
            .map(|e| (self.estimate_serial, e.report))
    }

    /// The serial of the estimate in use (changes with each new estimate).
    pub fn estimate_serial(&self) -> Option<u32> {
        self.estimate.as_ref().map(|_| self.estimate_serial)
    }

    /// The commanded twist's norm, for tests.
    pub fn reference(&self) -> TaskState<f32> {
        self.reference
    }

    #[doc(hidden)]
    pub fn twist_norm(&self) -> f32 {
        let twist: Vector6<f32> = self.reference.twist();
        twist.norm()
    }
}

#[cfg(test)]
mod trigger_due_tests;

#[cfg(test)]
mod tests {
    use super::*;

    fn config(conveyor_counts_per_rev: u32, part_feature_count: u8) -> CellConfig {
        crate::test_cell::test_cell_config(conveyor_counts_per_rev, part_feature_count)
    }

    #[test]
    fn a_controller_replacing_another_is_a_new_controller() {
        let settings = PickSettings::default();
        let first = PickController::new(&config(4096, 4), settings, 1)
            .unwrap_or_else(|e| panic!("{}", e.field));
        let next = config(2048, 3);
        let reconfigured = PickController::replacing(Some(&first), &next, settings, 2)
            .unwrap_or_else(|e| panic!("{}", e.field));
        let new = PickController::new(&next, settings, 2).unwrap_or_else(|e| panic!("{}", e.field));
        assert_eq!(format!("{reconfigured:?}"), format!("{new:?}"));
        let mut bad = next;
        bad.conveyor_counts_per_rev = 0;
        assert_eq!(
            PickController::replacing(Some(&first), &bad, settings, 3)
                .map(|_| ())
                .map_err(|e| e.field),
            PickController::new(&bad, settings, 3)
                .map(|_| ())
                .map_err(|e| e.field)
        );
    }
}
