//! Links from the host to the controller, behind one byte-level trait
//! ([`ByteLink`]) so the same framing ([`FramedLink`]) and the same checks
//! ([`check`]) run over all three:
//!
//! - [`InProcessLink`]: `shared::app::LinkResponder` linked into this process
//!   (no emulator, no board) answering exactly as the firmware's link task does;
//! - [`TcpLink`]: the emulated board's UART0, which QEMU serves on a TCP socket;
//! - [`SerialPortLink`]: a real serial device (the STM32F407's USART2).
//!
//! The integration tests (`tests/tests/emulator_link.rs`) run the same checks.

pub mod board_timing;
pub mod check;
mod framed;
mod in_process;
mod noisy;
mod serial;
mod tcp;
pub mod worker_tap;

use std::fmt;
use std::time::Duration;

pub use board_timing::BoardTiming;
pub use framed::FramedLink;
pub use in_process::InProcessLink;
pub use noisy::{DirectionCounts, NoiseConfig, NoiseCounts, NoisyLink, TelemetryCheck};
pub use serial::SerialPortLink;
pub use tcp::TcpLink;
pub use worker_tap::{EstimateJob, WorkerLog, WorkerTap};

/// A bidirectional byte stream to the controller.
pub trait ByteLink {
    /// Sends all of `bytes`.
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError>;

    /// Receives what is available, waiting at most `timeout` for the first
    /// byte. `Ok(0)` means the timeout passed with nothing received.
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError>;

    /// What this link connects to, for messages.
    fn describe(&self) -> String;

    /// Whether every reply is already available when `send` returns (so an
    /// empty `recv` means none will come and waiting is pointless).
    fn replies_are_synchronous(&self) -> bool {
        false
    }

    /// What a noise injector on this link did ([`NoisyLink`]); `None` for a
    /// clean link.
    fn noise(&self) -> Option<NoiseCounts> {
        None
    }
}

/// What went wrong on a link.
#[derive(Debug)]
pub enum LinkError {
    /// The operating system refused an operation on the link.
    Io {
        what: &'static str,
        source: std::io::Error,
    },
    /// The serial device could not be opened or configured.
    Serial { path: String, detail: String },
    /// The peer closed the link.
    Closed,
    /// No complete reply arrived within the timeout.
    Timeout { waited: Duration, expecting: String },
    /// A message could not be framed for sending.
    Encode(String),
    /// A frame from the controller failed to decode.
    CorruptReply(String),
}

impl fmt::Display for LinkError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LinkError::Io { what, source } => write!(f, "link I/O error while {what}: {source}"),
            LinkError::Serial { path, detail } => {
                write!(f, "serial device {path}: {detail}")
            }
            LinkError::Closed => write!(f, "the controller closed the link"),
            LinkError::Timeout { waited, expecting } => {
                write!(f, "no reply within {waited:?} while expecting {expecting}")
            }
            LinkError::Encode(detail) => write!(f, "cannot frame message: {detail}"),
            LinkError::CorruptReply(detail) => {
                write!(f, "corrupt frame from the controller: {detail}")
            }
        }
    }
}

impl std::error::Error for LinkError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            LinkError::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}
