//! The controller's side of a protocol session: handshake, acknowledgements with a
//! running counter (so the host can prove no frame was lost or reordered), status,
//! and error reports for everything rejected.

use heapless::String;

use crate::protocol::{
    ControllerMode, ControllerStatus, DecodeError, ErrorCode, Message, MessageKind, RuntimeReport,
    MAX_FRAME_LEN, MAX_NAME_LEN, MAX_VERSION_LEN, PROTOCOL_VERSION,
};

/// Answers each decoded message; keeps the link's counters.
#[derive(Debug, Clone)]
pub struct LinkResponder {
    board_name: String<MAX_NAME_LEN>,
    control_rate_hz: u32,
    session_open: bool,
    session_acks: u32,
    status: ControllerStatus,
}

impl LinkResponder {
    /// `board_name` longer than the protocol allows is cut at a character boundary.
    pub fn new(board_name: &str, control_rate_hz: u32) -> Self {
        let mut name = String::new();
        for c in board_name.chars() {
            if name.push(c).is_err() {
                break;
            }
        }
        Self {
            board_name: name,
            control_rate_hz,
            session_open: false,
            session_acks: 0,
            status: ControllerStatus {
                mode: ControllerMode::Idle,
                control_ticks: 0,
                frames_received: 0,
                frames_rejected: 0,
                frames_unexpected: 0,
                deadline_misses: 0,
            },
        }
    }

    /// Fed by the control-loop task.
    pub fn set_control_ticks(&mut self, ticks: u64) {
        self.status.control_ticks = ticks;
    }

    /// Fed by the control-loop task.
    pub fn set_deadline_misses(&mut self, misses: u32) {
        self.status.deadline_misses = misses;
    }

    /// Counts a valid frame that the application answered itself.
    pub fn count_received(&mut self) {
        self.status.frames_received = self.status.frames_received.wrapping_add(1);
    }

    /// The status to report.
    pub fn status(&self) -> ControllerStatus {
        self.status
    }

    /// Whether a handshake has opened a session.
    pub fn session_open(&self) -> bool {
        self.session_open
    }

    /// The reply to one valid frame, if it needs one.
    pub fn handle(&mut self, message: &Message) -> Option<Message> {
        self.status.frames_received = self.status.frames_received.wrapping_add(1);
        match message {
            Message::Hello {
                protocol_version, ..
            } => Some(self.hello(*protocol_version)),
            Message::CameraFeatures(frame) => {
                Some(self.data(MessageKind::CameraFeatures, frame.trigger_id))
            }
            Message::SensorSample(sample) => Some(self.data(MessageKind::SensorSample, sample.seq)),
            Message::ActuatorCommand(command) => {
                Some(self.data(MessageKind::ActuatorCommand, command.seq))
            }
            Message::StatusRequest => Some(Message::Status(self.status)),
            Message::RuntimeReportRequest => Some(Message::RuntimeReport(
                RuntimeReport::not_measured(self.status.control_ticks),
            )),
            Message::Configure(_) => Some(self.data(MessageKind::Configure, 0)),
            Message::HelloAck { .. }
            | Message::Status(_)
            | Message::Ack { .. }
            | Message::ErrorReport { .. }
            | Message::Telemetry(_)
            | Message::CalibrationReport(_)
            | Message::RuntimeReport(_)
            | Message::TriggerEvent(_) => {
                self.status.frames_unexpected = self.status.frames_unexpected.wrapping_add(1);
                Some(Message::ErrorReport {
                    code: ErrorCode::UnexpectedMessage,
                    detail: self.status.frames_unexpected,
                })
            }
        }
    }

    /// Counts a rejected frame; returns the report to send back.
    pub fn on_decode_error(&mut self, error: &DecodeError) -> Message {
        self.status.frames_rejected = self.status.frames_rejected.wrapping_add(1);
        let code = match error {
            DecodeError::Oversized { .. } => ErrorCode::OversizedFrame,
            DecodeError::Corrupt | DecodeError::TooShort { .. } => ErrorCode::CorruptFrame,
            DecodeError::BadCrc { .. } => ErrorCode::BadCrc,
            DecodeError::BadMessage => ErrorCode::BadMessage,
        };
        Message::ErrorReport {
            code,
            detail: self.status.frames_rejected,
        }
    }

    fn hello(&mut self, peer_version: u16) -> Message {
        if peer_version != PROTOCOL_VERSION {
            self.session_open = false;
            self.status.mode = ControllerMode::Idle;
            return Message::ErrorReport {
                code: ErrorCode::UnsupportedVersion,
                detail: u32::from(PROTOCOL_VERSION),
            };
        }
        self.session_open = true;
        self.session_acks = 0;
        self.status.mode = ControllerMode::Running;
        let mut firmware_version: String<MAX_VERSION_LEN> = String::new();
        for c in env!("CARGO_PKG_VERSION").chars() {
            if firmware_version.push(c).is_err() {
                break;
            }
        }
        Message::HelloAck {
            protocol_version: PROTOCOL_VERSION,
            board_name: self.board_name.clone(),
            firmware_version,
            control_rate_hz: self.control_rate_hz,
            max_frame_len: u16::try_from(MAX_FRAME_LEN).unwrap_or(u16::MAX),
        }
    }

    fn data(&mut self, kind: MessageKind, token: u32) -> Message {
        if !self.session_open {
            return Message::ErrorReport {
                code: ErrorCode::HandshakeRequired,
                detail: token,
            };
        }
        self.session_acks = self.session_acks.wrapping_add(1);
        Message::Ack {
            kind,
            token,
            counter: self.session_acks,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::{SensorSample, JOINTS};

    fn hello(version: u16) -> Message {
        Message::Hello {
            protocol_version: version,
            peer_name: String::try_from("test").unwrap(),
        }
    }

    fn sample(seq: u32) -> Message {
        Message::SensorSample(SensorSample {
            seq,
            time_us: 0,
            joint_counts: [0; JOINTS],
            conveyor_counts: 0,
            part_in_gripper: false,
            joint_pots_rad: [0.0; 6],
            joint_index_counts: SensorSample::NO_INDEX,
        })
    }

    #[test]
    fn data_before_handshake_is_refused() {
        let mut r = LinkResponder::new("board", 1000);
        assert_eq!(
            r.handle(&sample(7)),
            Some(Message::ErrorReport {
                code: ErrorCode::HandshakeRequired,
                detail: 7
            })
        );
    }

    #[test]
    fn wrong_version_is_refused_and_right_one_opens_a_session() {
        let mut r = LinkResponder::new("board", 1000);
        for version in [PROTOCOL_VERSION - 1, PROTOCOL_VERSION + 1] {
            assert!(matches!(
                r.handle(&hello(version)),
                Some(Message::ErrorReport {
                    code: ErrorCode::UnsupportedVersion,
                    ..
                })
            ));
            assert!(!r.session_open());
        }
        assert!(matches!(
            r.handle(&hello(PROTOCOL_VERSION)),
            Some(Message::HelloAck {
                control_rate_hz: 1000,
                ..
            })
        ));
        for i in 1..=5u32 {
            assert_eq!(
                r.handle(&sample(100 + i)),
                Some(Message::Ack {
                    kind: MessageKind::SensorSample,
                    token: 100 + i,
                    counter: i
                })
            );
        }
        // A new handshake restarts the session's counter.
        r.handle(&hello(PROTOCOL_VERSION));
        assert!(matches!(
            r.handle(&sample(1)),
            Some(Message::Ack { counter: 1, .. })
        ));
    }

    #[test]
    fn rejections_are_counted_in_status() {
        let mut r = LinkResponder::new("a-very-long-board-name-that-does-not-fit", 1000);
        r.on_decode_error(&DecodeError::Corrupt);
        let report = r.on_decode_error(&DecodeError::BadCrc {
            expected: 1,
            found: 2,
        });
        assert_eq!(
            report,
            Message::ErrorReport {
                code: ErrorCode::BadCrc,
                detail: 2
            }
        );
        r.set_control_ticks(42);
        match r.handle(&Message::StatusRequest) {
            Some(Message::Status(s)) => {
                assert_eq!(s.frames_rejected, 2);
                assert_eq!(s.control_ticks, 42);
                assert_eq!(s.frames_received, 1);
            }
            other => panic!("expected status, got {other:?}"),
        }
    }
}
