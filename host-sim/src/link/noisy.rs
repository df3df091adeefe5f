//! A noisy line between the host and the controller: every byte, in both
//! directions, is flipped (one random bit), dropped, or followed by an extra
//! random byte with a set probability, from a seeded generator per direction,
//! so a run is reproducible and the damage to a byte stream does not depend
//! on how the link chunks it (in process or over a socket).
//!
//! The link also checks itself. For each direction it runs two reference
//! decoders (`shared::protocol::FrameDecoder`): one on the bytes as they were
//! sent, one on the bytes as they arrived. Every message the second accepts
//! must be one of the messages the first decoded, in order (no corrupt frame
//! is ever taken for a message), and the second's refusals are the number of
//! rejections the receiver must report: the controller in telemetry
//! (`PickTelemetry::frames_rejected`), the host in
//! [`super::FramedLink::frames_rejected`].

use std::collections::VecDeque;
use std::time::Duration;

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use shared::protocol::{FrameDecoder, Message};

use super::{ByteLink, LinkError};

/// How noisy the line is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseConfig {
    /// Probability that a byte is damaged; the damage is a bit flip, a drop or
    /// an inserted byte, one third each.
    pub byte_error_rate: f64,
    pub seed: u64,
}

/// What one direction of the line did, and what its receiver must have seen.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct DirectionCounts {
    pub bytes: u64,
    pub flipped: u64,
    pub dropped: u64,
    pub inserted: u64,
    /// Frames as sent (decoded from the clean bytes).
    pub frames_sent: u64,
    /// Frames a decoder accepts from the damaged bytes.
    pub frames_delivered: u64,
    /// Frames a decoder refuses in the damaged bytes: what the receiver must count.
    pub frames_rejected: u64,
    /// Accepted frames that are not a message that was sent (must stay 0).
    pub forged: u64,
}

/// The controller's telemetry against the line's own count of the frames it
/// refused (`PickTelemetry::frames_rejected`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct TelemetryCheck {
    /// Telemetry messages the controller sent whose sample the line saw delivered.
    pub checked: u64,
    /// Those whose count differs from the refusals the damaged stream held
    /// before their sample was delivered. The in-process controller answers
    /// in order, so this must be 0 there; a board's link task may refuse more
    /// frames before its control loop reads the count, so there it may be
    /// higher, never lower.
    pub mismatched: u64,
    /// Those whose count is lower than the line's (frames refused and not counted).
    pub undercounted: u64,
}

impl DirectionCounts {
    pub fn damaged_bytes(&self) -> u64 {
        self.flipped + self.dropped + self.inserted
    }
}

/// Both directions' counts.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct NoiseCounts {
    pub to_controller: DirectionCounts,
    pub to_host: DirectionCounts,
    pub telemetry: TelemetryCheck,
}

/// Mixed into the seed of the controller-to-host direction's generator.
const TO_HOST_SEED_MIX: u64 = 0x9E37_79B9_7F4A_7C15;

/// Sensor samples delivered to the controller remembered for the telemetry check.
const REMEMBERED_SAMPLES: usize = 256;

/// One direction: the damage and its check.
struct Direction {
    rng: ChaCha8Rng,
    clean: FrameDecoder,
    damaged: FrameDecoder,
    /// Messages decoded from the clean bytes that no accepted frame has
    /// matched yet, oldest first.
    pending: VecDeque<Message>,
    counts: DirectionCounts,
}

impl Direction {
    fn new(rng: ChaCha8Rng) -> Self {
        Direction {
            rng,
            clean: FrameDecoder::new(),
            damaged: FrameDecoder::new(),
            pending: VecDeque::new(),
            counts: DirectionCounts::default(),
        }
    }

    /// Damages `bytes` into `out` (appended) and checks what arrives. Returns
    /// the messages as sent, and those delivered with the refusals before each.
    fn carry(
        &mut self,
        rate: f64,
        bytes: &[u8],
        out: &mut Vec<u8>,
    ) -> (Vec<Message>, Vec<(Message, u64)>) {
        let start = out.len();
        let mut sent = Vec::new();
        let mut delivered = Vec::new();
        for &byte in bytes {
            self.counts.bytes += 1;
            if let Some(Ok(message)) = self.clean.push(byte) {
                self.counts.frames_sent += 1;
                self.pending.push_back(message.clone());
                sent.push(message);
            }
            if rate > 0.0 && self.rng.random::<f64>() < rate {
                match self.rng.random_range(0..3u8) {
                    0 => {
                        self.counts.flipped += 1;
                        out.push(byte ^ (1u8 << self.rng.random_range(0..8u32)));
                    }
                    1 => self.counts.dropped += 1,
                    _ => {
                        self.counts.inserted += 1;
                        out.push(byte);
                        out.push(self.rng.random::<u8>());
                    }
                }
            } else {
                out.push(byte);
            }
        }
        for &byte in out.iter().skip(start) {
            match self.damaged.push(byte) {
                Some(Ok(message)) => {
                    self.deliver(&message);
                    delivered.push((message, self.counts.frames_rejected));
                }
                Some(Err(_)) => self.counts.frames_rejected += 1,
                None => {}
            }
        }
        (sent, delivered)
    }

    /// An accepted frame must be the next sent message or a later one (the
    /// ones in between were lost).
    fn deliver(&mut self, message: &Message) {
        self.counts.frames_delivered += 1;
        match self.pending.iter().position(|sent| sent == message) {
            Some(i) => {
                self.pending.drain(..=i);
            }
            None => self.counts.forged += 1,
        }
    }
}

/// A [`ByteLink`] that damages the bytes of another.
pub struct NoisyLink<L: ByteLink> {
    inner: L,
    config: NoiseConfig,
    enabled: bool,
    to_controller: Direction,
    to_host: Direction,
    /// Damaged bytes from the controller not yet handed to the caller.
    incoming: VecDeque<u8>,
    /// (time, refusals before it) of the sensor samples delivered to the controller.
    samples_delivered: VecDeque<(u64, u64)>,
    telemetry: TelemetryCheck,
}

impl<L: ByteLink> NoisyLink<L> {
    pub fn new(inner: L, config: NoiseConfig) -> Self {
        NoisyLink {
            inner,
            config,
            enabled: true,
            to_controller: Direction::new(ChaCha8Rng::seed_from_u64(config.seed)),
            to_host: Direction::new(ChaCha8Rng::seed_from_u64(config.seed ^ TO_HOST_SEED_MIX)),
            incoming: VecDeque::new(),
            samples_delivered: VecDeque::new(),
            telemetry: TelemetryCheck::default(),
        }
    }

    /// The link whose bytes are damaged.
    pub fn inner(&self) -> &L {
        &self.inner
    }

    /// The same, to change.
    pub fn inner_mut(&mut self) -> &mut L {
        &mut self.inner
    }

    /// Turns the noise off (bytes pass unharmed, still checked) or on again.
    pub fn set_enabled(&mut self, enabled: bool) {
        self.enabled = enabled;
    }

    pub fn counts(&self) -> NoiseCounts {
        NoiseCounts {
            to_controller: self.to_controller.counts,
            to_host: self.to_host.counts,
            telemetry: self.telemetry,
        }
    }

    /// The first delivery of each sample, with the refusals before it.
    fn on_delivered_to_controller(&mut self, delivered: Vec<(Message, u64)>) {
        for (message, refused_before) in delivered {
            let Message::SensorSample(sample) = message else {
                continue;
            };
            if self
                .samples_delivered
                .iter()
                .any(|(t, _)| *t == sample.time_us)
            {
                continue;
            }
            if self.samples_delivered.len() >= REMEMBERED_SAMPLES {
                self.samples_delivered.pop_front();
            }
            self.samples_delivered
                .push_back((sample.time_us, refused_before));
        }
    }

    /// Telemetry as the controller sent it, against the refusals before its sample.
    fn on_sent_by_controller(&mut self, sent: Vec<Message>) {
        for message in sent {
            let Message::Telemetry(telemetry) = message else {
                continue;
            };
            let Some(&(_, expected)) = self
                .samples_delivered
                .iter()
                .find(|(t, _)| *t == telemetry.time_us)
            else {
                continue;
            };
            let reported = u64::from(telemetry.frames_rejected);
            self.telemetry.checked += 1;
            if reported != expected {
                self.telemetry.mismatched += 1;
            }
            if reported < expected {
                self.telemetry.undercounted += 1;
            }
        }
    }

    fn rate(&self) -> f64 {
        if self.enabled {
            self.config.byte_error_rate
        } else {
            0.0
        }
    }
}

impl<L: ByteLink> ByteLink for NoisyLink<L> {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        let rate = self.rate();
        let mut out = Vec::with_capacity(bytes.len() + 4);
        let (_, delivered) = self.to_controller.carry(rate, bytes, &mut out);
        self.on_delivered_to_controller(delivered);
        self.inner.send(&out)
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        if self.incoming.is_empty() {
            let mut raw = vec![0u8; buf.len().max(1)];
            let n = self.inner.recv(&mut raw, timeout)?;
            let rate = self.rate();
            let mut out = Vec::with_capacity(n + 4);
            let (sent, _) = self
                .to_host
                .carry(rate, raw.get(..n).unwrap_or(&[]), &mut out);
            self.on_sent_by_controller(sent);
            self.incoming.extend(out);
        }
        let n = buf.len().min(self.incoming.len());
        for (slot, byte) in buf.iter_mut().zip(self.incoming.drain(..n)) {
            *slot = byte;
        }
        Ok(n)
    }

    fn describe(&self) -> String {
        format!(
            "{} through a noisy line ({:e} of the bytes damaged, seed {})",
            self.inner.describe(),
            self.config.byte_error_rate,
            self.config.seed
        )
    }

    fn replies_are_synchronous(&self) -> bool {
        self.inner.replies_are_synchronous()
    }

    fn noise(&self) -> Option<NoiseCounts> {
        Some(self.counts())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::{FramedLink, InProcessLink};
    use shared::protocol::PROTOCOL_VERSION;

    fn hello() -> Message {
        let mut peer_name = heapless::String::new();
        let _ = peer_name.push_str("noisy test");
        Message::Hello {
            protocol_version: PROTOCOL_VERSION,
            peer_name,
        }
    }

    #[test]
    fn a_clean_line_delivers_every_frame() {
        let config = NoiseConfig {
            byte_error_rate: 0.0,
            seed: 1,
        };
        let mut link = FramedLink::new(NoisyLink::new(InProcessLink::new(), config));
        for _ in 0..20 {
            link.send(&hello()).unwrap();
            assert!(matches!(
                link.recv(Duration::from_millis(10), "HelloAck").unwrap(),
                Message::HelloAck { .. }
            ));
        }
        let counts = link.inner().counts();
        assert_eq!(counts.to_controller.frames_sent, 20);
        assert_eq!(counts.to_controller.frames_delivered, 20);
        assert_eq!(counts.to_host.frames_delivered, 20);
        assert_eq!(counts.to_controller.damaged_bytes(), 0);
    }

    #[test]
    fn damage_is_refused_counted_and_never_forged() {
        let config = NoiseConfig {
            byte_error_rate: 0.02,
            seed: 7,
        };
        let mut link = FramedLink::new(NoisyLink::new(InProcessLink::new(), config));
        let mut acks = 0;
        let mut reports = 0;
        let mut refused_replies = 0;
        for _ in 0..2_000 {
            link.send(&hello()).unwrap();
            loop {
                match link.recv(Duration::from_millis(10), "reply") {
                    Ok(Message::HelloAck { .. }) => acks += 1,
                    Ok(Message::ErrorReport { .. }) => reports += 1,
                    Ok(other) => panic!("unexpected reply {other:?}"),
                    Err(LinkError::CorruptReply(_)) => refused_replies += 1,
                    Err(LinkError::Timeout { .. }) => break,
                    Err(e) => panic!("{e}"),
                }
            }
        }
        // The controller counts exactly the refusals the damaged stream
        // holds. On a clean line from here, its status comes after any reply
        // whose frame the damage had left open (the clean bytes close it).
        link.inner_mut().set_enabled(false);
        link.send(&Message::StatusRequest).unwrap();
        let status = loop {
            match link.recv(Duration::from_millis(10), "Status") {
                Ok(Message::Status(status)) => break status,
                Ok(Message::HelloAck { .. }) => acks += 1,
                Ok(Message::ErrorReport { .. }) => reports += 1,
                Ok(other) => panic!("expected Status, got {other:?}"),
                Err(LinkError::CorruptReply(_)) => refused_replies += 1,
                Err(e) => panic!("{e}"),
            }
        };
        let counts = link.inner().counts();
        for direction in [counts.to_controller, counts.to_host] {
            assert!(direction.damaged_bytes() > 100, "{direction:?}");
            assert!(direction.frames_rejected > 50, "{direction:?}");
            assert_eq!(direction.forged, 0, "{direction:?}");
            assert!(direction.frames_delivered < direction.frames_sent);
        }
        assert_eq!(refused_replies, counts.to_host.frames_rejected);
        assert_eq!(link.frames_rejected(), counts.to_host.frames_rejected);
        assert_eq!(acks + reports + 1, counts.to_host.frames_delivered);
        assert_eq!(
            u64::from(status.frames_rejected),
            counts.to_controller.frames_rejected
        );
    }
}
