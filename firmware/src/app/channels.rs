//! The hand-offs between the firmware's tasks. Every one is a critical-section
//! channel or signal that the control loop only ever `try_`s (it never waits
//! on another task, except in lock step for a job result that is due, see
//! `control_loop`). Capacities are sized for lock step, where the host sends
//! one period's frames and then waits for the actuator command, and are
//! counted when a real-time run overflows them (`RuntimeReport`). The most
//! each queue held in the emulated pick (experiment 2, 63,000 periods, three
//! jobs) is given with it; the other emulated runs (faults, noisy line) pass
//! at these capacities too. The queued items are large (a `Message` is 312
//! bytes, a `WorkItem` 304, a `VisionNews` 352), so every slot is RAM the
//! 64 KiB goal counts.

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_sync::signal::Signal;
use shared::app::pick::handoff::{TriggerRecord, VisionNews, WorkItem};
use shared::protocol::{
    ActuatorCommand, CalibrationReport, CellConfig, Message, SensorSample, TriggerEvent,
};

type Raw = CriticalSectionRawMutex;

/// A cell configuration accepted by the link, for the task that builds its
/// part of the pick.
#[derive(Clone, Copy)]
pub struct Configured {
    pub config: CellConfig,
    pub session: u32,
}

/// Link -> control loop: a new cell configuration.
pub static CONTROL_CONFIG: Signal<Raw, Configured> = Signal::new();
/// Link -> worker: a new cell configuration.
pub static WORKER_CONFIG: Signal<Raw, Configured> = Signal::new();
/// Link -> control loop (lock step): one sensor sample per control period.
pub static SAMPLES: Channel<Raw, SensorSample, 2> = Channel::new();
/// Control loop -> link (frame pairer): the encoders latched at a trigger.
pub static TRIGGERS: Channel<Raw, TriggerRecord, 8> = Channel::new();
/// Link (observations) and control loop (jobs) -> worker, in order, with the
/// session they belong to. The observations of the frames that arrive while
/// a job runs wait here: an estimate's result is due after 1 s, five frames
/// at the camera's 5 Hz, and in lock step the host waits then (5 at most in
/// the emulated pick). 8 slots are 1.6 s of frames; a real-time job that runs
/// longer drops the later observations (counted), as 16 slots did after
/// 3.2 s.
pub static WORK: Channel<Raw, (u32, WorkItem), 8> = Channel::new();
/// Link (pairings) and worker (refusals, job results) -> control loop, which
/// empties it every period: a pairing per camera frame, a result per job (1 at
/// most in the emulated pick). A pairing or refusal that finds it full is
/// dropped (counted); a job's result waits for room.
pub static NEWS: Channel<Raw, VisionNews, 4> = Channel::new();
/// Worker -> control loop: news is waiting (a job result, or the news queue
/// filled up while the control loop waited for a result).
pub static NEWS_READY: Signal<Raw, ()> = Signal::new();
/// Control loop -> link: telemetry and the other messages of a period, at
/// most `MAX_TICK_MESSAGES` (3) a period. The link sends them before it reads
/// again, so in lock step the queue is empty when the next sample arrives (1
/// at most in the emulated pick).
pub static OUTGOING: Channel<Raw, Message, 4> = Channel::new();
/// Control loop -> link (lock step): the period's actuator command, which the
/// link sends before anything in `OUTGOING` (a 40-byte hand-over: queueing it
/// as a 320-byte `Message` cost the control period about 500 instructions).
pub static COMMANDS: Channel<Raw, ActuatorCommand, 2> = Channel::new();
/// Control loop -> link (ticker): each camera trigger's id and instant, for
/// the vision side, sent before anything in `OUTGOING` (a 16-byte hand-over;
/// at most one a camera period, 5 a second in the pick).
pub static TRIGGER_EVENTS: Channel<Raw, TriggerEvent, 4> = Channel::new();
/// Control loop -> link: the latest calibration report, which the link
/// sends as a message (composing and queueing the 320-byte `Message` in the
/// control period cost 1,200 instructions; this is a 72-byte hand-over). A
/// report not yet taken is replaced by a newer one.
pub static REPORTS: Signal<Raw, CalibrationReport> = Signal::new();
