//! The controller's link logic linked into this process: bytes sent are decoded
//! and answered by `shared::app::LinkResponder` exactly as the firmware's link
//! task does, and the framed replies are queued for `recv`.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use shared::app::LinkResponder;
use shared::protocol::{encode_frame, FrameDecoder, MAX_FRAME_LEN};

use super::{ByteLink, LinkError};

/// The control rate the in-process controller reports (the firmware's).
pub const IN_PROCESS_CONTROL_RATE_HZ: u32 = 1_000;

pub struct InProcessLink {
    decoder: FrameDecoder,
    responder: LinkResponder,
    replies: VecDeque<u8>,
    /// Control ticks are wall-clock milliseconds since the link was made,
    /// standing in for the firmware's 1 kHz tick task.
    started: Instant,
}

impl InProcessLink {
    pub fn new() -> Self {
        InProcessLink {
            decoder: FrameDecoder::new(),
            responder: LinkResponder::new("in-process", IN_PROCESS_CONTROL_RATE_HZ),
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
            let reply = match decoded {
                Ok(message) => {
                    let ticks = self.started.elapsed().as_millis();
                    self.responder
                        .set_control_ticks(u64::try_from(ticks).unwrap_or(u64::MAX));
                    self.responder.handle(&message)
                }
                Err(e) => Some(self.responder.on_decode_error(&e)),
            };
            if let Some(reply) = reply {
                let len = encode_frame(&reply, &mut frame)
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
        "in-process controller (shared::app::LinkResponder)".to_string()
    }
}
