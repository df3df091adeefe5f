//! One pick: the simulated world against the controller over the serial
//! protocol, in lock step (the plant advances one control period per exchanged
//! sensor sample and actuator command), so the run is deterministic and does not
//! depend on how fast the controller's link answers.
//!
//! Per period: camera frames that have arrived are sent, then the sensor
//! sample; the controller answers with the actuator command (and, at its own
//! bounded rate, telemetry and calibration reports); the world applies the
//! command for one period.

use std::collections::VecDeque;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use shared::protocol::{
    ActuatorCommand, ControllerMode, FaultCause, Message, MessageKind, PickPhase, PickTelemetry,
    PROTOCOL_VERSION,
};

use super::invariants::{PeriodTruth, SafetyMonitor};
use super::record::{
    CalibrationRecord, GraspRecord, LinkRecord, PhaseEvent, PickResult, PickRun, TickRecord,
};
use super::watch::{EachPeriod, NoWatcher, PickWatcher};
use crate::geometry::{angle_distance, wrap_angle};
use crate::link::{ByteLink, FramedLink, LinkError, NoiseConfig, NoisyLink};
use crate::scenario::pick::PickExperiment;
use crate::world::{World, WorldTruth};

/// Seconds the run goes on after the controller reports Done or Faulted, to
/// see the arm come to rest and stay there.
const SETTLE_AFTER_END_S: f64 = 0.5;

/// How long to wait for a reply before sending the request again. A noisy
/// line loses frames both ways; the in-process link answers at once, so there
/// a lost reply is known at once and this wait is never spent.
const RESEND_AFTER: Duration = Duration::from_millis(1_000);

/// The wait for a command once a refused frame was seen (the controller
/// reported one, or a reply came damaged): a few round trips on the emulated
/// board's link (about 2 ms each). A command that was only slow is answered
/// again for the resent sample and skipped as stale.
const RESEND_AFTER_DAMAGE: Duration = Duration::from_millis(20);

/// How long the run reads a board's last replies after its last period.
const DRAIN_AFTER_RUN: Duration = Duration::from_millis(200);

/// Sends of one request (a sample, the handshake, the configuration) before
/// the run gives up on the link: at [`RESEND_AFTER`] apart, 10 s in all (a
/// real board or an emulator may be slow to answer).
const MAX_SENDS: u32 = 10;

/// Sorts out a failed receive, counting it in `record`: a lost reply
/// (`Ok(true)`: send again), a refused frame (`Ok(false)`: keep waiting) or a
/// dead link (`Err`).
fn resend_after(record: &mut LinkRecord, error: LinkError) -> Result<bool> {
    match error {
        LinkError::Timeout { .. } => Ok(true),
        LinkError::CorruptReply(_) => {
            record.replies_refused += 1;
            Ok(false)
        }
        other => Err(other.into()),
    }
}

/// Sends `request` until `accept` takes a reply (`Some`), at most
/// [`MAX_SENDS`] times; replies `accept` passes over (`None`) are skipped.
fn request<L: ByteLink, T>(
    link: &mut FramedLink<L>,
    tally: &mut LinkRecord,
    request: &Message,
    expecting: &str,
    mut accept: impl FnMut(Message) -> Result<Option<T>>,
) -> Result<T> {
    for send in 0..MAX_SENDS {
        if send > 0 {
            tally.session_resends += 1;
        }
        link.send(request)?;
        loop {
            match link.recv(RESEND_AFTER, expecting) {
                Ok(Message::ErrorReport { code, .. }) if code.is_frame_refusal() => {
                    tally.refusals_reported += 1;
                }
                Ok(message) => {
                    if let Some(value) = accept(message)? {
                        return Ok(value);
                    }
                }
                Err(e) => {
                    if resend_after(tally, e)? {
                        break;
                    }
                }
            }
        }
    }
    bail!(
        "no {expecting} from {} after {MAX_SENDS} sends",
        link.describe()
    )
}

/// Periods of truth kept to pair a telemetry message with its own instant.
const RECENT_TRUTHS: usize = 64;

/// The truth at the sample time `time_us`, or `now` if it is no longer kept.
fn truth_at(recent: &VecDeque<(u64, WorldTruth)>, time_us: u64, now: &WorldTruth) -> WorldTruth {
    recent
        .iter()
        .rev()
        .find(|(t, _)| *t == time_us)
        .map_or(*now, |(_, truth)| *truth)
}

/// What the safety invariants read of the world after a period.
fn period_truth(world: &World) -> PeriodTruth {
    let truth = world.truth();
    PeriodTruth {
        q: truth.q_rad.into(),
        qd: truth.qd_rad_s.into(),
        part_base_m: truth.part_base_m.into(),
        part_velocity_base_m_s: truth.part_velocity_base_m_s.into(),
        part_held: truth.part_held,
        applied_torque_ratio: world.plant().peak_torque_ratio(),
    }
}

/// Opens the session and sends the cell configuration.
fn open_session<L: ByteLink>(
    link: &mut FramedLink<L>,
    tally: &mut LinkRecord,
    world: &World,
) -> Result<()> {
    let mut peer_name = heapless::String::new();
    let _ = peer_name.push_str("host-sim pick");
    let hello = Message::Hello {
        protocol_version: PROTOCOL_VERSION,
        peer_name,
    };
    request(link, tally, &hello, "HelloAck", |message| match message {
        Message::HelloAck { .. } => Ok(Some(())),
        // Reports of frames refused before this session (stale bytes on a
        // board's UART), and what an earlier session's last control period
        // queued behind its command (a restart after a stop).
        Message::ErrorReport { .. }
        | Message::Telemetry(_)
        | Message::CalibrationReport(_)
        | Message::ActuatorCommand(_)
        | Message::Ack { .. } => Ok(None),
        other => bail!("expected HelloAck, got {other:?}"),
    })?;
    let configure = Message::Configure(world.cell_config());
    request(
        link,
        tally,
        &configure,
        "Ack of the cell configuration",
        |message| match message {
            Message::Ack {
                kind: MessageKind::Configure,
                ..
            } => Ok(Some(())),
            // A HelloAck of a Hello sent again (its first answer was lost late).
            Message::HelloAck { .. } => Ok(None),
            other => bail!("the controller refused the cell configuration: {other:?}"),
        },
    )
}

fn vector_sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn to_f64(v: [f32; 3]) -> [f64; 3] {
    v.map(f64::from)
}

/// The record of one telemetry message against the truth at the same instant.
fn tick_record(telemetry: &PickTelemetry, truth: &WorldTruth) -> TickRecord {
    TickRecord {
        t_s: truth.time_s,
        phase: telemetry.phase,
        part_true_base_m: truth.part_base_m,
        part_true_yaw_rad: truth.part_yaw_rad,
        part_est_base_m: telemetry.part_base_m.map(to_f64),
        part_est_yaw_rad: telemetry
            .part_base_m
            .map(|_| f64::from(telemetry.part_yaw_base_rad)),
        part_sigma_m: f64::from(telemetry.part_sigma_m),
        tool_true_base_m: truth.tool_base_m,
        tool_true_yaw_rad: truth.tool_yaw_rad,
        tool_ref_base_m: to_f64(telemetry.tool_reference_base_m),
        tool_ref_yaw_rad: f64::from(telemetry.tool_reference_yaw_rad),
        theta_true_rad: truth.theta_rad,
        theta_est_wrapped_rad: f64::from(telemetry.theta_rad),
        omega_true_rad_s: truth.omega_rad_s,
        omega_est_rad_s: f64::from(telemetry.omega_rad_s),
        q_rad: truth.q_rad,
        qd_rad_s: truth.qd_rad_s,
        tau_nm: truth.tau_nm,
    }
}

/// Runs one pick of `experiment` (world seeded with `seed`) against the
/// controller behind `link`.
pub fn run_pick<L: ByteLink>(
    experiment: &PickExperiment,
    seed: u64,
    link: &mut FramedLink<L>,
) -> Result<PickRun> {
    run_pick_watched(experiment, seed, link, &mut NoWatcher)
}

/// [`run_pick`], showing `observe` the world and the command of every
/// period just before the world applies it (a frame triggered by that
/// command is exposed at this instant). It only looks: the run is the same.
pub fn run_pick_observed<L: ByteLink>(
    experiment: &PickExperiment,
    seed: u64,
    link: &mut FramedLink<L>,
    observe: &mut dyn FnMut(&World, &ActuatorCommand) -> Result<()>,
) -> Result<PickRun> {
    run_pick_watched(experiment, seed, link, &mut EachPeriod(observe))
}

/// [`run_pick`], showing `watcher` every period, the camera frames sent and
/// the controller's telemetry (see [`PickWatcher`]). It only looks: the run
/// is the same.
pub fn run_pick_watched<L: ByteLink>(
    experiment: &PickExperiment,
    seed: u64,
    link: &mut FramedLink<L>,
    watcher: &mut dyn PickWatcher,
) -> Result<PickRun> {
    let mut world = World::new(experiment, seed)
        .with_context(|| format!("building the world of {} (seed {seed})", experiment.name))?;
    let mut tally = LinkRecord::default();
    open_session(link, &mut tally, &world)?;
    let model = *world.plant().model();

    let mut records = Vec::new();
    let mut phases: Vec<PhaseEvent> = Vec::new();
    let mut calibrations = Vec::new();
    // The controller's disc frame starts where the disc stood when the pick
    // began (after homing), not at the world's zero: the world's angle minus
    // the controller's, a circular mean over its telemetry (each sample
    // quantised to an encoder count; the mean is good to about 1e-4 rad),
    // turns the true base yaw into the controller's frame for scoring.
    let mut disc_offset = (0.0_f64, 0.0_f64);
    let mut grasp = None;
    let mut last_phase = None;
    let mut last_fault: Option<FaultCause> = None;
    let mut ended_at: Option<f64> = None;
    let layout = world.layout();
    let mut monitor = SafetyMonitor::new(
        &model,
        layout.camera_centre_base_m,
        layout.disc_centre_base_m,
        layout.disc_radius_m,
    );
    // The part's last estimate (position, yaw) and the truth at its instant.
    let mut latest_estimate: Option<([f64; 3], f64, WorldTruth)> = None;
    let mut recent_truths: VecDeque<(u64, WorldTruth)> = VecDeque::with_capacity(RECENT_TRUTHS);

    loop {
        let now = world.time_s();
        if now > experiment.time_limit_s {
            break;
        }
        if ended_at.is_some_and(|t| now - t > SETTLE_AFTER_END_S) {
            break;
        }
        if world.control_stalled() {
            // No period runs: no sample read, no command; the drives' watchdog acts.
            world
                .apply_unattended()
                .with_context(|| format!("world step (stalled) at t = {now:.3} s"))?;
            monitor.observe(&period_truth(&world));
            continue;
        }
        let frames = world.due_camera_frames();
        watcher.frames_sent(&world, &frames)?;
        for frame in frames {
            link.send(&Message::CameraFeatures(frame))?;
        }
        let sample = world.sensor_sample();
        let truth = world.truth();
        if recent_truths.len() >= RECENT_TRUTHS {
            recent_truths.pop_front();
        }
        recent_truths.push_back((sample.time_us, truth));
        let command = 'exchange: {
            for send in 0..MAX_SENDS {
                if send > 0 {
                    tally.samples_resent += 1;
                }
                link.send(&Message::SensorSample(sample))?;
                // A refused frame either way may have been this sample or its
                // command: then wait only briefly for the command before
                // sending the sample again.
                let mut damage_seen = false;
                loop {
                    let wait = if damage_seen {
                        RESEND_AFTER_DAMAGE
                    } else {
                        RESEND_AFTER
                    };
                    let reply = match link.recv(wait, "ActuatorCommand") {
                        Ok(reply) => reply,
                        Err(e) => {
                            let refused = matches!(e, LinkError::CorruptReply(_));
                            if resend_after(&mut tally, e)? {
                                break;
                            }
                            damage_seen |= refused;
                            continue;
                        }
                    };
                    match reply {
                        Message::ActuatorCommand(command) if command.seq == sample.seq => {
                            break 'exchange command;
                        }
                        // The answer to an earlier sample sent twice: its period is done.
                        Message::ActuatorCommand(_) => {
                            tally.stale_commands += 1;
                        }
                        Message::Telemetry(telemetry) => {
                            tally.controller_frames_rejected = telemetry.frames_rejected;
                            // The truth at the telemetry's own instant (it comes
                            // after its period's command, a period or more late).
                            let truth = truth_at(&recent_truths, telemetry.time_us, &truth);
                            if last_phase != Some(telemetry.phase) {
                                last_phase = Some(telemetry.phase);
                                phases.push(PhaseEvent {
                                    t_s: truth.time_s,
                                    phase: telemetry.phase,
                                });
                            }
                            if telemetry.fault.is_some() {
                                last_fault = telemetry.fault;
                            }
                            if matches!(telemetry.phase, PickPhase::Done | PickPhase::Faulted)
                                && ended_at.is_none()
                            {
                                ended_at = Some(truth.time_s);
                            }
                            // Homing sends no telemetry but a fault's (theta 0).
                            if !matches!(telemetry.phase, PickPhase::Idle | PickPhase::Faulted) {
                                let (s, c) =
                                    (truth.theta_rad - f64::from(telemetry.theta_rad)).sin_cos();
                                disc_offset = (disc_offset.0 + s, disc_offset.1 + c);
                            }
                            latest_estimate = telemetry.part_base_m.map(|p| {
                                (to_f64(p), f64::from(telemetry.part_yaw_base_rad), truth)
                            });
                            records.push(tick_record(&telemetry, &truth));
                            watcher.telemetry(&telemetry, &truth)?;
                        }
                        Message::CalibrationReport(report) => {
                            let workcell = world.workcell();
                            calibrations.push(CalibrationRecord {
                                t_s: truth.time_s,
                                report,
                                true_camera_height_m: workcell.camera.height_m(),
                                true_base_yaw_rad: wrap_angle(
                                    workcell.base_from_disc_yaw_rad
                                        + disc_offset.0.atan2(disc_offset.1),
                                ),
                                true_base_translation_m: [
                                    workcell.base_from_disc_translation_m.x,
                                    workcell.base_from_disc_translation_m.y,
                                    workcell.base_from_disc_translation_m.z,
                                ],
                            });
                        }
                        Message::Ack {
                            kind: MessageKind::SensorSample,
                            ..
                        } => bail!(
                            "the controller acknowledged a sensor sample instead of answering with joint torques: \
                             its application does not run the pick (firmware older than the pick application?)"
                        ),
                        Message::Ack { .. } => {}
                        Message::ErrorReport { code, .. } if code.is_frame_refusal() => {
                            tally.refusals_reported += 1;
                            damage_seen = true;
                        }
                        Message::ErrorReport { code, detail } => {
                            bail!("the controller reported {code:?} ({detail}) at t = {now:.3} s")
                        }
                        Message::Status(status) if status.mode == ControllerMode::Faulted => {
                            bail!("the controller faulted its link")
                        }
                        other => bail!("unexpected reply {other:?} at t = {now:.3} s"),
                    }
                }
            }
            bail!(
                "no ActuatorCommand for sample {} at t = {now:.3} s after {MAX_SENDS} sends over {}",
                sample.seq,
                link.describe()
            )
        };
        let had_grasp = world.grasp().is_some();
        watcher.period(&world, &command)?;
        world
            .apply(&command)
            .with_context(|| format!("world step at t = {now:.3} s"))?;
        if let (false, Some(attempt)) = (had_grasp, world.grasp()) {
            let estimate = latest_estimate;
            grasp = Some(GraspRecord {
                // The last estimate against the truth at its own instant.
                estimate_error_m: estimate.map(|(p, _, at)| vector_sub(p, at.part_base_m)),
                estimate_yaw_error_rad: estimate.map(|(_, yaw, at)| {
                    angle_distance(yaw, at.part_yaw_rad)
                        .min(angle_distance(yaw + std::f64::consts::PI, at.part_yaw_rad))
                }),
                ..GraspRecord::of_attempt(&attempt)
            });
        }
        monitor.observe(&period_truth(&world));
    }

    {
        // What the last period left behind, so that the link's counts are whole
        // (a board's last replies may still be on the way).
        let wait = if link.inner().replies_are_synchronous() {
            Duration::from_millis(1)
        } else {
            DRAIN_AFTER_RUN
        };
        loop {
            match link.recv(wait, "the last replies") {
                Ok(Message::Telemetry(telemetry)) => {
                    tally.controller_frames_rejected = telemetry.frames_rejected
                }
                Ok(Message::ErrorReport { code, .. }) if code.is_frame_refusal() => {
                    tally.refusals_reported += 1;
                }
                Ok(_) => {}
                Err(e) => {
                    if resend_after(&mut tally, e)? {
                        break;
                    }
                }
            }
        }
    }
    tally.noise = link.inner().noise();

    let duration_s = world.time_s();
    let safety = monitor.worst();
    let end_joint_speed_rad_s = world
        .truth()
        .qd_rad_s
        .iter()
        .fold(0.0_f64, |worst, qd| worst.max(qd.abs()));
    let placed = world.placed_position_base();
    let placed_error_m = placed.map(|p| {
        let d = vector_sub(p, world.drop_off_base());
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
    });
    let final_phase = last_phase.unwrap_or(PickPhase::Idle);
    let result = match (final_phase, grasp.as_ref()) {
        (PickPhase::Done, Some(g)) if g.succeeded && placed.is_some() => PickResult::Success,
        // A missed grasp the controller noticed (part-present switch) and stopped for.
        (PickPhase::Faulted, _) => PickResult::Fault(last_fault.unwrap_or(FaultCause::Timeout)),
        (_, Some(g)) if !g.succeeded => PickResult::GraspMissed,
        (phase, _) => PickResult::TimedOut(phase),
    };
    // The cell is calibrated when the controller starts to locate the part.
    let calibrated_after_s = phases
        .iter()
        .find(|event| event.phase == PickPhase::Locate)
        .map(|event| event.t_s);
    Ok(PickRun {
        experiment: experiment.name.clone(),
        seed,
        layout: world.layout(),
        records,
        phases,
        calibrations,
        grasp,
        result,
        placed_error_m,
        calibrated_after_s,
        duration_s,
        max_speed_ratio: safety.speed_ratio,
        max_torque_ratio: safety.applied_torque_ratio,
        min_tool_clearance_m: safety.disc_clearance_mm * 1e-3,
        safety,
        end_joint_speed_rad_s,
        link: tally,
        vision: world.image_vision_stats(),
    })
}

/// A pick against the controller linked into this process.
pub fn run_pick_in_process(experiment: &PickExperiment, seed: u64) -> Result<PickRun> {
    let mut link = FramedLink::new(crate::link::InProcessLink::new());
    run_pick(experiment, seed, &mut link)
}

/// The same through a noisy line ([`NoisyLink`]): bytes flipped, dropped and
/// inserted in both directions.
pub fn run_pick_in_process_noisy(
    experiment: &PickExperiment,
    seed: u64,
    noise: NoiseConfig,
) -> Result<PickRun> {
    let mut link = FramedLink::new(NoisyLink::new(crate::link::InProcessLink::new(), noise));
    run_pick(experiment, seed, &mut link)
}
