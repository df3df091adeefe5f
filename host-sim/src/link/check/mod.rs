//! The link check: handshake, a long pipelined exchange of mixed frames in
//! which every acknowledgement is checked (kind, echoed token and the running
//! counter, in order), and corruption injection that checks the controller
//! rejects and counts bad frames and then carries on.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use shared::protocol::{
    ControllerStatus, Message, MessageKind, RuntimeReport, MAX_FRAME_LEN, PROTOCOL_VERSION,
};

use super::{ByteLink, FramedLink};

mod outcome;
mod traffic;

pub use outcome::{CheckError, CorruptionSummary, ExchangeSummary, Handshake};

use traffic::{bounded_string, data_frame, data_kind_token, encode, flip_one_bit, SplitMix64};

/// One `StatusRequest` is mixed in per this many frames of the exchange.
const STATUS_EVERY: u64 = 64;

/// A reply the controller owes, in order.
#[derive(Debug, Clone, PartialEq)]
enum Expected {
    Ack {
        kind: MessageKind,
        token: u32,
        counter: u32,
    },
    Status,
    /// The report for a rejected frame; `detail` is the running rejected count.
    Rejection {
        detail: u32,
    },
}

/// A protocol session with the controller.
pub struct Session<L: ByteLink> {
    link: FramedLink<L>,
    /// Data frames acknowledged in this session (the controller's counter).
    acks: u32,
    /// Next token for data frames.
    next_token: u32,
    reply_timeout: Duration,
    pub handshake: Handshake,
}

impl<L: ByteLink> Session<L> {
    /// Handshakes: a lone delimiter first ends whatever partial frame the
    /// controller may hold, then `Hello` must be answered by `HelloAck`.
    pub fn open(link: L, reply_timeout: Duration) -> Result<Self, CheckError> {
        let mut link = FramedLink::new(link);
        link.send_raw(&[0])?;
        link.send(&Message::Hello {
            protocol_version: PROTOCOL_VERSION,
            peer_name: bounded_string("host-sim"),
        })?;
        let mut stale_reports = 0;
        loop {
            match link.recv(reply_timeout, "HelloAck")? {
                Message::HelloAck {
                    protocol_version,
                    board_name,
                    firmware_version,
                    control_rate_hz,
                    max_frame_len,
                } => {
                    return Ok(Session {
                        link,
                        acks: 0,
                        next_token: 1,
                        reply_timeout,
                        handshake: Handshake {
                            board_name: board_name.as_str().to_string(),
                            firmware_version: firmware_version.as_str().to_string(),
                            protocol_version,
                            control_rate_hz,
                            max_frame_len,
                            stale_reports,
                        },
                    })
                }
                Message::ErrorReport { .. } if stale_reports < 4 => stale_reports += 1,
                other => {
                    return Err(CheckError::Unexpected {
                        index: 0,
                        expected: "HelloAck".to_string(),
                        got: format!("{other:?}"),
                    })
                }
            }
        }
    }

    pub fn describe(&self) -> String {
        self.link.describe()
    }

    /// The controller's status, asked for and awaited.
    pub fn status(&mut self) -> Result<ControllerStatus, CheckError> {
        self.link.send(&Message::StatusRequest)?;
        match self.link.recv(self.reply_timeout, "Status")? {
            Message::Status(status) => Ok(status),
            other => Err(CheckError::Unexpected {
                index: 0,
                expected: "Status".to_string(),
                got: format!("{other:?}"),
            }),
        }
    }

    /// The controller's runtime report (costs, stack, uptime), asked for and awaited.
    pub fn runtime_report(&mut self) -> Result<RuntimeReport, CheckError> {
        self.link.send(&Message::RuntimeReportRequest)?;
        match self.link.recv(self.reply_timeout, "RuntimeReport")? {
            Message::RuntimeReport(report) => Ok(report),
            other => Err(CheckError::Unexpected {
                index: 0,
                expected: "RuntimeReport".to_string(),
                got: format!("{other:?}"),
            }),
        }
    }

    /// Sends `frames` mixed frames (camera features, sensor samples, actuator
    /// commands, and a status request every `STATUS_EVERY` (64)), keeping at most
    /// `window` unanswered, and checks every reply in order.
    pub fn exchange(
        &mut self,
        frames: u64,
        window: usize,
        seed: u64,
    ) -> Result<ExchangeSummary, CheckError> {
        if window == 0 {
            return Err(CheckError::Config("window must be at least 1".into()));
        }
        let mut rng = SplitMix64(seed);
        let mut pending: VecDeque<(Expected, Instant)> = VecDeque::with_capacity(window);
        let mut round_trips: Vec<Duration> =
            Vec::with_capacity(usize::try_from(frames).unwrap_or(0));
        let mut summary = ExchangeSummary::default();
        let (sent0, received0) = self.link.traffic();
        let started = Instant::now();
        let mut sent = 0u64;
        let mut checked = 0u64;
        while checked < frames {
            while sent < frames && pending.len() < window {
                let (message, expected) = if sent % STATUS_EVERY == STATUS_EVERY - 1 {
                    summary.status_requests += 1;
                    (Message::StatusRequest, Expected::Status)
                } else {
                    let message = self.data_frame(&mut rng, &mut summary);
                    self.acks = self.acks.wrapping_add(1);
                    let (kind, token) = data_kind_token(&message);
                    (
                        message,
                        Expected::Ack {
                            kind,
                            token,
                            counter: self.acks,
                        },
                    )
                };
                self.link.send(&message)?;
                pending.push_back((expected, Instant::now()));
                sent += 1;
            }
            let (expected, sent_at) = pending
                .pop_front()
                .ok_or_else(|| CheckError::Config("nothing in flight".into()))?;
            let got = self.link.recv(self.reply_timeout, &describe(&expected))?;
            round_trips.push(sent_at.elapsed());
            check_reply(checked, &expected, &got)?;
            checked += 1;
        }
        summary.elapsed = started.elapsed();
        round_trips.sort_unstable();
        let quantile = |q: f64| -> Duration {
            let last = round_trips.len().saturating_sub(1);
            let at = ((last as f64) * q).round() as usize;
            round_trips.get(at).copied().unwrap_or_default()
        };
        summary.round_trip_p50 = quantile(0.5);
        summary.round_trip_p99 = quantile(0.99);
        summary.round_trip_max = quantile(1.0);
        let (sent1, received1) = self.link.traffic();
        summary.bytes_sent = sent1 - sent0;
        summary.bytes_received = received1 - received0;
        Ok(summary)
    }

    /// Injects `rounds` rounds of corruption: random non-zero garbage closed by
    /// a delimiter, a valid frame with one bit flipped (never into a
    /// delimiter), and a run longer than any frame, each followed by a valid
    /// frame. Every bad frame must be
    /// answered by an error report carrying the running rejected count, every
    /// valid one by its ack, and `Status.frames_rejected` must grow by exactly
    /// the number injected.
    pub fn inject_corruption(
        &mut self,
        rounds: u32,
        seed: u64,
    ) -> Result<CorruptionSummary, CheckError> {
        let mut rng = SplitMix64(seed);
        let rejected_before = self.status()?.frames_rejected;
        let mut rejected = rejected_before;
        let mut summary = CorruptionSummary {
            rejected_before,
            ..CorruptionSummary::default()
        };
        let mut scratch = ExchangeSummary::default();
        let mut index = 0u64;
        for _ in 0..rounds {
            // Garbage: 1..=200 random non-zero bytes, then the delimiter.
            let len = 1 + (rng.next() % 200) as usize;
            let mut garbage: Vec<u8> = (0..len).map(|_| 1 + (rng.next() % 255) as u8).collect();
            garbage.push(0);
            self.link.send_raw(&garbage)?;
            summary.garbage_runs += 1;
            rejected += 1;
            self.expect(index, &Expected::Rejection { detail: rejected })?;
            index += 1;
            self.send_checked_data(&mut rng, &mut scratch, &mut index)?;
            summary.recovered_acks += 1;

            // One flipped bit inside an otherwise valid frame.
            let message = self.data_frame(&mut rng, &mut scratch);
            let mut frame = encode(&message)?;
            flip_one_bit(&mut frame, &mut rng);
            self.link.send_raw(&frame)?;
            summary.flipped_frames += 1;
            rejected += 1;
            self.expect(index, &Expected::Rejection { detail: rejected })?;
            index += 1;
            self.send_checked_data(&mut rng, &mut scratch, &mut index)?;
            summary.recovered_acks += 1;

            // More non-zero bytes than the longest frame: the decoder must
            // drop them and resynchronise on the delimiter.
            let len = MAX_FRAME_LEN + 1 + (rng.next() % 200) as usize;
            let mut run: Vec<u8> = (0..len).map(|_| 1 + (rng.next() % 255) as u8).collect();
            run.push(0);
            self.link.send_raw(&run)?;
            summary.oversized_runs += 1;
            rejected += 1;
            self.expect(index, &Expected::Rejection { detail: rejected })?;
            index += 1;
            self.send_checked_data(&mut rng, &mut scratch, &mut index)?;
            summary.recovered_acks += 1;
        }
        summary.rejected_after = self.status()?.frames_rejected;
        let injected = summary.garbage_runs + summary.flipped_frames + summary.oversized_runs;
        if summary.rejected_after != rejected_before.wrapping_add(injected) {
            return Err(CheckError::RejectCount {
                injected,
                before: rejected_before,
                after: summary.rejected_after,
            });
        }
        Ok(summary)
    }

    /// Sends one valid data frame and checks its ack.
    fn send_checked_data(
        &mut self,
        rng: &mut SplitMix64,
        summary: &mut ExchangeSummary,
        index: &mut u64,
    ) -> Result<(), CheckError> {
        let message = self.data_frame(rng, summary);
        let (kind, token) = data_kind_token(&message);
        self.acks = self.acks.wrapping_add(1);
        self.link.send(&message)?;
        let expected = Expected::Ack {
            kind,
            token,
            counter: self.acks,
        };
        self.expect(*index, &expected)?;
        *index += 1;
        Ok(())
    }

    fn expect(&mut self, index: u64, expected: &Expected) -> Result<(), CheckError> {
        let got = self.link.recv(self.reply_timeout, &describe(expected))?;
        check_reply(index, expected, &got)
    }

    /// A random data frame with the next token.
    fn data_frame(&mut self, rng: &mut SplitMix64, summary: &mut ExchangeSummary) -> Message {
        let token = self.next_token;
        self.next_token = self.next_token.wrapping_add(1);
        data_frame(token, rng, summary)
    }
}

fn check_reply(index: u64, expected: &Expected, got: &Message) -> Result<(), CheckError> {
    let ok = match (expected, got) {
        (
            Expected::Ack {
                kind,
                token,
                counter,
            },
            Message::Ack {
                kind: k,
                token: t,
                counter: c,
            },
        ) => kind == k && token == t && counter == c,
        (Expected::Status, Message::Status(_)) => true,
        (Expected::Rejection { detail }, Message::ErrorReport { code, detail: d }) => {
            code.is_frame_refusal() && detail == d
        }
        _ => false,
    };
    if ok {
        Ok(())
    } else {
        Err(CheckError::Unexpected {
            index,
            expected: describe(expected),
            got: format!("{got:?}"),
        })
    }
}

fn describe(expected: &Expected) -> String {
    match expected {
        Expected::Ack {
            kind,
            token,
            counter,
        } => format!("Ack {{ kind: {kind:?}, token: {token}, counter: {counter} }}"),
        Expected::Status => "Status".to_string(),
        Expected::Rejection { detail } => {
            format!("ErrorReport for a rejected frame with detail {detail}")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::{InProcessLink, LinkError};

    /// Lets the check's own frames through, except that it drops or swaps
    /// one (each `send` of `FramedLink` carries exactly one frame).
    struct Tamper {
        inner: InProcessLink,
        sends: u64,
        at: u64,
        mode: TamperMode,
        held: Option<Vec<u8>>,
    }

    enum TamperMode {
        Drop,
        SwapWithNext,
    }

    impl ByteLink for Tamper {
        fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
            self.sends += 1;
            if self.sends == self.at {
                match self.mode {
                    TamperMode::Drop => return Ok(()),
                    TamperMode::SwapWithNext => {
                        self.held = Some(bytes.to_vec());
                        return Ok(());
                    }
                }
            }
            self.inner.send(bytes)?;
            if let Some(held) = self.held.take() {
                self.inner.send(&held)?;
            }
            Ok(())
        }

        fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
            self.inner.recv(buf, timeout)
        }

        fn describe(&self) -> String {
            "tampered in-process link".into()
        }

        fn replies_are_synchronous(&self) -> bool {
            true
        }
    }

    fn tampered(at: u64, mode: TamperMode) -> Session<Tamper> {
        let link = Tamper {
            inner: InProcessLink::new(),
            sends: 0,
            at,
            mode,
            held: None,
        };
        Session::open(link, Duration::from_millis(50)).expect("handshake")
    }

    #[test]
    fn clean_in_process_exchange_passes() {
        let mut session =
            Session::open(InProcessLink::new(), Duration::from_millis(50)).expect("handshake");
        let summary = session.exchange(2_000, 8, 7).expect("exchange");
        assert_eq!(summary.data_frames + summary.status_requests, 2_000);
        let corruption = session.inject_corruption(5, 9).expect("corruption");
        assert_eq!(corruption.rejected_after, corruption.rejected_before + 15);
    }

    #[test]
    fn a_lost_frame_fails_the_exchange() {
        // Sends 1 and 2 are the delimiter and Hello; frame 500 of the exchange is lost.
        let mut session = tampered(502, TamperMode::Drop);
        let err = session
            .exchange(2_000, 8, 7)
            .expect_err("a lost frame must be noticed");
        assert!(
            matches!(
                err,
                CheckError::Unexpected { .. } | CheckError::Link(LinkError::Timeout { .. })
            ),
            "{err}"
        );
    }

    #[test]
    fn reordered_frames_fail_the_exchange() {
        let mut session = tampered(302, TamperMode::SwapWithNext);
        let err = session
            .exchange(2_000, 8, 7)
            .expect_err("reordering must be noticed");
        assert!(matches!(err, CheckError::Unexpected { .. }), "{err}");
    }
}
