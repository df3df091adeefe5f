//! One pick with the plant running free: the simulated world advances on the
//! host's wall clock whatever the controller does, the way a real arm and
//! conveyor do, against a controller that runs on its own ticker (the emulated
//! board built with `free-run`, `firmware/src/board/qemu/free_run.rs`).
//! Nothing of lock step is used: no period waits for the other side.
//!
//! - The plant integrates in its own steps (the experiment's
//!   `robot.control_rate_hz`, 1 ms) up to the wall clock, each with the
//!   newest command it has. A command older than [`FreeRunSettings::drive_watchdog_s`]
//!   (or none yet) leaves the arm to the drives' watchdog, which brakes it.
//! - Every [`FreeRunSettings::state_period_s`] it sends its state (a
//!   `SensorSample` stamped with the plant's time), and keeps the scene of
//!   that instant for a while; at most [`FreeRunSettings::states_in_flight`]
//!   states go unanswered (the commands echo the sequence number of the state
//!   they were computed from), so the emulated UART's bytes never queue up.
//! - A `TriggerEvent` from the controller names the state it latched at the
//!   trigger edge (its time stamp): the camera exposes that state's scene,
//!   and the frame goes out after the camera's latency, with the trigger's id.
//!
//! The time of the two sides: QEMU without `-icount` runs its virtual clock
//! on the host's, so the firmware's ticker and this plant both follow the host's
//! clock; neither needs the other's time. The controller's clock stamps its
//! own samples; the camera needs only the plant's own time stamp back.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use shared::protocol::{
    ActuatorCommand, CalibrationReport, FaultCause, Message, MessageKind, PickPhase, RuntimeReport,
    PROTOCOL_VERSION,
};

use super::record::{GraspRecord, PhaseEvent, PickResult};
use crate::link::{ByteLink, FramedLink, LinkError};
use crate::scenario::pick::PickExperiment;
use crate::world::vision::SceneMarks;
use crate::world::World;

/// How the free-running plant meets the controller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FreeRunSettings {
    /// Plant time between two states sent, seconds.
    pub state_period_s: f64,
    /// States sent that no command has answered yet, at most.
    pub states_in_flight: u32,
    /// How long the drives hold a command with no newer one, seconds; then
    /// they brake the arm (the lock-step world's 5 ms is one controller
    /// period or two there; here it must outlast the host holding QEMU off).
    pub drive_watchdog_s: f64,
    /// How long the run goes on after the controller reports Done or
    /// Faulted, seconds of plant time.
    pub settle_after_end_s: f64,
    /// The run's wall-clock limit (the experiment's time limit applies to
    /// plant time as well).
    pub wall_limit: Duration,
    /// Plant seconds per second of the host's clock: 1 runs the plant in
    /// real time; below 1 it runs slower than the wall clock (still free:
    /// it never waits), which gives a controller held off by a loaded host
    /// that much more margin in the plant's time. The controller stamps its
    /// samples with the plant's own time stamps, so its pick runs on the
    /// plant's time either way.
    pub time_scale: f64,
}

impl Default for FreeRunSettings {
    fn default() -> Self {
        FreeRunSettings {
            // One state per period of the emulated board's 250 Hz.
            state_period_s: 0.004,
            // A guard against bytes queueing up on a saturated link (16
            // states are 64 ms of plant time), not a pace: holding states
            // back when commands come late starves a late controller of
            // fresh states and makes the gap longer.
            states_in_flight: 16,
            drive_watchdog_s: 0.2,
            settle_after_end_s: 1.0,
            wall_limit: Duration::from_secs(600),
            time_scale: 1.0,
        }
    }
}

/// What crossed the link, and what the plant did about it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FreeRunCounts {
    /// Plant steps, and those run with no fresh command (braked or holding).
    pub plant_steps: u64,
    pub unattended_steps: u64,
    pub states_sent: u64,
    /// States not sent when due because too many were unanswered.
    pub states_held_back: u64,
    pub commands_received: u64,
    pub trigger_events: u64,
    /// Trigger events naming a state this plant no longer (or never) kept.
    pub trigger_events_unmatched: u64,
    pub frames_sent: u64,
    /// The controller's own counts from its last telemetry.
    pub frames_paired: u32,
    pub frames_unpaired: u32,
    /// The largest lag of the plant behind the (scaled) wall clock, seconds
    /// of plant time (how far the host fell behind and caught up).
    pub max_plant_lag_s: f64,
    /// The longest plant time between two commands while commands flowed, s.
    pub max_command_gap_s: f64,
}

/// How a free-running pick went.
#[derive(Debug, Clone, PartialEq)]
pub struct FreeRunPick {
    pub result: PickResult,
    pub phases: Vec<PhaseEvent>,
    pub calibrations: Vec<CalibrationReport>,
    pub grasp: Option<GraspRecord>,
    /// Plant time at the end, seconds, and the wall time the run took.
    pub duration_s: f64,
    pub wall_s: f64,
    pub counts: FreeRunCounts,
    /// The controller's report after the run, when it gave one.
    pub runtime: Option<RuntimeReport>,
}

/// Plant states kept for the camera: their time stamp and scene (2 s at
/// one state every 4 ms, far more than a trigger event's trip takes).
const SCENES_KEPT: usize = 500;

/// Waits this long for a reply in the session's handshake before asking again.
const HANDSHAKE_WAIT: Duration = Duration::from_secs(2);
const HANDSHAKE_TRIES: u32 = 10;

/// Sends `request` until a reply `accept` takes.
fn handshake<L: ByteLink>(
    link: &mut FramedLink<L>,
    request: &Message,
    expecting: &str,
    mut accept: impl FnMut(&Message) -> Result<bool>,
) -> Result<()> {
    for _ in 0..HANDSHAKE_TRIES {
        link.send(request)?;
        loop {
            match link.recv(HANDSHAKE_WAIT, expecting) {
                Ok(reply) => {
                    if accept(&reply)? {
                        return Ok(());
                    }
                }
                Err(LinkError::Timeout { .. }) => break,
                Err(LinkError::CorruptReply(_)) => {}
                Err(e) => return Err(e.into()),
            }
        }
    }
    bail!(
        "no {expecting} from {} after {HANDSHAKE_TRIES} tries",
        link.describe()
    )
}

/// Opens the session: the handshake, then the cell's configuration.
fn open_session<L: ByteLink>(link: &mut FramedLink<L>, world: &World) -> Result<()> {
    let mut peer_name = heapless::String::new();
    let _ = peer_name.push_str("host-sim free run");
    let hello = Message::Hello {
        protocol_version: PROTOCOL_VERSION,
        peer_name,
    };
    handshake(link, &hello, "HelloAck", |reply| match reply {
        Message::HelloAck { board_name, .. } => {
            if !board_name.ends_with("free-run") {
                bail!("board {board_name} runs in lock step: it needs `host-sim run`, not a free-running plant");
            }
            Ok(true)
        }
        Message::ErrorReport { code, detail } if !code.is_frame_refusal() => {
            bail!("the controller refused the handshake: {code:?} ({detail})")
        }
        _ => Ok(false),
    })?;
    let configure = Message::Configure(world.cell_config());
    handshake(
        link,
        &configure,
        "Ack of the cell configuration",
        |reply| match reply {
            Message::Ack {
                kind: MessageKind::Configure,
                ..
            } => Ok(true),
            Message::ErrorReport { code, detail } if !code.is_frame_refusal() => {
                bail!("the controller refused the cell configuration: {code:?} ({detail})")
            }
            _ => Ok(false),
        },
    )
}

/// The newest command and when (plant time) it came.
struct Drives {
    command: Option<(ActuatorCommand, f64)>,
    watchdog_s: f64,
}

impl Drives {
    /// The command the drives act on at plant time `now_s`, if still fresh.
    fn fresh(&self, now_s: f64) -> Option<&ActuatorCommand> {
        self.command
            .as_ref()
            .filter(|(_, at)| now_s - at <= self.watchdog_s)
            .map(|(command, _)| command)
    }
}

/// Runs one pick of `experiment` (world seeded with `seed`) with the plant
/// running free against the controller behind `link`.
pub fn run_free<L: ByteLink>(
    experiment: &PickExperiment,
    seed: u64,
    link: &mut FramedLink<L>,
    settings: &FreeRunSettings,
) -> Result<FreeRunPick> {
    let mut world = World::new(experiment, seed)
        .with_context(|| format!("building the world of {} (seed {seed})", experiment.name))?;
    open_session(link, &world)?;
    let step_s = world.control_period_s();
    let mut counts = FreeRunCounts::default();
    let mut drives = Drives {
        command: None,
        watchdog_s: settings.drive_watchdog_s,
    };
    let mut scenes: VecDeque<(u64, SceneMarks)> = VecDeque::with_capacity(SCENES_KEPT);
    let mut phases: Vec<PhaseEvent> = Vec::new();
    let mut calibrations = Vec::new();
    let mut last_phase: Option<PickPhase> = None;
    let mut last_fault: Option<FaultCause> = None;
    let mut ended_at: Option<f64> = None;
    let mut grasp: Option<GraspRecord> = None;
    let mut next_state_s = 0.0;
    let mut last_state_seq: Option<u32> = None;
    let mut answered_seq: Option<u32> = None;
    let started = Instant::now();

    loop {
        let wall_s = started.elapsed().as_secs_f64() * settings.time_scale;
        let now_s = world.time_s();
        if now_s > experiment.time_limit_s
            || ended_at.is_some_and(|t| now_s - t > settings.settle_after_end_s)
            || started.elapsed() > settings.wall_limit
        {
            break;
        }
        counts.max_plant_lag_s = counts.max_plant_lag_s.max(wall_s - now_s);
        // The plant, up to the wall clock, on the newest command it has.
        while world.time_s() + step_s <= wall_s {
            let t = world.time_s();
            let had_grasp = world.grasp().is_some();
            match drives.fresh(t) {
                Some(command) => {
                    let command = *command;
                    world
                        .apply(&command)
                        .with_context(|| format!("plant step at t = {t:.3} s"))?;
                }
                None => {
                    counts.unattended_steps += 1;
                    world
                        .apply_unattended()
                        .with_context(|| format!("plant step (braked) at t = {t:.3} s"))?;
                }
            }
            counts.plant_steps += 1;
            if let (false, Some(attempt)) = (had_grasp, world.grasp()) {
                grasp = Some(GraspRecord::of_attempt(&attempt));
            }
        }
        let now_s = world.time_s();
        // The state, when due and the link is not backed up.
        if now_s >= next_state_s {
            // On a fixed schedule; after a gap (the host held off) from now.
            next_state_s += settings.state_period_s;
            if next_state_s <= now_s {
                next_state_s = now_s + settings.state_period_s;
            }
            let unanswered = match (last_state_seq, answered_seq) {
                (Some(sent), Some(answered)) => sent.wrapping_sub(answered),
                _ => 0,
            };
            // Only while commands flow: without them (drives off, before the
            // pick) the states go out at their period regardless.
            if drives.fresh(now_s).is_some() && unanswered >= settings.states_in_flight {
                counts.states_held_back += 1;
            } else {
                let sample = world.sensor_sample();
                if scenes.len() >= SCENES_KEPT {
                    scenes.pop_front();
                }
                scenes.push_back((sample.time_us, world.scene_marks()));
                link.send(&Message::SensorSample(sample))?;
                last_state_seq = Some(sample.seq);
                counts.states_sent += 1;
            }
        }
        for frame in world.due_camera_frames() {
            link.send(&Message::CameraFeatures(frame))?;
            counts.frames_sent += 1;
        }
        // Whatever the controller sent by now; a short wait paces the loop.
        let mut wait = Duration::from_micros(200);
        loop {
            let reply = match link.recv(wait, "anything") {
                Ok(reply) => reply,
                Err(LinkError::Timeout { .. }) => break,
                Err(LinkError::CorruptReply(detail)) => {
                    bail!("corrupt frame from the controller on a clean link: {detail}")
                }
                Err(e) => return Err(e.into()),
            };
            wait = Duration::ZERO;
            let now_s = world.time_s();
            match reply {
                Message::ActuatorCommand(command) => {
                    if let Some((_, at)) = drives.command {
                        counts.max_command_gap_s = counts.max_command_gap_s.max(now_s - at);
                    }
                    counts.commands_received += 1;
                    answered_seq = Some(command.seq);
                    drives.command = Some((command, now_s));
                }
                Message::TriggerEvent(event) => {
                    counts.trigger_events += 1;
                    match scenes.iter().find(|(t, _)| *t == event.time_us) {
                        Some((t, scene)) => {
                            let scene = scene.clone();
                            world.expose_camera(event.trigger_id, *t as f64 * 1e-6, &scene);
                        }
                        None => counts.trigger_events_unmatched += 1,
                    }
                }
                Message::Telemetry(telemetry) => {
                    counts.frames_paired = telemetry.frames_paired;
                    counts.frames_unpaired = telemetry.frames_unpaired;
                    if last_phase != Some(telemetry.phase) {
                        last_phase = Some(telemetry.phase);
                        phases.push(PhaseEvent {
                            t_s: now_s,
                            phase: telemetry.phase,
                        });
                    }
                    if telemetry.fault.is_some() {
                        last_fault = telemetry.fault;
                    }
                    if matches!(telemetry.phase, PickPhase::Done | PickPhase::Faulted)
                        && ended_at.is_none()
                    {
                        ended_at = Some(now_s);
                    }
                }
                Message::CalibrationReport(report) => calibrations.push(report),
                Message::Ack { .. } => {}
                Message::ErrorReport { code, detail } => {
                    bail!("the controller reported {code:?} ({detail}) at t = {now_s:.3} s")
                }
                other => bail!("unexpected message {other:?} at t = {now_s:.3} s"),
            }
        }
    }
    let wall_s = started.elapsed().as_secs_f64();
    let runtime = runtime_report(link);

    let placed = world.placed_position_base();
    let final_phase = last_phase.unwrap_or(PickPhase::Idle);
    let result = match (final_phase, grasp.as_ref()) {
        (PickPhase::Done, Some(g)) if g.succeeded && placed.is_some() => PickResult::Success,
        (PickPhase::Faulted, _) => PickResult::Fault(last_fault.unwrap_or(FaultCause::Timeout)),
        (_, Some(g)) if !g.succeeded => PickResult::GraspMissed,
        (phase, _) => PickResult::TimedOut(phase),
    };
    Ok(FreeRunPick {
        result,
        phases,
        calibrations,
        grasp,
        duration_s: world.time_s(),
        wall_s,
        counts,
        runtime,
    })
}

/// The controller's runtime report, read past whatever it still sends.
fn runtime_report<L: ByteLink>(link: &mut FramedLink<L>) -> Option<RuntimeReport> {
    link.send(&Message::RuntimeReportRequest).ok()?;
    let deadline = Instant::now() + Duration::from_secs(5);
    while Instant::now() < deadline {
        match link.recv(Duration::from_millis(500), "RuntimeReport") {
            Ok(Message::RuntimeReport(report)) => return Some(report),
            Ok(_) | Err(LinkError::CorruptReply(_)) => {}
            Err(_) => return None,
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_drives_act_on_a_command_only_while_it_is_fresh() {
        let command = ActuatorCommand {
            seq: 4,
            joint_torque_nm: [1.0; 6],
            gripper: shared::protocol::GripperCommand::Open,
            camera_trigger: None,
        };
        let drives = Drives {
            command: Some((command, 2.0)),
            watchdog_s: 0.1,
        };
        assert_eq!(drives.fresh(2.0), Some(&command));
        assert_eq!(drives.fresh(2.099), Some(&command));
        assert_eq!(drives.fresh(2.101), None);
        let none = Drives {
            command: None,
            watchdog_s: 0.1,
        };
        assert_eq!(none.fresh(0.0), None);
    }
}
