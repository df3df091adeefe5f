//! The whole controller application behind the serial link: the protocol
//! session ([`LinkResponder`]) plus, once a cell configuration has arrived, the
//! pick ([`PickController`]). The firmware's tasks and the simulator's
//! in-process link both drive this one type.

use heapless::{Deque, Vec};

use super::homing::HomingError;
use super::link::LinkResponder;
use super::pick::cell::ConfigError;
use super::pick::handoff::{ControlEvent, JobTicket, VisionNews, WorkItem};
use super::pick::{PickController, PickParts, MAX_TICK_MESSAGES};
use super::power_on_homing::{self, HomedOffsets, HomingStage, PowerOnHoming};
use crate::protocol::{
    ActuatorCommand, CalibrationReport, CellConfig, DecodeError, ErrorCode, GripperCommand,
    Message, SensorSample,
};
use crate::safety::{check_reconfigure, CellState, EncoderMotion, ReconfigureRefusal};

/// Replies one incoming message may produce.
pub const MAX_REPLIES: usize = MAX_TICK_MESSAGES + 1;

/// Jobs requested and not yet run (one at a time is the pick's rule).
const PENDING_JOBS: usize = 2;

/// The worker's queue when the caller runs the worker itself
/// ([`ControllerApp::with_queued_work`]): as many items as the firmware's
/// `WORK` channel holds, so that a slow job costs the same frames here as on
/// the board.
pub const WORK_SLOTS: usize = 8;

/// The controller application in one piece, for the in-process link: the
/// pick's three parts called in the order the firmware's tasks call them.
#[derive(Debug, Clone)]
pub struct ControllerApp {
    link: LinkResponder,
    pick: Option<PickParts>,
    sessions: u32,
    jobs: Deque<JobTicket, PENDING_JOBS>,
    reported_estimate: u32,
    /// Joint speeds from the samples' encoder counts, for the
    /// reconfiguration gate (the same estimate the firmware's interlock
    /// makes).
    motion: EncoderMotion,
    joint_speed_rad_s: Option<[f32; crate::safety::JOINTS]>,
    /// Observations and jobs for a worker the caller runs (a board's
    /// low-priority task stands in here), or `None`: the worker runs in
    /// [`ControllerApp::on_message`] and [`ControllerApp::run_background`].
    work: Option<Deque<WorkItem, WORK_SLOTS>>,
    /// Items refused because `work` was full (the firmware's handoffs dropped).
    work_dropped: u32,
    /// Homing at power-on, while it runs or after it failed
    /// ([`CellConfig::home_at_power_on`]).
    homing: Option<HomingRun>,
    /// The counters' offsets once homed, or zero where no homing is asked
    /// for.
    offsets: Option<HomedOffsets>,
    /// What the last homing found.
    homed: Option<HomedOffsets>,
}

/// Homing as the application runs it: the sequence, its telemetry's
/// period, and the last command (a sample sent again gets it again).
#[derive(Debug, Clone)]
struct HomingRun {
    homing: PowerOnHoming,
    counts_per_rad: [f32; crate::safety::JOINTS],
    telemetry_period_ticks: u16,
    ticks: u32,
    last: Option<(u32, u64, ActuatorCommand)>,
}

impl ControllerApp {
    /// The application of a board called `board_name` running `control_rate_hz` periods a
    /// second.
    pub fn new(board_name: &str, control_rate_hz: u32) -> Self {
        Self {
            link: LinkResponder::new(board_name, control_rate_hz),
            pick: None,
            sessions: 0,
            jobs: Deque::new(),
            reported_estimate: 0,
            motion: EncoderMotion::new(&[0.0; crate::safety::JOINTS]),
            joint_speed_rad_s: None,
            work: None,
            work_dropped: 0,
            homing: None,
            offsets: None,
            homed: None,
        }
    }

    /// The same application with its worker's items queued for the caller
    /// ([`ControllerApp::next_work`], [`ControllerApp::process_work`],
    /// [`ControllerApp::deliver`]), as the firmware's worker task takes
    /// them: a host that delays each job's result by what it costs on a
    /// board runs the pick as that board would.
    pub fn with_queued_work(board_name: &str, control_rate_hz: u32) -> Self {
        Self {
            work: Some(Deque::new()),
            ..Self::new(board_name, control_rate_hz)
        }
    }

    /// The next item for the worker, oldest first (queued work only).
    pub fn next_work(&mut self) -> Option<WorkItem> {
        self.work.as_mut().and_then(Deque::pop_front)
    }

    /// Runs `item` on the worker and returns its news without delivering it
    /// (the caller delivers it when the board would have finished).
    pub fn process_work(&mut self, item: &WorkItem) -> Option<VisionNews> {
        self.pick
            .as_mut()
            .and_then(|parts| parts.worker.process(item))
    }

    /// Hands the worker's `news` to the control loop.
    pub fn deliver(&mut self, news: &VisionNews) {
        if let Some(parts) = self.pick.as_mut() {
            parts.control.on_news(news);
        }
    }

    /// Worker items refused because the queue was full (queued work only).
    pub fn work_dropped(&self) -> u32 {
        self.work_dropped
    }

    /// Whether a new configuration may replace the pick now
    /// (`crate::safety::reconfigure`). The plant is the host's, in lock step:
    /// its drives are not this controller's to switch off.
    pub fn may_reconfigure(&self) -> Result<(), ReconfigureRefusal> {
        let control = self.pick.as_ref().map(|parts| &parts.control);
        check_reconfigure(&CellState {
            phase: control.map(PickController::phase),
            joint_speed_rad_s: self.joint_speed_rad_s,
            gripper_holds: control.is_some_and(PickController::gripper_holds),
            drives_on: false,
            drives_off_required: false,
        })
    }

    /// The link's responder.
    pub fn link(&self) -> &LinkResponder {
        &self.link
    }

    /// The link's responder, to update its counters.
    pub fn link_mut(&mut self) -> &mut LinkResponder {
        &mut self.link
    }

    /// The pick, once configured.
    pub fn pick(&self) -> Option<&PickController> {
        self.pick.as_ref().map(|parts| &parts.control)
    }

    /// Where homing stands: `None` before a configuration that asks for it.
    pub fn homing_stage(&self) -> Option<HomingStage> {
        match (&self.homing, self.homed) {
            (Some(run), _) => Some(run.homing.stage()),
            (None, Some(offsets)) => Some(HomingStage::Homed(offsets)),
            (None, None) => None,
        }
    }

    /// The error homing stopped on, if it did.
    pub fn homing_error(&self) -> Option<HomingError> {
        self.homing.as_ref().and_then(|run| run.homing.error())
    }

    /// One homing period for `sample` (the pick waits until homing is done).
    fn homing_period(&mut self, sample: &SensorSample, out: &mut Vec<Message, MAX_REPLIES>) {
        let Some(run) = self.homing.as_mut() else {
            return;
        };
        self.link.count_received();
        if let Some((seq, time_us, command)) = run.last {
            if seq == sample.seq && time_us == sample.time_us {
                let _ = out.push(Message::ActuatorCommand(command));
                return;
            }
        }
        let torque = run.homing.period(sample);
        let command = ActuatorCommand {
            seq: sample.seq,
            joint_torque_nm: torque,
            gripper: GripperCommand::Open,
            camera_trigger: None,
        };
        run.last = Some((sample.seq, sample.time_us, command));
        run.ticks = run.ticks.wrapping_add(1);
        self.joint_speed_rad_s = self.motion.update(&sample.joint_counts, sample.time_us).1;
        self.link
            .set_control_ticks(self.link.status().control_ticks.saturating_add(1));
        let _ = out.push(Message::ActuatorCommand(command));
        match run.homing.stage() {
            HomingStage::Homed(offsets) => {
                self.offsets = Some(offsets);
                self.homed = Some(offsets);
                // The pick's samples are homed from here: speeds start over.
                self.motion = EncoderMotion::new(&run.counts_per_rad);
                self.joint_speed_rad_s = None;
                self.homing = None;
            }
            HomingStage::Failed(error) => {
                let period = u32::from(run.telemetry_period_ticks.max(1));
                if run.ticks % period == 0 {
                    let _ = out.push(Message::Telemetry(power_on_homing::fault_telemetry(
                        sample,
                        &error,
                        self.link.status().frames_rejected,
                    )));
                }
            }
            _ => {}
        }
    }

    /// Answers one decoded message into `out`.
    pub fn on_message(&mut self, message: &Message, out: &mut Vec<Message, MAX_REPLIES>) {
        let armed = self.link.session_open() && self.pick.is_some();
        match (message, armed) {
            (Message::SensorSample(sample), true) if self.offsets.is_none() => {
                self.homing_period(sample, out);
            }
            (Message::SensorSample(sample), true) => {
                let mut homed = *sample;
                if let Some(offsets) = self.offsets.as_ref() {
                    offsets.apply(&mut homed);
                }
                let sample = &homed;
                self.link.count_received();
                let mut extra: Vec<Message, MAX_TICK_MESSAGES> = Vec::new();
                if let Some(parts) = self.pick.as_mut() {
                    let repeated = parts.control.repeats(sample);
                    parts
                        .control
                        .set_link_frames_rejected(self.link.status().frames_rejected);
                    let command = parts.control.on_sensor_sample(sample, &mut extra);
                    if !repeated {
                        self.joint_speed_rad_s =
                            self.motion.update(&sample.joint_counts, sample.time_us).1;
                        self.link
                            .set_control_ticks(self.link.status().control_ticks.saturating_add(1));
                    }
                    let _ = out.push(Message::ActuatorCommand(command));
                    if let Some(report) =
                        new_calibration_report(&parts.control, &mut self.reported_estimate)
                    {
                        let _ = out.push(report);
                    }
                    while let Some(event) = parts.control.pop_event() {
                        match event {
                            ControlEvent::Trigger(record) => parts.pairer.on_trigger(&record),
                            ControlEvent::Job(ticket) => {
                                if let Some(WorkItem::Job(ticket)) = queue_into(
                                    &mut self.work,
                                    &mut self.work_dropped,
                                    WorkItem::Job(ticket),
                                ) {
                                    if self.jobs.is_full() {
                                        let _ = self.jobs.pop_front();
                                    }
                                    let _ = self.jobs.push_back(ticket);
                                }
                            }
                        }
                    }
                }
                for message in extra {
                    let _ = out.push(message);
                }
            }
            // While homing, a camera frame has no trigger to pair with.
            (Message::CameraFeatures(frame), true) if self.offsets.is_some() => {
                if let Some(parts) = self.pick.as_mut() {
                    // A frame that cannot be paired is counted by the pick, not an error of the link.
                    match parts.pairer.on_frame(frame) {
                        Ok(paired) => {
                            parts.control.on_news(&paired.news);
                            if let Some(observation) = paired.observation {
                                let item = WorkItem::Observation(observation);
                                if let Some(item) =
                                    queue_into(&mut self.work, &mut self.work_dropped, item)
                                {
                                    if let Some(news) = parts.worker.process(&item) {
                                        parts.control.on_news(&news);
                                    }
                                }
                            }
                        }
                        Err(_) => parts.control.on_news(&VisionNews::Unpaired),
                    }
                }
                if let Some(reply) = self.link.handle(message) {
                    let _ = out.push(reply);
                }
            }
            (Message::Configure(_), _)
                if self.link.session_open() && self.may_reconfigure().is_err() =>
            {
                self.link.count_received();
                if let Err(refusal) = self.may_reconfigure() {
                    let _ = out.push(refusal_message(refusal));
                }
            }
            (Message::Configure(config), _) if self.link.session_open() => {
                match configure(config, &mut self.sessions) {
                    Ok(parts) => {
                        self.pick = Some(parts);
                        self.jobs.clear();
                        if let Some(work) = self.work.as_mut() {
                            work.clear();
                        }
                        self.reported_estimate = 0;
                        self.motion = EncoderMotion::new(&config.joint_counts_per_rad);
                        self.joint_speed_rad_s = None;
                        self.start_homing(config);
                        if let Some(reply) = self.link.handle(message) {
                            let _ = out.push(reply);
                        }
                    }
                    Err(report) => {
                        self.link.count_received();
                        let _ = out.push(report.message());
                    }
                }
            }
            _ => {
                if let Some(reply) = self.link.handle(message) {
                    let _ = out.push(reply);
                }
            }
        }
    }

    /// A new configuration: homing starts unless the counters need none.
    /// Every configuration homes again: it is the restart after a stop,
    /// after which the arm may have been moved with the drives off.
    fn start_homing(&mut self, config: &CellConfig) {
        if !config.home_at_power_on {
            self.homing = None;
            self.offsets = Some(HomedOffsets::ZERO);
            return;
        }
        self.homed = None;
        self.offsets = None;
        self.homing = match PowerOnHoming::new(&config.joint_counts_per_rad) {
            Ok(homing) => Some(HomingRun {
                homing,
                counts_per_rad: config.joint_counts_per_rad,
                telemetry_period_ticks: config.telemetry_period_ticks,
                ticks: 0,
                last: None,
            }),
            // The configuration's counts per radian were accepted by the
            // pick, so this does not happen; nothing moves without homing.
            Err(_) => None,
        };
    }

    /// A frame the decoder refused: counted and reported.
    pub fn on_decode_error(&mut self, error: &DecodeError) -> Message {
        self.link.on_decode_error(error)
    }

    /// Background work (self-calibration, planning): the firmware's low-priority
    /// task, or the simulator after each message.
    pub fn run_background(&mut self) {
        let Some(parts) = self.pick.as_mut() else {
            return;
        };
        while let Some(ticket) = self.jobs.pop_front() {
            if let Some(news) = parts.worker.process(&WorkItem::Job(ticket)) {
                parts.control.on_news(&news);
            }
        }
    }
}

/// Queues `item` into `work` for the caller's worker (counting it in
/// `dropped` when full, as the firmware's `WORK` channel does), or, with no
/// queue, gives it back to be run now.
fn queue_into(
    work: &mut Option<Deque<WorkItem, WORK_SLOTS>>,
    dropped: &mut u32,
    item: WorkItem,
) -> Option<WorkItem> {
    let Some(work) = work.as_mut() else {
        return Some(item);
    };
    if work.push_back(item).is_err() {
        *dropped = dropped.saturating_add(1);
    }
    None
}

/// A cell configuration refused: which field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ConfigRefused {
    /// Why it was refused.
    pub error: ConfigError,
}

impl ConfigRefused {
    /// The error report for the peer (the detail is the field's index).
    pub fn message(&self) -> Message {
        Message::ErrorReport {
            code: ErrorCode::BadConfiguration,
            detail: config_field_index(self.error.field),
        }
    }
}

/// The report refusing a configuration that came while the cell was not
/// ready for one (the running controller is kept).
pub fn refusal_message(refusal: ReconfigureRefusal) -> Message {
    Message::ErrorReport {
        code: ErrorCode::ConfigurationRefusedActive,
        detail: refusal.detail(),
    }
}

/// The pick's parts for a new cell configuration (a new session number).
pub fn configure(config: &CellConfig, sessions: &mut u32) -> Result<PickParts, ConfigRefused> {
    *sessions = sessions.wrapping_add(1);
    PickParts::new(config, *sessions).map_err(|error| ConfigRefused { error })
}

/// A calibration report message when the control loop holds an estimate
/// newer than the last one reported.
pub fn new_calibration_report(control: &PickController, reported: &mut u32) -> Option<Message> {
    new_report(control, reported).map(Message::CalibrationReport)
}

/// The report itself, for a caller that hands it on without composing the
/// message (the firmware's control loop gives it to the link task).
pub fn new_report(control: &PickController, reported: &mut u32) -> Option<CalibrationReport> {
    // The serial first: every control period asks, and copying the report
    // out only to find it already sent is a measurable share of a period.
    if control.estimate_serial()? == *reported {
        return None;
    }
    let (serial, report) = control.calibration_report()?;
    *reported = serial;
    Some(report)
}

/// `CellConfig`'s fields in declaration order, for the error report's detail.
const CONFIG_FIELDS: [&str; 14] = [
    "image_width_px",
    "image_height_px",
    "f_px",
    "cx_px",
    "cy_px",
    "reference_radius_m",
    "part_feature_count",
    "conveyor_counts_per_rev",
    "conveyor_counter_bits",
    "joint_counts_per_rad",
    "disc_height_in_base_m",
    "drop_off_base_m",
    "camera_period_ms",
    "telemetry_period_ticks",
];

fn config_field_index(field: &str) -> u32 {
    CONFIG_FIELDS
        .iter()
        .position(|f| *f == field)
        .and_then(|i| u32::try_from(i).ok())
        .unwrap_or(u32::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::{PickPhase, SensorSample, PROTOCOL_VERSION};

    fn config() -> CellConfig {
        crate::test_cell::test_cell_config(4096, 4)
    }

    /// A controller that has answered the host's hello.
    fn greeted() -> ControllerApp {
        let mut app = ControllerApp::new("test", 1000);
        let mut out = Vec::new();
        app.on_message(
            &Message::Hello {
                protocol_version: PROTOCOL_VERSION,
                peer_name: heapless::String::new(),
            },
            &mut out,
        );
        app
    }

    fn configured() -> ControllerApp {
        let mut app = greeted();
        let mut out = Vec::new();
        app.on_message(&Message::Configure(config()), &mut out);
        assert!(app.pick().is_some(), "{out:?}");
        app
    }

    fn sample(seq: u32) -> SensorSample {
        SensorSample {
            seq,
            time_us: 1_000 * u64::from(seq),
            // Elbow up, away from the singularities.
            joint_counts: [0, -8_000, 16_000, 0, 8_000, 0],
            conveyor_counts: 3 * seq,
            part_in_gripper: false,
            joint_pots_rad: [0.0; 6],
            joint_index_counts: SensorSample::NO_INDEX,
        }
    }

    fn exchange(app: &mut ControllerApp, sample: &SensorSample) -> Vec<Message, MAX_REPLIES> {
        let mut out = Vec::new();
        app.on_message(&Message::SensorSample(*sample), &mut out);
        out
    }

    #[test]
    fn a_sample_sent_again_gets_the_same_command_and_no_second_period() {
        let mut app = configured();
        for seq in 1..=50 {
            exchange(&mut app, &sample(seq));
        }
        let first = exchange(&mut app, &sample(51));
        let ticks = app.link().status().control_ticks;
        let time_s = app.pick().map(|p| p.time_s());
        let again = exchange(&mut app, &sample(51));
        assert!(matches!(first.first(), Some(Message::ActuatorCommand(c)) if c.seq == 51));
        // The same command, and nothing else (no second telemetry).
        assert_eq!(again.len(), 1, "{again:?}");
        assert_eq!(again.first(), first.first());
        assert_eq!(app.link().status().control_ticks, ticks);
        assert_eq!(app.pick().map(|p| p.time_s()), time_s);
        // The next sample runs its period as usual.
        let next = exchange(&mut app, &sample(52));
        assert!(matches!(next.first(), Some(Message::ActuatorCommand(c)) if c.seq == 52));
        assert_eq!(app.link().status().control_ticks, ticks + 1);
    }

    #[test]
    fn a_configuration_mid_motion_is_refused_and_the_pick_runs_on() {
        let mut app = configured();
        for seq in 1..=20 {
            exchange(&mut app, &sample(seq));
        }
        let phase = app.pick().map(PickController::phase);
        assert!(
            !matches!(
                phase,
                Some(PickPhase::Idle | PickPhase::Done | PickPhase::Faulted)
            ),
            "{phase:?}"
        );
        let time_s = app.pick().map(|p| p.time_s());
        let mut out = Vec::new();
        app.on_message(&Message::Configure(config()), &mut out);
        let Some(Message::ErrorReport { code, detail }) = out.first() else {
            panic!("expected a refusal, got {out:?}");
        };
        assert_eq!(*code, ErrorCode::ConfigurationRefusedActive);
        assert_eq!(detail >> 16, 1, "pick active: {detail:#x}");
        // The same pick, not a new one from its start.
        assert_eq!(app.pick().map(|p| p.time_s()), time_s);
        assert_eq!(app.pick().map(PickController::phase), phase);
    }

    #[test]
    fn a_configuration_after_a_stop_at_rest_is_accepted() {
        let mut app = configured();
        for seq in 1..=5 {
            exchange(&mut app, &sample(seq));
        }
        if let Some(parts) = app.pick.as_mut() {
            parts.control.stop(crate::protocol::FaultCause::LinkLost);
        }
        // The arm stands still (the samples' counts do not change) while the
        // pick stops and then holds.
        let mut seq = 6;
        while app.pick().map(PickController::phase) != Some(PickPhase::Faulted) && seq < 5_000 {
            exchange(&mut app, &sample(seq));
            seq += 1;
        }
        for _ in 0..20 {
            exchange(&mut app, &sample(seq));
            seq += 1;
        }
        assert_eq!(app.may_reconfigure(), Ok(()));
        let mut out = Vec::new();
        app.on_message(&Message::Configure(config()), &mut out);
        assert!(
            matches!(
                out.first(),
                Some(Message::Ack {
                    kind: crate::protocol::MessageKind::Configure,
                    ..
                })
            ),
            "{out:?}"
        );
        assert_eq!(app.pick().map(PickController::phase), Some(PickPhase::Idle));
    }

    #[test]
    fn a_sample_with_a_new_time_is_a_new_period_even_with_the_same_seq() {
        let mut app = configured();
        exchange(&mut app, &sample(1));
        let mut later = sample(1);
        later.time_us += 1_000;
        exchange(&mut app, &later);
        assert_eq!(app.link().status().control_ticks, 2);
    }

    #[test]
    fn a_homing_fault_holds_the_pick_back_and_reports_its_cause() {
        let mut app = greeted();
        let mut out = Vec::new();
        let mut homing = config();
        homing.home_at_power_on = true;
        app.on_message(&Message::Configure(homing), &mut out);
        assert!(matches!(app.homing_stage(), Some(HomingStage::Coarse)));
        let mut broken = sample(1);
        broken.joint_pots_rad = [0.1, f32::NAN, 0.2, 0.0, 0.3, 0.0];
        let out = exchange(&mut app, &broken);
        assert!(matches!(out.first(), Some(Message::ActuatorCommand(c)) if c.seq == 1));
        assert_eq!(
            app.homing_error(),
            Some(HomingError::PotentiometerNotFinite { joint: 1 })
        );
        let telemetry = out.iter().find_map(|m| match m {
            Message::Telemetry(t) => Some(*t),
            _ => None,
        });
        assert_eq!(
            telemetry.map(|t| (t.phase, t.fault)),
            Some((
                PickPhase::Faulted,
                Some(crate::protocol::FaultCause::HomingPotentiometer)
            ))
        );
        // The pick never ran a period.
        assert_eq!(app.pick().map(PickController::phase), Some(PickPhase::Idle));
    }

    #[test]
    fn telemetry_reports_every_refused_frame() {
        let mut app = configured();
        exchange(&mut app, &sample(1));
        app.on_decode_error(&DecodeError::Corrupt);
        app.on_decode_error(&DecodeError::BadCrc {
            expected: 1,
            found: 2,
        });
        let out = exchange(&mut app, &sample(2));
        let telemetry = out.iter().find_map(|m| match m {
            Message::Telemetry(t) => Some(*t),
            _ => None,
        });
        assert_eq!(telemetry.map(|t| t.frames_rejected), Some(2), "{out:?}");
    }
}
