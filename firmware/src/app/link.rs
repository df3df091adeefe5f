//! The link to the vision computer / simulator, at the middle priority: bytes
//! arrive in arbitrary chunks, `shared::protocol`'s `FrameDecoder` turns them
//! into messages, `shared::app::LinkResponder` keeps the session (handshake,
//! acknowledgements, status). Camera frames are paired with their trigger here
//! (the pick's frame pairer) and go to the worker as observations; sensor
//! samples go to the control loop (lock step); a cell configuration starts the
//! pick in all three tasks. Messages the control loop queued go out between
//! reads.

use core::sync::atomic::Ordering;

use embassy_futures::select::{select4, Either4};
use embassy_time::Instant;
use embedded_io_async::{Read, Write};
use shared::app::pick::cell::Cell;
use shared::app::pick::handoff::{VisionNews, WorkItem};
use shared::app::pick::pairing::FramePairer;
use shared::app::{ConfigRefused, LinkResponder};
use shared::protocol::{encode_frame, FrameDecoder, Message, MAX_FRAME_LEN};

use super::channels::{
    Configured, COMMANDS, CONTROL_CONFIG, NEWS, OUTGOING, REPORTS, SAMPLES, TRIGGERS, WORK,
    WORKER_CONFIG,
};
use super::control_loop::{CONTROL_RATE_HZ, LAST_HOST_FRAME_US};
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
            Message::Configure(config) if open => match Cell::new(config) {
                Ok(_) => {
                    self.sessions = self.sessions.wrapping_add(1);
                    let configured = Configured {
                        config: *config,
                        session: self.sessions,
                    };
                    CONTROL_CONFIG.signal(configured);
                    WORKER_CONFIG.signal(configured);
                    self.pairer = Some((self.sessions, FramePairer::for_config(config)));
                    self.responder.handle(message)
                }
                Err(error) => {
                    self.responder.count_received();
                    Some(ConfigRefused { error }.message())
                }
            },
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
            Message::CameraFeatures(frame) if open => {
                self.pair(frame);
                self.responder.handle(message)
            }
            Message::RuntimeReportRequest => Some(Message::RuntimeReport(stats::report(self.unit))),
            _ => self.responder.handle(message),
        }
    }

    /// Pairs a camera frame with its trigger; the observation goes to the
    /// worker, the news to the control loop.
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

/// Frames and writes one message.
async fn write_message(serial: &mut active::Serial, message: &Message) {
    let mut frame = [0u8; MAX_FRAME_LEN];
    let bytes = match encode_frame(message, &mut frame) {
        Ok(len) => frame.get(..len),
        Err(e) => {
            defmt::error!("link: cannot encode: {}", e);
            None
        }
    };
    if let Some(bytes) = bytes {
        if let Err(e) = serial.write_all(bytes).await {
            defmt::warn!("link write error {}", e);
        }
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
    defmt::info!("link up on {}", board_name);
    loop {
        // The period's command first, then its other messages, then reports.
        let outgoing = select4(
            COMMANDS.receive(),
            OUTGOING.receive(),
            REPORTS.wait(),
            serial.read(&mut chunk),
        );
        let n = match outgoing.await {
            Either4::First(command) => {
                write_message(&mut serial, &Message::ActuatorCommand(command)).await;
                continue;
            }
            Either4::Second(message) => {
                write_message(&mut serial, &message).await;
                continue;
            }
            Either4::Third(report) => {
                write_message(&mut serial, &Message::CalibrationReport(report)).await;
                continue;
            }
            Either4::Fourth(Ok(n)) => n,
            Either4::Fourth(Err(e)) => {
                defmt::warn!("link read error {}", e);
                continue;
            }
        };
        for &byte in chunk.iter().take(n) {
            let Some(decoded) = decoder.push(byte) else {
                continue;
            };
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
                write_message(&mut serial, &reply).await;
            }
        }
    }
}
