//! The link to the vision computer / simulator, at the middle priority: bytes
//! arrive in arbitrary chunks, `shared::protocol`'s `FrameDecoder` turns them
//! into messages, `shared::app::LinkResponder` keeps the session (handshake,
//! acknowledgements, status). Camera frames are paired with their trigger here
//! (the pick's frame pairer) and go to the worker as observations; sensor
//! samples go to the control loop (lock step); a cell configuration starts the
//! pick in all three tasks. Messages the control loop queued go out between
//! reads.

use core::future::{poll_fn, Future};
use core::pin::Pin;
use core::sync::atomic::Ordering;
use core::task::{Context, Poll};

use embassy_futures::select::{select, Either};
use embassy_time::Instant;
use embedded_io_async::{Read, Write};
use shared::app::pick::cell::Cell;
use shared::app::pick::handoff::{VisionNews, WorkItem};
use shared::app::pick::pairing::FramePairer;
use shared::app::{ConfigRefused, LinkResponder};
use shared::protocol::{
    encode_frame, CellConfig, DecodeError, FrameDecoder, Message, MAX_FRAME_LEN,
};

use super::channels::{
    Configured, COMMANDS, CONTROL_CONFIG, NEWS, OUTGOING, REPORTS, SAMPLES, TRIGGERS,
    TRIGGER_EVENTS, WORK, WORKER_CONFIG,
};
use super::control_loop::{CONTROL_RATE_HZ, LAST_HOST_FRAME_US, RECONFIGURE_REFUSAL};
use super::stats;
use crate::board::{active, ControlSource, CycleCounter};

/// Bytes taken from the UART per `read` at most.
const READ_CHUNK: usize = 64;

/// The link's state besides the UART.
struct Session {
    responder: LinkResponder,
    source: ControlSource,
    unit: shared::protocol::CostUnit,
    /// The pick's frame pairer and session number, once configured.
    pairer: Option<(u32, FramePairer)>,
    sessions: u32,
    /// (seq, time) of the last sample handed to the control loop.
    last_sample: Option<(u32, u64)>,
}

impl Session {
    /// Answers one decoded message (the reply, if any, to send back).
    fn on_message(&mut self, message: &Message) -> Option<Message> {
        let (ticks, misses) = stats::ticks_and_misses();
        self.responder.set_control_ticks(ticks);
        self.responder.set_deadline_misses(misses);
        let open = self.responder.session_open();
        match message {
            Message::Configure(config) if open => self.configure(config, message),
            Message::SensorSample(sample)
                if open && self.pairer.is_some() && self.source == ControlSource::LockStep =>
            {
                self.responder.count_received();
                // A copy of the sample still queued (the host sent it again
                // while the control loop waited, e.g. for a job's result) is
                // answered by the queued one's command: coalesce it. A copy of
                // one already taken goes on: the control loop answers it with
                // the same command, in case the first was lost.
                let copy = self.last_sample == Some((sample.seq, sample.time_us));
                let coalesced = copy && !SAMPLES.is_empty();
                if !coalesced {
                    if SAMPLES.try_send(*sample).is_err() {
                        stats::count_dropped_handoff();
                    }
                    self.last_sample = Some((sample.seq, sample.time_us));
                }
                None
            }
            // Running free, once configured: the newest state of the host's
            // plant, for the board's plant to read (`board::qemu::free_run`).
            // Before that a sample is a data frame like any other
            // (acknowledged, so `host-sim link-check` works on this board).
            #[cfg(feature = "free-run")]
            Message::SensorSample(sample)
                if open && self.pairer.is_some() && self.source == ControlSource::Ticker =>
            {
                self.responder.count_received();
                crate::board::active::free_run::deliver_state(sample);
                None
            }
            Message::CameraFeatures(frame) if open => {
                self.pair(frame);
                self.responder.handle(message)
            }
            Message::RuntimeReportRequest => Some(Message::RuntimeReport(stats::report(self.unit))),
            _ => self.responder.handle(message),
        }
    }

    /// Starts the pick for a new cell configuration (the acknowledgement),
    /// or refuses it: a bad field, or a cell not ready for one (the pick
    /// moving, the arm not at rest, a part in the gripper, the drives on: the
    /// control loop's last verdict, [`RECONFIGURE_REFUSAL`]; then nothing
    /// changes and the running pick goes on). Out of line: validating the
    /// configuration and building the pairer happen once a session, and
    /// their temporaries should not be on the stack for every other message.
    #[inline(never)]
    fn configure(&mut self, config: &CellConfig, message: &Message) -> Option<Message> {
        let refusal = RECONFIGURE_REFUSAL.load(Ordering::Relaxed);
        if refusal != 0 {
            self.responder.count_received();
            defmt::warn!(
                "link: configuration refused, cell not at rest ({=u32:#x})",
                refusal
            );
            return Some(Message::ErrorReport {
                code: shared::protocol::ErrorCode::ConfigurationRefusedActive,
                detail: refusal,
            });
        }
        match Cell::new(config) {
            Ok(_) => {
                self.sessions = self.sessions.wrapping_add(1);
                let configured = Configured {
                    config: *config,
                    session: self.sessions,
                };
                CONTROL_CONFIG.signal(configured);
                WORKER_CONFIG.signal(configured);
                match self.pairer.as_mut() {
                    Some((session, pairer)) => {
                        *session = self.sessions;
                        pairer.reconfigure(config);
                    }
                    None => first_pairer(&mut self.pairer, self.sessions, config),
                }
                self.responder.handle(message)
            }
            Err(error) => {
                self.responder.count_received();
                Some(ConfigRefused { error }.message())
            }
        }
    }

    /// Pairs a camera frame with its trigger; the observation goes to the
    /// worker, the news to the control loop. Out of line: the pairing's
    /// temporaries (the news and the observation, 650 bytes) are on the stack
    /// only for camera frames.
    #[inline(never)]
    fn pair(&mut self, frame: &shared::protocol::CameraFeatureFrame) {
        let Some((session, pairer)) = self.pairer.as_mut() else {
            return;
        };
        while let Ok(record) = TRIGGERS.try_receive() {
            pairer.on_trigger(&record);
        }
        let news = match pairer.on_frame(frame) {
            Ok(paired) => {
                if let Some(observation) = paired.observation {
                    if WORK
                        .try_send((*session, WorkItem::Observation(observation)))
                        .is_err()
                    {
                        stats::count_dropped_handoff();
                    }
                }
                paired.news
            }
            Err(_) => VisionNews::Unpaired,
        };
        if NEWS.try_send(news).is_err() {
            stats::count_dropped_handoff();
        }
    }
}

/// The pairer of the first configuration. Out of line: it builds the arm's
/// kinematics (2.3 KB, in a 2.7 KB frame) and the pairer around them on the
/// stack; it runs before the worker has ever had work, so never on top of the
/// bundle adjustment (later configurations reuse the pairer in place).
#[inline(never)]
fn first_pairer(slot: &mut Option<(u32, FramePairer)>, session: u32, config: &CellConfig) {
    *slot = Some((session, FramePairer::for_config(config)));
}

/// Feeds the decoder from `rest` until a frame ends (its message, or why it
/// was refused), taking the bytes it used. Out of line: the decoder's
/// temporaries (the un-stuffed payload and the message being deserialised)
/// are off the stack again when the message is answered.
#[inline(never)]
fn next_frame(
    decoder: &mut FrameDecoder,
    rest: &mut &[u8],
) -> Option<Result<Message, DecodeError>> {
    while let Some((&byte, after)) = rest.split_first() {
        *rest = after;
        if let Some(decoded) = decoder.push(byte) {
            return Some(decoded);
        }
    }
    None
}

/// Frames `message` into `frame`: the frame's length, 0 when it cannot be
/// encoded (logged). Out of line, with the decoding and answering below, so
/// that the encoder's and decoder's temporaries (a 324-byte payload, the
/// 312-byte `Message`) are on the stack only while they run, not in the task
/// poll's frame under every preemption of the worker.
#[inline(never)]
fn encode(message: &Message, frame: &mut [u8; MAX_FRAME_LEN]) -> usize {
    match encode_frame(message, frame) {
        Ok(len) => len,
        Err(e) => {
            defmt::error!("link: cannot encode: {}", e);
            0
        }
    }
}

/// The next message to send, framed into `frame` (its length): the period's
/// command first, then the camera triggers' events, then the period's other
/// messages, then the latest calibration report. Polled before the UART's read, so reads wait until all three are
/// empty; the message taken is encoded here and never crosses an await.
#[inline(never)]
fn poll_outgoing(cx: &mut Context<'_>, frame: &mut [u8; MAX_FRAME_LEN]) -> Poll<usize> {
    // Running free: the newest command for the host's plant goes first.
    #[cfg(feature = "free-run")]
    if let Poll::Ready(command) =
        Pin::new(&mut crate::board::active::free_run::PLANT_COMMANDS.wait()).poll(cx)
    {
        return Poll::Ready(encode(&Message::ActuatorCommand(command), frame));
    }
    if let Poll::Ready(command) = COMMANDS.poll_receive(cx) {
        return Poll::Ready(encode(&Message::ActuatorCommand(command), frame));
    }
    if let Poll::Ready(event) = TRIGGER_EVENTS.poll_receive(cx) {
        return Poll::Ready(encode(&Message::TriggerEvent(event), frame));
    }
    if let Poll::Ready(message) = OUTGOING.poll_receive(cx) {
        return Poll::Ready(encode(&message, frame));
    }
    // `Signal::wait` is a stateless poll function: a new one per poll is the
    // same as keeping one.
    if let Poll::Ready(report) = Pin::new(&mut REPORTS.wait()).poll(cx) {
        return Poll::Ready(encode(&Message::CalibrationReport(report), frame));
    }
    Poll::Pending
}

/// Decodes `bytes` until a frame ends in a reply: the reply is framed into
/// `frame`; returns its length (0: no reply, every byte taken) and the bytes
/// not yet taken.
#[inline(never)]
fn take_bytes<'a>(
    session: &mut Session,
    decoder: &mut FrameDecoder,
    bytes: &'a [u8],
    frame: &mut [u8; MAX_FRAME_LEN],
) -> (usize, &'a [u8]) {
    let mut rest = bytes;
    while let Some(decoded) = next_frame(decoder, &mut rest) {
        let reply = match decoded {
            Ok(message) => {
                LAST_HOST_FRAME_US.store(Instant::now().as_micros() as u32, Ordering::Relaxed);
                session.on_message(&message)
            }
            Err(e) => {
                defmt::warn!("link: frame rejected: {}", e);
                let report = session.responder.on_decode_error(&e);
                stats::FRAMES_REJECTED.store(
                    session.responder.status().frames_rejected,
                    Ordering::Relaxed,
                );
                Some(report)
            }
        };
        if let Some(reply) = reply {
            return (encode(&reply, frame), rest);
        }
    }
    (0, rest)
}

/// Writes one frame (nothing for an empty one).
async fn write_frame(serial: &mut active::Serial, frame: &[u8]) {
    if frame.is_empty() {
        return;
    }
    if let Err(e) = serial.write_all(frame).await {
        defmt::warn!("link write error {}", e);
    }
}

#[embassy_executor::task]
pub async fn link_task(
    board_name: &'static str,
    mut serial: active::Serial,
    source: ControlSource,
    cycles: active::Cycles,
) {
    let mut decoder = FrameDecoder::new();
    let mut session = Session {
        responder: LinkResponder::new(board_name, CONTROL_RATE_HZ),
        source,
        unit: cycles.cost_unit(),
        pairer: None,
        sessions: 0,
        last_sample: None,
    };
    let mut chunk = [0u8; READ_CHUNK];
    // The frame being written: every message goes out from here.
    let mut frame = [0u8; MAX_FRAME_LEN];
    defmt::info!("link up on {}", board_name);
    loop {
        let ready = select(
            poll_fn(|cx| poll_outgoing(cx, &mut frame)),
            serial.read(&mut chunk),
        )
        .await;
        let n = match ready {
            Either::First(len) => {
                write_frame(&mut serial, frame.get(..len).unwrap_or_default()).await;
                continue;
            }
            Either::Second(Ok(n)) => n,
            Either::Second(Err(e)) => {
                defmt::warn!("link read error {}", e);
                continue;
            }
        };
        let mut rest = chunk.get(..n).unwrap_or_default();
        while !rest.is_empty() {
            let (len, after) = take_bytes(&mut session, &mut decoder, rest, &mut frame);
            rest = after;
            write_frame(&mut serial, frame.get(..len).unwrap_or_default()).await;
        }
    }
}
