//! What a link check finds: why it failed, or the counts of its exchange and
//! of its corruption run, and the controller's handshake.

use std::fmt;
use std::time::Duration;

use crate::link::LinkError;

/// Why a check failed.
#[derive(Debug)]
pub enum CheckError {
    Link(LinkError),
    /// The controller's answer was not the one the protocol requires here.
    Unexpected {
        /// Which reply of the phase (0-based) went wrong.
        index: u64,
        expected: String,
        got: String,
    },
    /// The controller's rejected-frame count did not move as injected.
    RejectCount {
        injected: u32,
        before: u32,
        after: u32,
    },
    /// A configuration the check cannot run with.
    Config(String),
}

impl fmt::Display for CheckError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CheckError::Link(e) => write!(f, "{e}"),
            CheckError::Unexpected {
                index,
                expected,
                got,
            } => write!(f, "reply #{index}: expected {expected}, got {got}"),
            CheckError::RejectCount {
                injected,
                before,
                after,
            } => write!(
                f,
                "injected {injected} corrupt frames but frames_rejected went from {before} to {after}"
            ),
            CheckError::Config(detail) => write!(f, "invalid check configuration: {detail}"),
        }
    }
}

impl std::error::Error for CheckError {}

impl From<LinkError> for CheckError {
    fn from(e: LinkError) -> Self {
        CheckError::Link(e)
    }
}

/// What the controller said in its `HelloAck`.
#[derive(Debug, Clone, PartialEq)]
pub struct Handshake {
    pub board_name: String,
    pub firmware_version: String,
    pub protocol_version: u16,
    pub control_rate_hz: u32,
    pub max_frame_len: u16,
    /// Error reports received before the `HelloAck` (leftovers of a previous session).
    pub stale_reports: u32,
}

/// Counts from an exchange.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ExchangeSummary {
    /// Data frames sent, each acknowledged and checked.
    pub data_frames: u64,
    pub camera_frames: u64,
    pub sensor_samples: u64,
    pub actuator_commands: u64,
    pub status_requests: u64,
    pub elapsed: Duration,
    pub bytes_sent: u64,
    pub bytes_received: u64,
    /// Time from sending a frame to receiving its reply (including the wait
    /// behind the frames in flight before it): median, 99th percentile, max.
    pub round_trip_p50: Duration,
    pub round_trip_p99: Duration,
    pub round_trip_max: Duration,
}

impl ExchangeSummary {
    /// Round trips (all frames) per second.
    pub fn frames_per_second(&self) -> f64 {
        let frames = (self.data_frames + self.status_requests) as f64;
        frames / self.elapsed.as_secs_f64().max(1e-9)
    }
}

/// Counts from a corruption run.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CorruptionSummary {
    /// Garbage runs (random non-zero bytes, then a delimiter) sent.
    pub garbage_runs: u32,
    /// Valid frames sent with one bit flipped.
    pub flipped_frames: u32,
    /// Runs of non-zero bytes longer than any frame, then a delimiter.
    pub oversized_runs: u32,
    /// Valid frames sent after each injection and acknowledged in order.
    pub recovered_acks: u32,
    pub rejected_before: u32,
    pub rejected_after: u32,
}
