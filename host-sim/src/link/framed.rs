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
    /// Decoded replies (or the decoder's refusals) not yet handed out, oldest first.
    inbox: VecDeque<Result<Message, String>>,
    bytes_sent: u64,
    bytes_received: u64,
    frames_rejected: u64,
}

impl<L: ByteLink> FramedLink<L> {
    pub fn new(link: L) -> Self {
        FramedLink {
            link,
            decoder: FrameDecoder::new(),
            inbox: VecDeque::new(),
            bytes_sent: 0,
            bytes_received: 0,
            frames_rejected: 0,
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

    /// The next reply, waiting at most `timeout`. A frame the decoder refuses
    /// is returned as [`LinkError::CorruptReply`] in its place among the
    /// replies (the replies after it are kept) and counted in
    /// [`Self::frames_rejected`].
    pub fn recv(&mut self, timeout: Duration, expecting: &str) -> Result<Message, LinkError> {
        let deadline = Instant::now() + timeout;
        let mut chunk = [0u8; RECV_CHUNK];
        loop {
            if let Some(reply) = self.inbox.pop_front() {
                return reply.map_err(LinkError::CorruptReply);
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
                    Some(Ok(message)) => self.inbox.push_back(Ok(message)),
                    Some(Err(e)) => {
                        self.frames_rejected += 1;
                        self.inbox.push_back(Err(e.to_string()));
                    }
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

    /// Frames from the controller the decoder refused so far.
    pub fn frames_rejected(&self) -> u64 {
        self.frames_rejected
    }

    /// The link under the framing (its counters, its switches).
    pub fn inner(&self) -> &L {
        &self.link
    }

    pub fn inner_mut(&mut self) -> &mut L {
        &mut self.link
    }

    /// Bytes sent and received so far.
    pub fn traffic(&self) -> (u64, u64) {
        (self.bytes_sent, self.bytes_received)
    }

    pub fn describe(&self) -> String {
        self.link.describe()
    }
}
