//! The fault campaign (`host-sim faults`): the pick attacked the way a factory
//! floor will (issue 7).
//! Each trial draws a random workcell and one fault (or none, as the control
//! group) with random parameters, runs the pick in process, and checks the
//! safety invariants of [`super::invariants`] (joint ranges and speeds, the
//! disc, the camera, the arm itself, the gripper's speed near the part, the
//! applied torque) and that every run ends in a success or in a controlled
//! stop (arm at rest) with its cause reported.
//!
//! Trial k of base seed S uses world seed `S * 1_000_000 + k` and draws its
//! fault from a generator seeded with the same number, so
//! `host-sim faults --seed S --trial k` replays it alone, with plots.

use std::fmt::Write as _;
use std::fs;

use anyhow::{Context, Result};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use serde::Serialize;

use super::invariants::SafetyWorst;
use super::montecarlo::trial_seed;
use super::record::{PickResult, PickRun};
use super::report::result_name;
use super::runner::{run_pick_in_process, run_pick_in_process_noisy};
use crate::link::NoiseConfig;
use crate::scenario::pick::{CameraBump, FaultWindow, MissedCounts, PickExperiment, SpeedChange};

pub use super::invariants::STRIKE_CLEARANCE_M;
/// A controlled stop ends with every joint slower than this, rad/s.
pub const AT_REST_RAD_S: f64 = 0.02;

/// The faults the campaign injects, one per trial.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum FaultKind {
    /// No fault: the control group.
    None,
    /// Half of the detection groups missing.
    Dropouts50,
    /// 1 % of the points gross outliers.
    Outliers1,
    /// 150 +- 140 ms latency: frames late and out of order.
    LateFrames,
    CameraBump,
    /// The conveyor counter wraps during the run.
    CounterWrap,
    MissedCounts,
    /// The counter's value jumps (a glitch, not a slow loss).
    CounterGlitch,
    ConveyorStops,
    ConveyorSpeedsUp,
    ConveyorReverses,
    /// The vision computer's link is down for a while.
    VisionOutage,
    /// The control loop stalls for a while.
    ControlStall,
    /// The serial line damages 1e-3 of the bytes both ways (flips, drops, inserts).
    NoisyLink,
}

/// The byte error rate of [`FaultKind::NoisyLink`] (the figure).
pub const NOISY_LINK_BYTE_ERROR_RATE: f64 = 1e-3;

impl FaultKind {
    pub const ALL: [FaultKind; 14] = [
        FaultKind::None,
        FaultKind::Dropouts50,
        FaultKind::Outliers1,
        FaultKind::LateFrames,
        FaultKind::CameraBump,
        FaultKind::CounterWrap,
        FaultKind::MissedCounts,
        FaultKind::CounterGlitch,
        FaultKind::ConveyorStops,
        FaultKind::ConveyorSpeedsUp,
        FaultKind::ConveyorReverses,
        FaultKind::VisionOutage,
        FaultKind::ControlStall,
        FaultKind::NoisyLink,
    ];

    pub fn name(self) -> &'static str {
        match self {
            FaultKind::None => "none",
            FaultKind::Dropouts50 => "vision: 50 % dropouts",
            FaultKind::Outliers1 => "vision: 1 % gross outliers",
            FaultKind::LateFrames => "vision: late, out-of-order frames",
            FaultKind::CameraBump => "vision: camera bumped",
            FaultKind::CounterWrap => "encoder: counter wraps",
            FaultKind::MissedCounts => "encoder: missed count burst",
            FaultKind::CounterGlitch => "encoder: counter jumps",
            FaultKind::ConveyorStops => "conveyor stops",
            FaultKind::ConveyorSpeedsUp => "conveyor speeds up",
            FaultKind::ConveyorReverses => "conveyor reverses",
            FaultKind::VisionOutage => "link: vision link lost",
            FaultKind::ControlStall => "control loop stalls",
            FaultKind::NoisyLink => "link: 1e-3 of the bytes damaged",
        }
    }

    /// The kind trial `trial` injects: the kinds take turns.
    pub fn of_trial(trial: usize) -> FaultKind {
        Self::ALL
            .get(trial % Self::ALL.len())
            .copied()
            .unwrap_or(FaultKind::None)
    }
}

/// `experiment` with fault `kind` injected, its parameters drawn from `rng`,
/// and a one-line description of them.
pub fn inject(
    experiment: &PickExperiment,
    kind: FaultKind,
    rng: &mut ChaCha8Rng,
) -> (PickExperiment, String) {
    let mut e = experiment.clone();
    let mut uniform = |low: f64, high: f64| low + (high - low) * rng.random::<f64>();
    // Faults strike anywhere from the search (5 s) to the grasp (about 60 s).
    let at_s = uniform(5.0, 60.0);
    let speed = e.conveyor.speed_rad_s;
    let description = match kind {
        FaultKind::None => "no fault".to_owned(),
        FaultKind::NoisyLink => format!(
            "{NOISY_LINK_BYTE_ERROR_RATE:e} of the bytes flipped, dropped or inserted, both ways"
        ),
        FaultKind::Dropouts50 => {
            e.camera.dropout_probability = 0.5;
            "dropout probability 0.5".to_owned()
        }
        FaultKind::Outliers1 => {
            e.camera.outlier_probability = 0.01;
            "outlier probability 0.01".to_owned()
        }
        FaultKind::LateFrames => {
            e.camera.latency_ms = 150.0;
            e.camera.latency_jitter_ms = 140.0;
            "latency 150 +- 140 ms".to_owned()
        }
        FaultKind::CameraBump => {
            let sign = if uniform(0.0, 1.0) < 0.5 { -1.0 } else { 1.0 };
            let bump = CameraBump {
                at_s,
                rotation_deg: sign * uniform(1.0, 5.0),
                shift_m: uniform(-0.03, 0.03),
            };
            e.faults.camera_bump = Some(bump);
            format!(
                "at {:.1} s: {:+.2} deg, {:+.1} mm",
                bump.at_s,
                bump.rotation_deg,
                bump.shift_m * 1e3
            )
        }
        FaultKind::CounterWrap => {
            let before = uniform(0.0, 20_000.0) as u32;
            e.faults.counter_counts_before_wrap = Some(before);
            format!("{before} counts before the wrap")
        }
        FaultKind::MissedCounts | FaultKind::CounterGlitch => {
            let missed = MissedCounts {
                at_s,
                counts: uniform(16.0, 256.0) as u32,
                instant: kind == FaultKind::CounterGlitch,
            };
            e.faults.missed_counts = Some(missed);
            format!("at {:.1} s: {} counts", missed.at_s, missed.counts)
        }
        FaultKind::ConveyorStops | FaultKind::ConveyorSpeedsUp | FaultKind::ConveyorReverses => {
            let (speed_rad_s, acceleration_rad_s2) = match kind {
                FaultKind::ConveyorStops => (0.0, uniform(0.5, 2.0)),
                FaultKind::ConveyorSpeedsUp => (speed * uniform(1.3, 2.0), uniform(0.2, 1.0)),
                _ => (-speed * uniform(0.6, 1.4), uniform(0.5, 2.0)),
            };
            let change = SpeedChange {
                at_s,
                speed_rad_s,
                acceleration_rad_s2,
            };
            e.conveyor.stop = None;
            e.faults.conveyor_change = Some(change);
            format!(
                "at {:.1} s: to {:+.2} rad/s at {:.2} rad/s^2",
                change.at_s, change.speed_rad_s, change.acceleration_rad_s2
            )
        }
        FaultKind::VisionOutage | FaultKind::ControlStall => {
            let duration_s = if kind == FaultKind::VisionOutage {
                uniform(0.5, 4.0)
            } else {
                uniform(0.05, 1.0)
            };
            let window = Some(FaultWindow { at_s, duration_s });
            if kind == FaultKind::VisionOutage {
                e.faults.vision_outage = window;
            } else {
                e.faults.control_stall = window;
            }
            format!("at {at_s:.1} s for {duration_s:.2} s")
        }
    };
    (e, description)
}

/// How a faulty pick ended, and whether it kept the invariants.
#[derive(Debug, Clone, Serialize)]
pub struct FaultTrial {
    pub trial: usize,
    pub seed: u64,
    pub kind: FaultKind,
    pub fault: String,
    pub result: String,
    pub success: bool,
    /// The cause, when the pick ended in a controlled stop.
    pub stop_cause: Option<String>,
    pub max_speed_ratio: f64,
    /// The applied torque's (after the amplifier) worst ratio to its limit.
    pub max_torque_ratio: f64,
    pub min_tool_clearance_mm: f64,
    pub end_joint_speed_rad_s: f64,
    /// Every invariant's worst value.
    pub safety: SafetyWorst,
    /// Every invariant the run broke (empty when safe).
    pub violations: Vec<String>,
}

/// Runs `faulty` (fault `kind` injected) in process; through a noisy line
/// for [`FaultKind::NoisyLink`].
pub fn run_faulty(faulty: &PickExperiment, kind: FaultKind, seed: u64) -> Result<PickRun> {
    match kind {
        FaultKind::NoisyLink => run_pick_in_process_noisy(
            faulty,
            seed,
            NoiseConfig {
                byte_error_rate: NOISY_LINK_BYTE_ERROR_RATE,
                seed,
            },
        ),
        _ => run_pick_in_process(faulty, seed),
    }
}

/// The invariants of a safe run (see the module's doc), and of a sound link:
/// no damaged frame taken for a message, every refusal counted by the side
/// that refused it (the controller in its telemetry).
pub fn violations(run: &PickRun) -> Vec<String> {
    let mut found = Vec::new();
    if let Some(noise) = run.link.noise {
        let forged = noise.to_controller.forged + noise.to_host.forged;
        if forged > 0 {
            found.push(format!("{forged} damaged frames accepted as messages"));
        }
        // Fewer is a refusal not counted. (More is possible on a board, whose
        // link task may refuse a later frame before its control loop reads
        // the count; in process the count must be exact: tests/noisy_link.rs.)
        if noise.telemetry.undercounted > 0 {
            found.push(format!(
                "{} of {} telemetry messages counted fewer refused frames than there were",
                noise.telemetry.undercounted, noise.telemetry.checked
            ));
        }
        if run.link.replies_refused != noise.to_host.frames_rejected {
            found.push(format!(
                "the host counted {} refused replies, the line damaged {} into refusals",
                run.link.replies_refused, noise.to_host.frames_rejected
            ));
        }
    }
    found.extend(run.safety.violations());
    match run.result {
        PickResult::Success => {}
        PickResult::Fault(_) if run.end_joint_speed_rad_s < AT_REST_RAD_S => {}
        PickResult::Fault(_) => found.push(format!(
            "stopped but moving at {:.3} rad/s",
            run.end_joint_speed_rad_s
        )),
        PickResult::GraspMissed => found.push("grasp missed, not reported".to_owned()),
        PickResult::TimedOut(phase) => found.push(format!("no stop: timed out in {phase:?}")),
    }
    found
}

/// The generator trial seed `seed` draws its fault's parameters from.
pub fn trial_rng(seed: u64) -> ChaCha8Rng {
    // Not the world's stream: the fault's draws must not shift the workcell's.
    ChaCha8Rng::seed_from_u64(seed ^ 0xFA17_FA17_FA17_FA17)
}

/// One faulty trial.
pub fn run_trial(experiment: &PickExperiment, base_seed: u64, trial: usize) -> FaultTrial {
    let seed = trial_seed(base_seed, trial);
    let kind = FaultKind::of_trial(trial);
    let (faulty, fault) = inject(experiment, kind, &mut trial_rng(seed));
    let (run, error) = match run_faulty(&faulty, kind, seed) {
        Ok(run) => (run, None),
        Err(error) => (
            PickRun::empty(&faulty.name, seed),
            Some(format!("{error:#}")),
        ),
    };
    let mut found = violations(&run);
    let result = match &error {
        Some(error) => {
            found.push("simulation error".to_owned());
            format!("error: {error}")
        }
        None => result_name(&run.result),
    };
    FaultTrial {
        trial,
        seed,
        kind,
        fault,
        result,
        success: error.is_none() && run.result == PickResult::Success,
        stop_cause: match run.result {
            PickResult::Fault(cause) if error.is_none() => Some(format!("{cause:?}")),
            _ => None,
        },
        max_speed_ratio: run.max_speed_ratio,
        max_torque_ratio: run.max_torque_ratio,
        min_tool_clearance_mm: run.min_tool_clearance_m * 1e3,
        end_joint_speed_rad_s: run.end_joint_speed_rad_s,
        safety: run.safety,
        violations: found,
    }
}

/// The worst of each invariant over `rows`: speed ratio, applied torque
/// ratio, lowest gripper over the disc (mm), joint-range margin (deg), camera
/// and self clearance (mm), gripper speed near the part (mm/s).
fn worst_cells(rows: &[&FaultTrial]) -> String {
    let max = |f: fn(&SafetyWorst) -> f64| {
        rows.iter()
            .map(|t| f(&t.safety))
            .filter(|v| v.is_finite())
            .fold(f64::NAN, f64::max)
    };
    let min = |f: fn(&SafetyWorst) -> f64| {
        rows.iter()
            .map(|t| f(&t.safety))
            .filter(|v| v.is_finite())
            .fold(f64::NAN, f64::min)
    };
    format!(
        "{:.2} | {:.3} | {:.1} | {:.1} | {:.0} | {:.0} | {:.0}",
        max(|w| w.speed_ratio),
        max(|w| w.applied_torque_ratio),
        min(|w| w.disc_clearance_mm),
        min(|w| w.joint_limit_margin_deg),
        min(|w| w.camera_clearance_mm),
        min(|w| w.self_clearance_mm),
        max(|w| w.near_part_speed_mm_s),
    )
}

/// The fault-against-outcome table (markdown), with every invariant's worst
/// value per fault and over all trials.
pub fn fault_table(trials: &[FaultTrial]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "| fault | trials | success | controlled stop (cause: trials) | other end | unsafe | speed / limit | applied torque / limit | gripper over disc (mm) | joint range margin (deg) | camera clearance (mm) | self clearance (mm) | speed near part (mm/s) |\n|---|---:|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    for kind in FaultKind::ALL {
        let rows: Vec<&FaultTrial> = trials.iter().filter(|t| t.kind == kind).collect();
        if rows.is_empty() {
            continue;
        }
        let successes = rows.iter().filter(|t| t.success).count();
        let mut causes: Vec<(String, usize)> = Vec::new();
        let mut others: Vec<(String, usize)> = Vec::new();
        for t in &rows {
            let (list, key) = match (&t.stop_cause, t.success) {
                (Some(cause), _) => (&mut causes, cause.clone()),
                (None, false) => (&mut others, t.result.clone()),
                (None, true) => continue,
            };
            match list.iter_mut().find(|(name, _)| *name == key) {
                Some((_, n)) => *n += 1,
                None => list.push((key, 1)),
            }
        }
        let join = |list: &mut Vec<(String, usize)>| {
            list.sort_by_key(|(_, n)| std::cmp::Reverse(*n));
            let text: Vec<String> = list.iter().map(|(k, n)| format!("{k}: {n}")).collect();
            if text.is_empty() {
                "-".to_owned()
            } else {
                text.join(", ")
            }
        };
        let unsafe_runs = rows.iter().filter(|t| !t.violations.is_empty()).count();
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} |",
            kind.name(),
            rows.len(),
            successes,
            join(&mut causes),
            join(&mut others),
            unsafe_runs,
            worst_cells(&rows)
        );
    }
    let all: Vec<&FaultTrial> = trials.iter().collect();
    let _ = writeln!(
        out,
        "| all | {} | {} | {} | {} | {} | {} |",
        all.len(),
        all.iter().filter(|t| t.success).count(),
        all.iter().filter(|t| t.stop_cause.is_some()).count(),
        all.iter()
            .filter(|t| !t.success && t.stop_cause.is_none())
            .count(),
        all.iter().filter(|t| !t.violations.is_empty()).count(),
        worst_cells(&all)
    );
    out
}

/// Writes `trials.csv`: one line per trial.
pub fn write_trials_csv(path: &std::path::Path, trials: &[FaultTrial]) -> Result<()> {
    let mut text = String::from(
        "trial,seed,fault_kind,fault,result,success,stop_cause,max_speed_ratio,applied_torque_ratio,min_tool_clearance_mm,joint_limit_margin_deg,camera_clearance_mm,self_clearance_mm,near_part_speed_mm_s,end_joint_speed_rad_s,violations\n",
    );
    for t in trials {
        let w = &t.safety;
        let _ = writeln!(
            text,
            "{},{},\"{}\",\"{}\",\"{}\",{},{},{:.4},{:.4},{:.2},{:.2},{:.1},{:.1},{:.1},{:.5},\"{}\"",
            t.trial,
            t.seed,
            t.kind.name(),
            t.fault,
            t.result.replace('"', "'"),
            t.success,
            t.stop_cause.as_deref().unwrap_or(""),
            t.max_speed_ratio,
            t.max_torque_ratio,
            t.min_tool_clearance_mm,
            w.joint_limit_margin_deg,
            w.camera_clearance_mm,
            w.self_clearance_mm,
            w.near_part_speed_mm_s,
            t.end_joint_speed_rad_s,
            t.violations.join("; ")
        );
    }
    fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}
