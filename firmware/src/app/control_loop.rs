//! The control loop, at the highest priority: once per period it takes a
//! sensor sample (on a ticker the board's encoders, latched with the camera
//! trigger's edge when the period fires the camera; in lock step the
//! simulator's frame), runs the pick's control part (fusion Eq 1, the state
//! machine, Eq 23), and drives the outputs (the board's servos and gripper,
//! or an actuator-command frame in lock step); on a ticker it tells the
//! vision side each trigger's id (`TriggerEvent`). It hands triggers to
//! the link's frame pairer and jobs to the worker without ever waiting for
//! them, and measures its own cost.
//!
//! Supervisor duties here: a watchdog on the link (ticker mode: no valid frame
//! from the vision computer for [`LINK_TIMEOUT_US`] stops the arm), vision
//! staleness and the tracking, torque and speed checks inside the pick; any
//! fault ends in the pick's controlled stop, reported in telemetry.
//!
//! Behind them, where torques go out, the drive interlock
//! ([`shared::safety::DriveInterlock`]): every period the pick's torques,
//! the joint positions and speeds from the sample's encoder counts alone, and
//! whether the pick is braking decide whether the drives may be on. A trip,
//! or a board fault latched by a handler ([`crate::board::fail_safe`]), turns
//! the drives off (ticker: `PlantIo::disable`; lock step: zero torques in the
//! actuator command) and keeps them off, period after period, until the host
//! acknowledges by sending a configuration that is accepted (which also
//! restarts the pick).

use core::sync::atomic::{AtomicU32, Ordering};

use embassy_time::{Duration, Instant, Ticker};
use heapless::Vec;
use shared::app::new_report;
use shared::app::pick::handoff::{ControlEvent, WorkItem};
use shared::app::pick::settings::PickSettings;
use shared::app::pick::{PickController, MAX_TICK_MESSAGES};
use shared::app::power_on_homing;
use shared::protocol::{
    FaultCause, GripperCommand, Message, PickPhase, SensorSample, TriggerEvent,
};
use shared::safety::{
    check_reconfigure, BoardFault, CellState, DeadlineMonitor, DriveInterlock, EncoderMotion,
    InterlockFault, InterlockOutput, ParkState, Parking, ParkingInput, ParkingOutput, PeriodInput,
    REST_SPEED_RAD_S,
};

use super::channels::{
    Configured, COMMANDS, CONTROL_CONFIG, NEWS, NEWS_READY, OUTGOING, REPORTS, SAMPLES, TRIGGERS,
    TRIGGER_EVENTS, WORK,
};
use super::homing::Homing;
use super::phase_log;
use super::stats;
use crate::board::{active, fail_safe, BoardError, ControlSource, CycleCounter, PlantIo, Watchdog};

// `CONTROL_RATE_HZ`: the ticker's rate on a real board, the period a
// deadline is counted against, and the rate `HelloAck` reports. Set at build
// time with `FIRMWARE_CONTROL_RATE_HZ` (1,000 to 10,000 Hz, default 1,000; see
// build.rs). The pick's timing is in seconds, taken from the samples' time
// stamps, so in lock step the plant's rate is the host's.
include!(concat!(env!("OUT_DIR"), "/control_rate.rs"));

/// Ticker mode: the arm stops when no valid frame came from the vision
/// computer for this long.
pub const LINK_TIMEOUT_US: u32 = 500_000;

/// Time of the last valid frame from the host, microseconds modulo 2^32
/// (written by the link task; compared with wrapping arithmetic, which is
/// exact for gaps under 71 minutes).
pub static LAST_HOST_FRAME_US: AtomicU32 = AtomicU32::new(0);
/// Whether a new configuration may replace the pick, as of the last period:
/// 0 when it may, otherwise the refusal's detail
/// (`shared::safety::ReconfigureRefusal::detail`, never 0). Written by the
/// control loop every period, read by the link when a configuration comes:
/// the link answers it (acknowledgement or refusal) at once, and the control
/// loop takes an accepted one before it runs another period of the old pick.
/// The states that pass are ones the old pick does not leave by itself (none
/// yet, `Done`, `Faulted`, or `Idle` before its first period), so the answer
/// still holds when the control loop takes the configuration.
pub static RECONFIGURE_REFUSAL: AtomicU32 = AtomicU32::new(0);
/// Sequence number of ticker-mode samples.
static TICKER_SEQ: AtomicU32 = AtomicU32::new(0);

/// Hands everything news-like the other tasks left to the pick.
fn drain_news(pick: &mut PickController) {
    while let Ok(news) = NEWS.try_receive() {
        pick.on_news(&news);
    }
}

/// Queues a message for the link; counts it when the queue is full.
fn send(message: Message) {
    if OUTGOING.try_send(message).is_err() {
        stats::count_dropped_message();
    }
}

/// Hands the tick's triggers to the pairer and its job to the worker.
fn hand_on_events(pick: &mut PickController, session: u32) {
    while let Some(event) = pick.pop_event() {
        match event {
            ControlEvent::Trigger(record) => {
                if TRIGGERS.try_send(record).is_err() {
                    stats::count_dropped_handoff();
                }
            }
            ControlEvent::Job(ticket) => {
                if WORK.try_send((session, WorkItem::Job(ticket))).is_err() {
                    stats::count_dropped_handoff();
                    pick.on_job_lost();
                }
            }
        }
    }
}

/// The pick's settings on this build: the defaults, except that the
/// emulated board running free allows a longer gap between two periods
/// ([`FREE_RUN_STALL_LIMIT_S`]).
fn pick_settings() -> PickSettings {
    let settings = PickSettings::default();
    if cfg!(feature = "free-run") {
        PickSettings {
            stall_limit_s: FREE_RUN_STALL_LIMIT_S,
            ..settings
        }
    } else {
        settings
    }
}

/// The emulated board running free: the longest gap between two control
/// periods before the pick stops (`ControlStall`). The host's scheduler can
/// hold QEMU off for tens of milliseconds on a loaded machine, a gap the
/// real board's 20 ms limit would stop the pick for; the host's plant holds
/// the last torque for 200 ms (its drives' watchdog in this mode) before it
/// brakes, so a gap up to that is one the arm rides out on its last torque.
pub const FREE_RUN_STALL_LIMIT_S: f32 = 0.2;

/// Replaces the pick for a new configuration. Out of line: the controller
/// (4.5 KB) is built in this function's frame, not in the task poll's, which
/// is on the stack in every period. A new configuration keeps the current
/// controller's dynamic model, which no configuration changes: it is built
/// (`controller_model`'s 5 KB and `Puma560::new`'s 2.7 KB of stack) only when
/// there is no controller, the first time before the worker has ever had
/// work, so not on top of its bundle adjustment. Returns whether the
/// configuration was accepted.
#[inline(never)]
fn configure(
    pick: &mut Option<(u32, PickController)>,
    reported_estimate: &mut u32,
    configured: &Configured,
) -> bool {
    let settings = pick_settings();
    let current = pick.as_ref().map(|(_, controller)| controller);
    match PickController::replacing(current, &configured.config, settings, configured.session) {
        Ok(controller) => {
            *pick = Some((configured.session, controller));
            *reported_estimate = 0;
            stats::reset_costs();
            true
        }
        Err(e) => {
            defmt::error!(
                "control loop: configuration refused: {} {}",
                e.field,
                e.reason
            );
            *pick = None;
            false
        }
    }
}

/// The interlock's decision for this period: the checks on a new sample, the
/// latched state alone on a repeated one (its torques were checked when
/// first computed). A board fault latched by a handler trips it first. The
/// joint speeds from the encoders (rad/s, `None` until the window is full)
/// are kept in `speeds` for the reconfiguration gate.
fn interlock_period(
    interlock: &mut DriveInterlock<'_>,
    motion: &mut EncoderMotion,
    speeds: &mut Option<[f32; 6]>,
    sample: &SensorSample,
    torque_nm: &[f32; 6],
    phase: PickPhase,
    repeated: bool,
) -> InterlockOutput {
    if let Some(fault) = fail_safe::latched() {
        interlock.trip(InterlockFault::Board(fault));
    }
    if repeated {
        return interlock.hold(torque_nm);
    }
    let (q, qd) = motion.update(&sample.joint_counts, sample.time_us);
    *speeds = qd;
    interlock.period(&PeriodInput {
        torque_nm,
        q_measured_rad: &q,
        qd_measured_rad_s: qd.as_ref(),
        braking: matches!(phase, PickPhase::Stopping | PickPhase::Faulted),
    })
}

/// Ticker mode: the parking sequence's decision for this period
/// (`shared::safety::parking`): after the pick has ended and the arm rested,
/// or after the host link has been lost for a bounded time, the brakes
/// engage and then the drives go off. In lock step the plant, its drives and
/// brakes are the simulator's: always active there.
fn parking_period(
    parking: &mut Parking,
    source: ControlSource,
    now_us: u64,
    phase: PickPhase,
    speeds: Option<[f32; 6]>,
) -> ParkingOutput {
    if source != ControlSource::Ticker {
        return ParkingOutput {
            brake_engaged: false,
            drives_allowed: true,
        };
    }
    let at_rest = speeds.is_some_and(|qd| qd.iter().all(|v| v.abs() <= REST_SPEED_RAD_S));
    let before = parking.state();
    let output = parking.period(&ParkingInput {
        time_us: now_us,
        pick_ended: matches!(phase, PickPhase::Done | PickPhase::Faulted),
        at_rest,
        since_host_frame_us: (now_us as u32)
            .wrapping_sub(LAST_HOST_FRAME_US.load(Ordering::Relaxed)),
    });
    if parking.state() != before {
        defmt::info!("parking: {}", parking.state());
    }
    output
}

/// Publishes whether a configuration may replace the pick (in `phase`,
/// its gripper holding a part or not) now (see [`RECONFIGURE_REFUSAL`]).
fn publish_reconfigure(
    phase: PickPhase,
    gripper_holds: bool,
    speeds: Option<[f32; 6]>,
    drives_on: bool,
    source: ControlSource,
) {
    let verdict = check_reconfigure(&CellState {
        phase: Some(phase),
        joint_speed_rad_s: speeds,
        gripper_holds,
        drives_on,
        drives_off_required: source == ControlSource::Ticker,
    });
    RECONFIGURE_REFUSAL.store(
        verdict.err().map_or(0, |refusal| refusal.detail()),
        Ordering::Relaxed,
    );
}

/// The ticker of the control periods, and when its last tick was due.
struct PeriodClock {
    ticker: Ticker,
    period: Duration,
    due: Instant,
}

impl PeriodClock {
    fn new() -> Self {
        let period = Duration::from_hz(u64::from(CONTROL_RATE_HZ));
        PeriodClock {
            ticker: Ticker::every(period),
            period,
            due: Instant::now(),
        }
    }

    /// Waits for the next period; returns when it started. A tick later than
    /// one period past its due time (the core was held off: a long
    /// interrupt, or the host's scheduler holding QEMU off) starts the ticker
    /// again from now, rather than running the missed periods back to back
    /// on one reading of the plant.
    async fn next(&mut self) -> Instant {
        self.ticker.next().await;
        self.due += self.period;
        let now = Instant::now();
        if now > self.due + self.period {
            self.ticker.reset();
            self.due = now;
        }
        now
    }
}

/// What a period starts with.
enum Reading {
    /// A new sample, and the period's start on the controller's clock (in
    /// lock step the sample's own time).
    Sample { sample: SensorSample, now_us: u64 },
    /// The plant could not be read (logged once): the drives go off.
    Failed,
    /// The plant has nothing newer than the last sample (the emulated board
    /// running free, before the host's next state): no period runs, the
    /// last command stands.
    Unchanged,
}

/// What the ticker's reads remember between periods.
struct TickerReads {
    /// The last read's error, logged once until a read succeeds.
    error: Option<BoardError>,
    /// The last sample's time: a reading not newer is no new sample.
    last_time_us: Option<u64>,
}

/// The next sample: from the link in lock step, from the board's encoders on
/// the ticker. On the ticker the instant of the counts comes first
/// (`PlantIo::reading_time_us`: the period's start on the STM32F407, the
/// plant state's own stamp on the emulated board running free) and `pick`
/// says whether that instant fires the camera, so the board raises the
/// trigger line as it latches the counts (`PlantIo::read_sample`): the sample
/// the pick pairs with the trigger is the latched one, stamped with its
/// instant.
async fn next_sample(
    source: ControlSource,
    clock: &mut PeriodClock,
    plant: &mut active::Plant,
    pick: Option<&PickController>,
    homing: bool,
    reads: &mut TickerReads,
) -> Reading {
    match source {
        ControlSource::LockStep => {
            let sample = SAMPLES.receive().await;
            Reading::Sample {
                now_us: sample.time_us,
                sample,
            }
        }
        ControlSource::Ticker => {
            let now_us = clock.next().await.as_micros();
            let reading = plant.reading_time_us(now_us).and_then(|time_us| {
                if reads.last_time_us.is_some_and(|last| time_us <= last) {
                    return Ok(None);
                }
                let camera_trigger = pick.is_some_and(|pick| pick.camera_trigger_due(time_us));
                plant
                    .read_sample(camera_trigger)
                    .map(|reading| Some((time_us, reading)))
            });
            match reading {
                Ok(Some((time_us, reading))) => {
                    reads.error = None;
                    reads.last_time_us = Some(time_us);
                    // Latched: the interlock turns the drives off this
                    // period and keeps them off until the host acknowledges,
                    // even if the input returns.
                    if reading.emergency_stop {
                        fail_safe::latch(BoardFault::EmergencyStop);
                    }
                    if reading.drive_fault {
                        fail_safe::latch(BoardFault::DriveFault);
                    }
                    let mut sample = SensorSample {
                        seq: TICKER_SEQ.fetch_add(1, Ordering::Relaxed),
                        time_us,
                        joint_counts: reading.joint_counts,
                        conveyor_counts: reading.conveyor_counts,
                        part_in_gripper: reading.part_in_gripper,
                        joint_pots_rad: [f32::NAN; 6],
                        joint_index_counts: SensorSample::NO_INDEX,
                    };
                    if homing {
                        match plant.read_homing_inputs() {
                            Ok(inputs) => {
                                sample.joint_pots_rad = inputs.joint_pots_rad;
                                sample.joint_index_counts = inputs.joint_index_counts;
                            }
                            // Homing stops on the NaN potentiometers.
                            Err(e) => defmt::warn!("control loop: {}", e),
                        }
                    }
                    Reading::Sample { sample, now_us }
                }
                Ok(None) => Reading::Unchanged,
                Err(e) => {
                    // Once per kind of error, not every period.
                    if reads.error != Some(e) {
                        defmt::warn!("control loop: {}", e);
                    }
                    reads.error = Some(e);
                    Reading::Failed
                }
            }
        }
    }
}

#[embassy_executor::task]
pub async fn control_loop(
    mut plant: active::Plant,
    mut watchdog: active::Watchdog,
    cycles: active::Cycles,
    source: ControlSource,
) {
    plant.disable();
    let mut interlock = DriveInterlock::new(&crate::board::INTERLOCK_SETTINGS);
    // Replaced with the cell's counts per radian by every configuration.
    let mut motion = EncoderMotion::new(&[0.0; 6]);
    let mut speeds: Option<[f32; 6]> = None;
    let mut parking = Parking::new();
    let mut deadline = DeadlineMonitor::new();
    let mut reported_fault: Option<InterlockFault> = None;
    let mut pick: Option<(u32, PickController)> = None;
    let mut homing = Homing::new();
    let mut reported_estimate = 0u32;
    let mut last_phase = PickPhase::Idle;
    let mut clock = PeriodClock::new();
    let mut reads = TickerReads {
        error: None,
        last_time_us: None,
    };
    // The period's budget in the counter's units at the board's nominal clock.
    let budget = active::CPU_HZ / CONTROL_RATE_HZ;
    loop {
        // No camera trigger while homing: the pick has not started.
        let reading = next_sample(
            source,
            &mut clock,
            &mut plant,
            pick.as_ref()
                .filter(|_| !homing.active())
                .map(|(_, controller)| controller),
            homing.active(),
            &mut reads,
        )
        .await;
        // Every period, configured or not; the first one arms it.
        watchdog.feed();
        let sample = match reading {
            Reading::Sample { sample, now_us } => Some((sample, now_us)),
            Reading::Failed => None,
            Reading::Unchanged => continue,
        };
        if let Some(configured) = CONTROL_CONFIG.try_take() {
            // Measured on its own: it runs with the arm at rest (the link
            // accepted it through the reconfiguration gate), so it is not
            // this period's control cost or a deadline miss.
            let reconfigure_started = cycles.now();
            let accepted = configure(&mut pick, &mut reported_estimate, &configured);
            if accepted {
                homing.configure(&configured.config);
            }
            let reconfigure_cost = cycles
                .now()
                .wrapping_sub(reconfigure_started)
                .saturating_mul(cycles.scale());
            stats::record_reconfigure(reconfigure_cost);
            defmt::info!(
                "control loop: reconfigured in {} {}",
                reconfigure_cost,
                cycles.unit()
            );
            if accepted {
                // The host's acknowledgement of any drive fault: it has
                // started over with a new configuration and a new pick.
                if let Some(fault) = interlock.fault() {
                    defmt::warn!("drive interlock: {} acknowledged by the host", fault);
                }
                fail_safe::acknowledge();
                interlock.acknowledge();
                reported_fault = None;
                motion = EncoderMotion::new(&configured.config.joint_counts_per_rad);
                speeds = None;
                parking.restart();
                deadline = DeadlineMonitor::new();
                if source == ControlSource::Ticker {
                    // This period's counts were read for the old pick (its
                    // trigger decision): the new one starts next period,
                    // with the drives off (the gate required them off).
                    plant.disable();
                    continue;
                }
            }
        }
        let (Some((sample, now_us)), Some((session, controller))) = (sample, pick.as_mut()) else {
            plant.disable();
            if pick.is_none() {
                // No pick (none yet, or the last configuration failed to
                // build): the drives are off, so the next one is welcome.
                RECONFIGURE_REFUSAL.store(0, Ordering::Relaxed);
            }
            continue;
        };
        if let Some(period) = homing.period(&sample) {
            let started = cycles.now();
            // Without the host, parking engages the brakes and turns the
            // drives off after its bounded wait, as for the pick.
            let mut command = period.command;
            let drives = interlock_period(
                &mut interlock,
                &mut motion,
                &mut speeds,
                &period.interlock_sample,
                &command.joint_torque_nm,
                period.phase,
                period.repeated,
            );
            if interlock.fault() != reported_fault {
                reported_fault = interlock.fault();
                if let Some(fault) = reported_fault {
                    defmt::error!(
                        "drive interlock while homing: {}; drives off until the host acknowledges",
                        fault
                    );
                }
            }
            command.joint_torque_nm = drives.torque_nm;
            let park = parking_period(&mut parking, source, now_us, period.phase, speeds);
            let drives_on = drives.enable && park.drives_allowed;
            publish_reconfigure(period.phase, false, speeds, drives_on, source);
            match source {
                ControlSource::LockStep => {
                    if COMMANDS.try_send(command).is_err() {
                        stats::count_dropped_message();
                    }
                }
                ControlSource::Ticker if !drives_on => plant.disable(),
                ControlSource::Ticker => {
                    if let Err(e) = plant.apply(&command.joint_torque_nm, false) {
                        defmt::error!("control loop: {}; drives off", e);
                        fail_safe::latch(BoardFault::DriveFault);
                    }
                    plant.set_brakes(park.brake_engaged);
                }
            }
            if let Some(error) = period.report {
                send(Message::Telemetry(power_on_homing::fault_telemetry(
                    &sample,
                    &error,
                    stats::FRAMES_REJECTED.load(Ordering::Relaxed),
                )));
            }
            if period.homed {
                // The pick's samples are homed counts: the interlock's
                // speeds start over on them.
                if let Some(counts_per_rad) = homing.counts_per_rad() {
                    motion = EncoderMotion::new(&counts_per_rad);
                }
                speeds = None;
            }
            let cost = cycles
                .now()
                .wrapping_sub(started)
                .saturating_mul(cycles.scale());
            if !period.repeated {
                let missed = cost > budget;
                stats::record_control(cost, missed, 0, period.phase);
                if source == ControlSource::Ticker
                    && deadline.period(missed)
                    && fail_safe::latched().is_none()
                {
                    fail_safe::latch(BoardFault::DeadlineMissed);
                }
            }
            continue;
        }
        let mut sample = sample;
        if let Some(offsets) = homing.offsets() {
            offsets.apply(&mut sample);
        }
        drain_news(controller);
        if source == ControlSource::LockStep {
            // Lock step: the plant waits for this period anyway, so wait for
            // a result that is due rather than apply it late: the run is then
            // the same whatever the emulator's speed.
            while controller.awaits_result(sample.time_us) {
                NEWS_READY.wait().await;
                drain_news(controller);
            }
        }
        let started = cycles.now();
        if source == ControlSource::Ticker
            && (now_us as u32).wrapping_sub(LAST_HOST_FRAME_US.load(Ordering::Relaxed))
                > LINK_TIMEOUT_US
        {
            controller.stop(FaultCause::LinkLost);
        }
        if parking.state() != ParkState::Active {
            // The brakes hold the arm from the period they dropped: Eq 23
            // no longer moves it (see `PickController::on_brakes`).
            controller.on_brakes();
        }
        let mut extra: Vec<Message, MAX_TICK_MESSAGES> = Vec::new();
        controller.set_link_frames_rejected(stats::FRAMES_REJECTED.load(Ordering::Relaxed));
        // A sample sent again (its command was lost) gets the same command and
        // runs no period: not a control period in the figures either.
        let repeated = controller.repeats(&sample);
        let mut command = controller.on_sensor_sample(&sample, &mut extra);
        hand_on_events(controller, *session);
        if let (ControlSource::Ticker, Some(trigger_id)) = (source, command.camera_trigger) {
            // The vision side learns the id of the exposure the trigger line
            // started (in lock step it is in the actuator command).
            let event = TriggerEvent {
                trigger_id,
                time_us: sample.time_us,
            };
            if TRIGGER_EVENTS.try_send(event).is_err() {
                stats::count_dropped_message();
            }
        }
        let drives = interlock_period(
            &mut interlock,
            &mut motion,
            &mut speeds,
            &sample,
            &command.joint_torque_nm,
            controller.phase(),
            repeated,
        );
        if interlock.fault() != reported_fault {
            reported_fault = interlock.fault();
            if let Some(fault) = reported_fault {
                defmt::error!(
                    "drive interlock: {}; drives off until the host acknowledges",
                    fault
                );
                controller.stop(FaultCause::ControlFailure);
            }
        }
        command.joint_torque_nm = drives.torque_nm;
        let park = parking_period(&mut parking, source, now_us, controller.phase(), speeds);
        let drives_on = drives.enable && park.drives_allowed;
        publish_reconfigure(
            controller.phase(),
            controller.gripper_holds(),
            speeds,
            drives_on,
            source,
        );
        match source {
            ControlSource::LockStep => {
                if COMMANDS.try_send(command).is_err() {
                    stats::count_dropped_message();
                }
            }
            ControlSource::Ticker if !drives_on => plant.disable(),
            ControlSource::Ticker => {
                let closed = command.gripper == GripperCommand::Close;
                if let Err(e) = plant.apply(&command.joint_torque_nm, closed) {
                    defmt::error!("control loop: {}; drives off", e);
                    controller.stop(FaultCause::ControlFailure);
                }
                plant.set_brakes(park.brake_engaged);
            }
        }
        if let Some(report) = new_report(controller, &mut reported_estimate) {
            REPORTS.signal(report);
        }
        // By reference: `for message in extra` moves the whole three-slot
        // queue (960 bytes) into an iterator first, and the size-tuned task
        // code copies it more than once (3,600 instructions for one
        // telemetry message in the worst period).
        for message in extra.iter() {
            send(message.clone());
        }
        let phase = controller.phase();
        if phase != last_phase {
            last_phase = phase;
            phase_log::note(phase, controller.fault());
        }
        let cost = cycles
            .now()
            .wrapping_sub(started)
            .saturating_mul(cycles.scale());
        if !repeated {
            let missed = cost > budget;
            stats::record_control(cost, missed, controller.counters().late_results, phase);
            // Ticker only: there a late period leaves the arm running on
            // stale torques. In lock step the plant waits for the command
            // (its time does not advance), so lateness is only a cost
            // figure; the emulated `turning` run has 10 periods in a row
            // over the 168,000-instruction budget about 70 ms in, which
            // the host's plant never sees.
            if source == ControlSource::Ticker
                && deadline.period(missed)
                && fail_safe::latched().is_none()
            {
                // Latched like a handler's fault: the interlock turns the
                // drives off next period and the pick stops.
                defmt::error!(
                    "control loop: {} deadlines missed in a row; stopping",
                    deadline.in_a_row()
                );
                fail_safe::latch(BoardFault::DeadlineMissed);
            }
        }
    }
}
