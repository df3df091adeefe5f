//! The whole controller application behind the serial link: the protocol
//! session ([`LinkResponder`]) plus, once a cell configuration has arrived, the
//! pick ([`PickController`]). The firmware's tasks and the simulator's
//! in-process link both drive this one type.

use heapless::{Deque, Vec};

use super::link::LinkResponder;
use super::pick::cell::ConfigError;
use super::pick::handoff::{ControlEvent, JobTicket, VisionNews, WorkItem};
use super::pick::{PickController, PickParts, MAX_TICK_MESSAGES};
use crate::protocol::{CellConfig, DecodeError, ErrorCode, Message};

/// Replies one incoming message may produce.
pub const MAX_REPLIES: usize = MAX_TICK_MESSAGES + 1;

/// Jobs requested and not yet run (one at a time is the pick's rule).
const PENDING_JOBS: usize = 2;

/// The controller application in one piece, for the in-process link: the
/// pick's three parts called in the order the firmware's tasks call them.
#[derive(Debug, Clone)]
pub struct ControllerApp {
    link: LinkResponder,
    pick: Option<PickParts>,
    sessions: u32,
    jobs: Deque<JobTicket, PENDING_JOBS>,
    reported_estimate: u32,
}

impl ControllerApp {
    pub fn new(board_name: &str, control_rate_hz: u32) -> Self {
        Self {
            link: LinkResponder::new(board_name, control_rate_hz),
            pick: None,
            sessions: 0,
            jobs: Deque::new(),
            reported_estimate: 0,
        }
    }

    pub fn link(&self) -> &LinkResponder {
        &self.link
    }

    pub fn link_mut(&mut self) -> &mut LinkResponder {
        &mut self.link
    }

    pub fn pick(&self) -> Option<&PickController> {
        self.pick.as_ref().map(|parts| &parts.control)
    }

    /// Answers one decoded message into `out`.
    pub fn on_message(&mut self, message: &Message, out: &mut Vec<Message, MAX_REPLIES>) {
        let armed = self.link.session_open() && self.pick.is_some();
        match (message, armed) {
            (Message::SensorSample(sample), true) => {
                self.link.count_received();
                let mut extra: Vec<Message, MAX_TICK_MESSAGES> = Vec::new();
                if let Some(parts) = self.pick.as_mut() {
                    let command = parts.control.on_sensor_sample(sample, &mut extra);
                    self.link
                        .set_control_ticks(self.link.status().control_ticks.saturating_add(1));
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
                                if self.jobs.is_full() {
                                    let _ = self.jobs.pop_front();
                                }
                                let _ = self.jobs.push_back(ticket);
                            }
                        }
                    }
                }
                for message in extra {
                    let _ = out.push(message);
                }
            }
            (Message::CameraFeatures(frame), true) => {
                if let Some(parts) = self.pick.as_mut() {
                    // A frame that cannot be paired is counted by the pick, not an error of the link.
                    match parts.pairer.on_frame(frame) {
                        Ok(paired) => {
                            parts.control.on_news(&paired.news);
                            if let Some(observation) = paired.observation {
                                let item = WorkItem::Observation(observation);
                                if let Some(news) = parts.worker.process(&item) {
                                    parts.control.on_news(&news);
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
            (Message::Configure(config), _) if self.link.session_open() => {
                match configure(config, &mut self.sessions) {
                    Ok(parts) => {
                        self.pick = Some(parts);
                        self.jobs.clear();
                        self.reported_estimate = 0;
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

/// A cell configuration refused: which field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ConfigRefused {
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

/// The pick's parts for a new cell configuration (a new session number).
pub fn configure(config: &CellConfig, sessions: &mut u32) -> Result<PickParts, ConfigRefused> {
    *sessions = sessions.wrapping_add(1);
    PickParts::new(config, *sessions).map_err(|error| ConfigRefused { error })
}

/// A calibration report when the control loop holds an estimate newer than
/// the last one reported.
pub fn new_calibration_report(control: &PickController, reported: &mut u32) -> Option<Message> {
    let (serial, report) = control.calibration_report()?;
    if serial == *reported {
        return None;
    }
    *reported = serial;
    Some(Message::CalibrationReport(report))
}

/// `CellConfig`'s fields in declaration order, for the error report's detail.
const CONFIG_FIELDS: [&str; 15] = [
    "image_width_px",
    "image_height_px",
    "f_px",
    "cx_px",
    "cy_px",
    "pixel_sigma_px",
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
