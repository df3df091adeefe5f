//! The controller application linked into this process: bytes sent are decoded
//! and answered by `shared::app::ControllerApp` (the protocol session and, once
//! configured, the pick) exactly as the firmware does, and the framed replies
//! are queued for `recv`. Background work (self-calibration, planning) runs
//! right after each message; the pick applies its results after a fixed
//! simulated delay, so a run does not depend on this computer's speed.
//!
//! With [`InProcessLink::with_board_timing`] the worker is instead a board's:
//! its items are queued as the firmware's worker task takes them (eight at
//! most), and each job's result comes when a 168 MHz Cortex-M4F would have
//! finished it ([`super::board_timing`]), on the plant's clock: late, as on
//! the STM32F407 running on its own ticker.
//!
//! With [`InProcessLink::recording_worker`] every item the worker takes is
//! also shown to a [`WorkerTap`] (the pick's own observation log). Without a
//! board's timing the items are then queued and run right after each message,
//! as the unqueued application runs them (observations in the message,
//! jobs after it): the run is the same, which the tests check.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use shared::app::pick::handoff::{VisionNews, WorkItem};
use shared::app::power_on_homing::HomingStage;
use shared::app::{ControllerApp, MAX_REPLIES};
use shared::protocol::{encode_frame, FrameDecoder, Message, MessageKind, MAX_FRAME_LEN};

use super::board_timing::BoardTiming;
use super::worker_tap::WorkerTap;
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
    /// The board's worker, when its jobs take a board's time.
    board: Option<BoardWorker>,
    /// What the worker is given, when asked to record it.
    tap: Option<WorkerTap>,
}

/// A board's worker on the plant's clock: busy with one item at a time.
struct BoardWorker {
    timing: BoardTiming,
    /// The job being computed: its news and when it is done, microseconds.
    running: Option<(u64, Option<VisionNews>)>,
    /// When the worker was last done.
    free_at_us: u64,
    /// The newest sample's time: the plant's clock here.
    now_us: u64,
}

impl InProcessLink {
    pub fn new() -> Self {
        InProcessLink {
            decoder: FrameDecoder::new(),
            app: ControllerApp::new("in-process", IN_PROCESS_CONTROL_RATE_HZ),
            replies: VecDeque::new(),
            started: Instant::now(),
            board: None,
            tap: None,
        }
    }

    /// The same controller with every item its worker takes shown to a
    /// [`WorkerTap`] first ([`InProcessLink::worker_tap`]). Without a
    /// board's timing the application queues its worker's items and this
    /// link runs them right after each message.
    pub fn recording_worker(mut self) -> Self {
        if self.board.is_none() {
            self.app = ControllerApp::with_queued_work("in-process", IN_PROCESS_CONTROL_RATE_HZ);
        }
        self.tap = Some(WorkerTap::new());
        self
    }

    /// What the worker was given, when recorded.
    pub fn worker_tap(&self) -> Option<&WorkerTap> {
        self.tap.as_ref()
    }

    /// The tap, taken out of the link.
    pub fn take_worker_tap(&mut self) -> Option<WorkerTap> {
        self.tap.take()
    }

    /// Runs the worker on everything queued, delivering each news at once
    /// (a recording link without a board's timing).
    fn run_queued_now(&mut self) {
        while let Some(item) = self.app.next_work() {
            if let Some(tap) = self.tap.as_mut() {
                tap.before(&item);
            }
            let news = self.app.process_work(&item);
            if let Some(tap) = self.tap.as_mut() {
                tap.after(&item, news.as_ref());
            }
            if let Some(news) = news {
                self.app.deliver(&news);
            }
        }
    }

    /// The controller with its jobs' results delayed by what they cost on a
    /// board (`timing`), on the plant's clock.
    pub fn with_board_timing(timing: BoardTiming) -> Self {
        InProcessLink {
            app: ControllerApp::with_queued_work(
                "in-process-board-timing",
                IN_PROCESS_CONTROL_RATE_HZ,
            ),
            board: Some(BoardWorker {
                timing,
                running: None,
                free_at_us: 0,
                now_us: 0,
            }),
            ..Self::new()
        }
    }

    /// Runs the board's worker up to `now_us`: results whose job is done by
    /// then are delivered, and the worker takes its next items, each
    /// computed when it starts and delivered when the board would be done
    /// with it. An observation costs nothing here (its share of the board's
    /// time is small beside a job's and is not modelled).
    fn advance_worker(&mut self, now_us: u64) {
        let Some(board) = self.board.as_mut() else {
            return;
        };
        board.now_us = board.now_us.max(now_us);
        loop {
            if let Some((done_us, news)) = board.running.take() {
                if done_us > board.now_us {
                    board.running = Some((done_us, news));
                    return;
                }
                if let Some(news) = news {
                    self.app.deliver(&news);
                }
                board.free_at_us = done_us;
            }
            let Some(item) = self.app.next_work() else {
                return;
            };
            // Items are looked at once a control period: one that waited
            // for a busy worker starts within a period of it being free.
            let start_us = board.free_at_us.max(board.now_us);
            if let Some(tap) = self.tap.as_mut() {
                tap.before(&item);
            }
            let news = self.app.process_work(&item);
            if let Some(tap) = self.tap.as_mut() {
                tap.after(&item, news.as_ref());
            }
            let cost_us = match &item {
                WorkItem::Job(ticket) => board.timing.job_us(&ticket.request),
                WorkItem::Observation(_) => 0,
            };
            board.running = Some((start_us.saturating_add(cost_us), news));
        }
    }

    /// The answer to a runtime-report request, with what this process knows
    /// of the pick: its late results and the worker items dropped.
    fn patch_report(&self, reply: &mut Message) {
        if let (Message::RuntimeReport(report), Some(pick)) = (reply, self.app.pick()) {
            report.late_results = pick.counters().late_results;
            report.handoffs_dropped = self.app.work_dropped();
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
                    if let Message::SensorSample(sample) = &message {
                        self.advance_worker(sample.time_us);
                        // Homed (or asked for no homing): the sample is the pick's.
                        let to_pick = self.app.pick().is_some()
                            && matches!(
                                self.app.homing_stage(),
                                None | Some(HomingStage::Homed(_))
                            );
                        if let (true, Some(tap)) = (to_pick, self.tap.as_mut()) {
                            tap.pick_sample(sample.time_us);
                        }
                    }
                    self.app.on_message(&message, &mut replies);
                    if let (Message::Configure(config), Some(tap)) = (&message, self.tap.as_mut()) {
                        let accepted = replies.iter().any(|reply| {
                            matches!(
                                reply,
                                Message::Ack {
                                    kind: MessageKind::Configure,
                                    ..
                                }
                            )
                        });
                        if accepted {
                            tap.configured(config);
                        }
                    }
                    match (&self.board, &self.tap) {
                        (Some(board), _) => {
                            let now_us = board.now_us;
                            self.advance_worker(now_us);
                        }
                        (None, Some(_)) => self.run_queued_now(),
                        (None, None) => self.app.run_background(),
                    }
                }
                Err(e) => {
                    let _ = replies.push(self.app.on_decode_error(&e));
                }
            }
            for reply in replies.iter_mut() {
                self.patch_report(reply);
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
        match &self.board {
            Some(board) => format!(
                "in-process controller (shared::app::ControllerApp), jobs timed as on {}",
                board.timing.describe()
            ),
            None => "in-process controller (shared::app::ControllerApp)".to_string(),
        }
    }
}
