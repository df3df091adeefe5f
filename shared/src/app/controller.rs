//! The whole controller application behind the serial link: the protocol
//! session ([`LinkResponder`]) plus, once a cell configuration has arrived, the
//! pick ([`PickController`]). The firmware's tasks and the simulator's
//! in-process link both drive this one type.

use heapless::Vec;

use super::link::LinkResponder;
use super::pick::{PickController, MAX_TICK_MESSAGES};
use crate::protocol::{DecodeError, ErrorCode, Message};

/// Replies one incoming message may produce.
pub const MAX_REPLIES: usize = MAX_TICK_MESSAGES + 1;

/// The controller application.
#[derive(Debug, Clone)]
pub struct ControllerApp {
    link: LinkResponder,
    pick: Option<PickController>,
    reported_estimate: u32,
}

impl ControllerApp {
    pub fn new(board_name: &str, control_rate_hz: u32) -> Self {
        Self {
            link: LinkResponder::new(board_name, control_rate_hz),
            pick: None,
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
        self.pick.as_ref()
    }

    /// Answers one decoded message into `out`.
    pub fn on_message(&mut self, message: &Message, out: &mut Vec<Message, MAX_REPLIES>) {
        let armed = self.link.session_open() && self.pick.is_some();
        match (message, armed) {
            (Message::SensorSample(sample), true) => {
                self.link.count_received();
                let mut extra: Vec<Message, MAX_TICK_MESSAGES> = Vec::new();
                if let Some(pick) = self.pick.as_mut() {
                    let command = pick.on_sensor_sample(sample, &mut extra);
                    self.link
                        .set_control_ticks(self.link.status().control_ticks.saturating_add(1));
                    let _ = out.push(Message::ActuatorCommand(command));
                    if let Some((serial, report)) = pick.calibration_report() {
                        if serial != self.reported_estimate {
                            self.reported_estimate = serial;
                            let _ = out.push(Message::CalibrationReport(report));
                        }
                    }
                }
                for message in extra {
                    let _ = out.push(message);
                }
            }
            (Message::CameraFeatures(frame), true) => {
                if let Some(pick) = self.pick.as_mut() {
                    // A frame that cannot be paired is counted by the pick, not an error of the link.
                    let _ = pick.on_camera_frame(frame);
                }
                if let Some(reply) = self.link.handle(message) {
                    let _ = out.push(reply);
                }
            }
            (Message::Configure(config), _) if self.link.session_open() => {
                match PickController::new(config) {
                    Ok(pick) => {
                        self.pick = Some(pick);
                        self.reported_estimate = 0;
                        if let Some(reply) = self.link.handle(message) {
                            let _ = out.push(reply);
                        }
                    }
                    Err(error) => {
                        self.link.count_received();
                        let _ = out.push(Message::ErrorReport {
                            code: ErrorCode::BadConfiguration,
                            detail: config_field_index(error.field),
                        });
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
        if let Some(pick) = self.pick.as_mut() {
            pick.run_background();
        }
    }
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
