//! Protocol frames over any [`ByteLink`].

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use shared::protocol::{encode_frame, FrameDecoder, Message, MAX_FRAME_LEN};

use super::{ByteLink, LinkError};

/// Bytes read from the link per `recv` call at most.
const RECV_CHUNK: usize = 4096;

pub struct FramedLink<L: ByteLink> {
    link: L,
    decoder: FrameDecoder,
    /// Decoded replies not yet handed out, oldest first.
    inbox: VecDeque<Message>,
    bytes_sent: u64,
    bytes_received: u64,
}

impl<L: ByteLink> FramedLink<L> {
    pub fn new(link: L) -> Self {
        FramedLink {
            link,
            decoder: FrameDecoder::new(),
            inbox: VecDeque::new(),
            bytes_sent: 0,
            bytes_received: 0,
        }
    }

    /// Frames and sends one message.
    pub fn send(&mut self, message: &Message) -> Result<(), LinkError> {
        let mut frame = [0u8; MAX_FRAME_LEN];
        let len =
            encode_frame(message, &mut frame).map_err(|e| LinkError::Encode(e.to_string()))?;
        let bytes = frame
            .get(..len)
            .ok_or_else(|| LinkError::Encode(format!("encoder reported {len} bytes")))?;
        self.send_raw(bytes)
    }

    /// Sends bytes as they are (for corruption tests).
    pub fn send_raw(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        self.bytes_sent += bytes.len() as u64;
        self.link.send(bytes)
    }

    /// The next reply, waiting at most `timeout`.
    pub fn recv(&mut self, timeout: Duration, expecting: &str) -> Result<Message, LinkError> {
        let deadline = Instant::now() + timeout;
        let mut chunk = [0u8; RECV_CHUNK];
        loop {
            if let Some(message) = self.inbox.pop_front() {
                return Ok(message);
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(LinkError::Timeout {
                    waited: timeout,
                    expecting: expecting.to_string(),
                });
            }
            let n = self.link.recv(&mut chunk, left)?;
            self.bytes_received += n as u64;
            for &byte in chunk.iter().take(n) {
                match self.decoder.push(byte) {
                    Some(Ok(message)) => self.inbox.push_back(message),
                    Some(Err(e)) => return Err(LinkError::CorruptReply(e.to_string())),
                    None => {}
                }
            }
            if n == 0 && self.inbox.is_empty() && self.link.replies_are_synchronous() {
                return Err(LinkError::Timeout {
                    waited: timeout,
                    expecting: expecting.to_string(),
                });
            }
        }
    }

    /// Bytes sent and received so far.
    pub fn traffic(&self) -> (u64, u64) {
        (self.bytes_sent, self.bytes_received)
    }

    pub fn describe(&self) -> String {
        self.link.describe()
    }
}
