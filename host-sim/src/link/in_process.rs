//! The controller application linked into this process: bytes sent are decoded
//! and answered by `shared::app::ControllerApp` (the protocol session and, once
//! configured, the pick) exactly as the firmware does, and the framed replies
//! are queued for `recv`. Background work (self-calibration, planning) runs
//! right after each message; the pick applies its results after a fixed
//! simulated delay, so a run does not depend on this computer's speed.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use shared::app::{ControllerApp, MAX_REPLIES};
use shared::protocol::{encode_frame, FrameDecoder, MAX_FRAME_LEN};

use super::{ByteLink, LinkError};

/// The control rate the in-process controller reports (the firmware's default;
/// in lock step the plant's rate is the scenario's).
pub const IN_PROCESS_CONTROL_RATE_HZ: u32 = 1_000;

pub struct InProcessLink {
    decoder: FrameDecoder,
    app: ControllerApp,
    replies: VecDeque<u8>,
    /// Control ticks are wall-clock milliseconds since the link was made,
    /// standing in for the firmware's 1 kHz tick task.
    started: Instant,
}

impl InProcessLink {
    pub fn new() -> Self {
        InProcessLink {
            decoder: FrameDecoder::new(),
            app: ControllerApp::new("in-process", IN_PROCESS_CONTROL_RATE_HZ),
            replies: VecDeque::new(),
            started: Instant::now(),
        }
    }
}

impl Default for InProcessLink {
    fn default() -> Self {
        Self::new()
    }
}

impl ByteLink for InProcessLink {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        let mut frame = [0u8; MAX_FRAME_LEN];
        for &byte in bytes {
            let Some(decoded) = self.decoder.push(byte) else {
                continue;
            };
            let mut replies: heapless::Vec<_, MAX_REPLIES> = heapless::Vec::new();
            match decoded {
                Ok(message) => {
                    if self.app.pick().is_none() {
                        let ticks = self.started.elapsed().as_millis();
                        self.app
                            .link_mut()
                            .set_control_ticks(u64::try_from(ticks).unwrap_or(u64::MAX));
                    }
                    self.app.on_message(&message, &mut replies);
                    self.app.run_background();
                }
                Err(e) => {
                    let _ = replies.push(self.app.on_decode_error(&e));
                }
            }
            for reply in &replies {
                let len = encode_frame(reply, &mut frame)
                    .map_err(|e| LinkError::Encode(e.to_string()))?;
                self.replies.extend(frame.iter().take(len));
            }
        }
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], _timeout: Duration) -> Result<usize, LinkError> {
        // Replies are produced synchronously by `send`: nothing more will
        // arrive by waiting.
        let n = buf.len().min(self.replies.len());
        for (slot, byte) in buf.iter_mut().zip(self.replies.drain(..n)) {
            *slot = byte;
        }
        Ok(n)
    }

    fn replies_are_synchronous(&self) -> bool {
        true
    }

    fn describe(&self) -> String {
        "in-process controller (shared::app::ControllerApp)".to_string()
    }
}
