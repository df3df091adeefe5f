//! Power-on homing trials: a world drawn from a seed (counter offsets,
//! potentiometer biases, where the arm stands), the controller linked into
//! this process homing it, and the result scored against the world's
//! drawn offsets (truth the controller never sees).

use anyhow::{bail, Context, Result};
use serde::Serialize;
use shared::app::power_on_homing::HomingStage;
use shared::app::ControllerApp;
use shared::protocol::{Message, JOINTS, PROTOCOL_VERSION};

use crate::scenario::pick::PickExperiment;
use crate::world::World;

/// Longest a homing may take before the trial gives up, simulated s.
pub const HOMING_TIME_LIMIT_S: f64 = 30.0;

/// One power-on's homing, scored.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HomingTrial {
    pub seed: u64,
    /// The counter offsets the world drew (truth).
    pub true_offsets: [i32; JOINTS],
    /// What homing found, if it finished.
    pub homed_offsets: Option<[i32; JOINTS]>,
    /// Why homing stopped, if it failed.
    pub error: Option<String>,
    /// Simulated time to the end of homing, s.
    pub duration_s: f64,
    /// The fastest any joint turned, rad/s, which joint (0-based) and when (s).
    pub max_joint_speed_rad_s: f64,
    pub max_speed_joint: usize,
    pub max_speed_at_s: f64,
    /// The farthest any joint went from where it stood at power-on, rad.
    pub max_excursion_rad: f64,
    /// How far the arm ended from where it stood at power-on, worst joint, rad.
    pub end_offset_rad: f64,
    /// Every counter reads at the end what it read at power-on (the pick
    /// starts from the very counts it would have without homing).
    pub back_on_power_on_counts: bool,
}

impl HomingTrial {
    /// Every joint's offset is the drawn one, to the count.
    pub fn exact(&self) -> bool {
        self.homed_offsets == Some(self.true_offsets)
    }
}

/// Homes the world of `experiment` drawn from `seed` with the controller
/// linked into this process.
pub fn run_homing_trial(experiment: &PickExperiment, seed: u64) -> Result<HomingTrial> {
    let mut world = World::new(experiment, seed)
        .with_context(|| format!("building the world of {} (seed {seed})", experiment.name))?;
    let config = world.cell_config();
    if !config.home_at_power_on {
        bail!("the experiment's counters need no homing (robot.homing.counters_start_anywhere)");
    }
    let rate = experiment.robot.control_rate_hz.round() as u32;
    let mut app = ControllerApp::new("homing", rate);
    let mut out = heapless::Vec::new();
    app.on_message(
        &Message::Hello {
            protocol_version: PROTOCOL_VERSION,
            peer_name: heapless::String::new(),
        },
        &mut out,
    );
    out.clear();
    app.on_message(&Message::Configure(config), &mut out);
    if app.pick().is_none() {
        bail!("the controller refused the cell configuration: {out:?}");
    }
    let start = world.truth().q_rad;
    let mut max_speed: f64 = 0.0;
    let mut max_excursion: f64 = 0.0;
    let (mut max_speed_joint, mut max_speed_at_s) = (0, 0.0);
    let mut counts: Option<([i32; JOINTS], [i32; JOINTS])> = None;
    let stage = loop {
        let now = world.time_s();
        if now > HOMING_TIME_LIMIT_S {
            bail!("seed {seed}: homing still running after {now:.1} s");
        }
        if let Some(stage @ (HomingStage::Homed(_) | HomingStage::Failed(_))) = app.homing_stage() {
            break stage;
        }
        let sample = world.sensor_sample();
        let first = counts.map_or(sample.joint_counts, |(first, _)| first);
        counts = Some((first, sample.joint_counts));
        out.clear();
        app.on_message(&Message::SensorSample(sample), &mut out);
        let Some(command) = out.iter().find_map(|m| match m {
            Message::ActuatorCommand(c) => Some(*c),
            _ => None,
        }) else {
            bail!("seed {seed}: no command at t = {now:.3} s: {out:?}");
        };
        world.apply(&command)?;
        let truth = world.truth();
        for (j, ((qd, q), q0)) in truth
            .qd_rad_s
            .iter()
            .zip(truth.q_rad.iter())
            .zip(start.iter())
            .enumerate()
        {
            if qd.abs() > max_speed {
                max_speed = qd.abs();
                max_speed_joint = j;
                max_speed_at_s = truth.time_s;
            }
            max_excursion = max_excursion.max((q - q0).abs());
        }
    };
    let end = world.truth().q_rad;
    let end_offset_rad = end
        .iter()
        .zip(start.iter())
        .fold(0.0_f64, |w, (q, q0)| w.max((q - q0).abs()));
    Ok(HomingTrial {
        seed,
        true_offsets: world.homing_sensors().counter_offsets(),
        homed_offsets: match stage {
            HomingStage::Homed(offsets) => Some(offsets.counts),
            _ => None,
        },
        error: app.homing_error().map(|e| e.to_string()),
        duration_s: world.time_s(),
        max_joint_speed_rad_s: max_speed,
        max_speed_joint,
        max_speed_at_s,
        max_excursion_rad: max_excursion,
        end_offset_rad,
        back_on_power_on_counts: counts.is_some_and(|(first, last)| first == last),
    })
}
