//! The control loop, at the highest priority: once per period it takes a
//! sensor sample (the board's encoders on a ticker, or the simulator's frame in
//! lock step), runs the pick's control part (fusion Eq 1, the state machine,
//! Eq 23), and drives the outputs (the board's servos, gripper and camera
//! trigger, or an actuator-command frame in lock step). It hands triggers to
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
use shared::protocol::{FaultCause, GripperCommand, Message, PickPhase, SensorSample};
use shared::safety::{
    check_reconfigure, BoardFault, CellState, DeadlineMonitor, DriveInterlock, EncoderMotion,
    InterlockFault, InterlockOutput, Parking, ParkingInput, ParkingOutput, PeriodInput,
    REST_SPEED_RAD_S,
};

use super::channels::{
    Configured, COMMANDS, CONTROL_CONFIG, NEWS, NEWS_READY, OUTGOING, REPORTS, SAMPLES, TRIGGERS,
    WORK,
};
use super::phase_log;
use super::stats;
use crate::board::{active, fail_safe, ControlSource, CycleCounter, PlantIo, Watchdog};

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
    let settings = PickSettings::default();
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
    sample: &SensorSample,
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
        time_us: sample.time_us,
        pick_ended: matches!(phase, PickPhase::Done | PickPhase::Faulted),
        at_rest,
        since_host_frame_us: (sample.time_us as u32)
            .wrapping_sub(LAST_HOST_FRAME_US.load(Ordering::Relaxed)),
    });
    if parking.state() != before {
        defmt::info!("parking: {}", parking.state());
    }
    output
}

/// Publishes whether a configuration may replace `controller` now (see
/// [`RECONFIGURE_REFUSAL`]).
fn publish_reconfigure(
    controller: &PickController,
    speeds: Option<[f32; 6]>,
    drives_on: bool,
    source: ControlSource,
) {
    let verdict = check_reconfigure(&CellState {
        phase: Some(controller.phase()),
        joint_speed_rad_s: speeds,
        gripper_holds: controller.gripper_holds(),
        drives_on,
        drives_off_required: source == ControlSource::Ticker,
    });
    RECONFIGURE_REFUSAL.store(
        verdict.err().map_or(0, |refusal| refusal.detail()),
        Ordering::Relaxed,
    );
}

/// The next sample: from the link in lock step, from the board's encoders on
/// the ticker.
async fn next_sample(
    source: ControlSource,
    ticker: &mut Ticker,
    plant: &mut active::Plant,
) -> Option<SensorSample> {
    match source {
        ControlSource::LockStep => Some(SAMPLES.receive().await),
        ControlSource::Ticker => {
            ticker.next().await;
            match plant.read_sample() {
                Ok(reading) => {
                    // Latched: the interlock turns the drives off this
                    // period and keeps them off until the host acknowledges,
                    // even if the input returns.
                    if reading.emergency_stop {
                        fail_safe::latch(BoardFault::EmergencyStop);
                    }
                    if reading.drive_fault {
                        fail_safe::latch(BoardFault::DriveFault);
                    }
                    Some(SensorSample {
                        seq: TICKER_SEQ.fetch_add(1, Ordering::Relaxed),
                        time_us: Instant::now().as_micros(),
                        joint_counts: reading.joint_counts,
                        conveyor_counts: reading.conveyor_counts,
                        part_in_gripper: reading.part_in_gripper,
                    })
                }
                Err(e) => {
                    defmt::warn!("control loop: {}", e);
                    None
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
    let mut reported_estimate = 0u32;
    let mut last_phase = PickPhase::Idle;
    let mut ticker = Ticker::every(Duration::from_hz(u64::from(CONTROL_RATE_HZ)));
    // The period's budget in the counter's units at the board's nominal clock.
    let budget = active::CPU_HZ / CONTROL_RATE_HZ;
    loop {
        let sample = next_sample(source, &mut ticker, &mut plant).await;
        // Every period, configured or not; the first one arms it.
        watchdog.feed();
        if let Some(configured) = CONTROL_CONFIG.try_take() {
            // Measured on its own: it runs with the arm at rest (the link
            // accepted it through the reconfiguration gate), so it is not
            // this period's control cost or a deadline miss.
            let reconfigure_started = cycles.now();
            let accepted = configure(&mut pick, &mut reported_estimate, &configured);
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
            }
        }
        let (Some(sample), Some((session, controller))) = (sample, pick.as_mut()) else {
            plant.disable();
            if pick.is_none() {
                // No pick (none yet, or the last configuration failed to
                // build): the drives are off, so the next one is welcome.
                RECONFIGURE_REFUSAL.store(0, Ordering::Relaxed);
            }
            continue;
        };
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
            && (sample.time_us as u32).wrapping_sub(LAST_HOST_FRAME_US.load(Ordering::Relaxed))
                > LINK_TIMEOUT_US
        {
            controller.stop(FaultCause::LinkLost);
        }
        let mut extra: Vec<Message, MAX_TICK_MESSAGES> = Vec::new();
        controller.set_link_frames_rejected(stats::FRAMES_REJECTED.load(Ordering::Relaxed));
        // A sample sent again (its command was lost) gets the same command and
        // runs no period: not a control period in the figures either.
        let repeated = controller.repeats(&sample);
        let mut command = controller.on_sensor_sample(&sample, &mut extra);
        hand_on_events(controller, *session);
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
        let park = parking_period(&mut parking, source, &sample, controller.phase(), speeds);
        let drives_on = drives.enable && park.drives_allowed;
        publish_reconfigure(controller, speeds, drives_on, source);
        match source {
            ControlSource::LockStep => {
                if COMMANDS.try_send(command).is_err() {
                    stats::count_dropped_message();
                }
            }
            ControlSource::Ticker if !drives_on => plant.disable(),
            ControlSource::Ticker => {
                let closed = command.gripper == GripperCommand::Close;
                if let Err(e) =
                    plant.apply(&command.joint_torque_nm, closed, command.camera_trigger)
                {
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
