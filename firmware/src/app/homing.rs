//! Homing at power-on in the control loop: before the pick's first period,
//! every sample runs a homing period (`shared::app::power_on_homing`) and
//! its torques go out through the same interlock and outputs as the
//! pick's. Once homed, the loop hands the pick each sample less the
//! counters' offsets: six subtractions, the pick's period otherwise
//! unchanged. Every accepted configuration homes again (it is the restart
//! after a stop, after which the arm may have been moved with the drives
//! off, or, in the simulator, be another cell's); a failed homing is held,
//! reported in telemetry every telemetry period, and starts over with the
//! next configuration.

use shared::app::homing::HomingError;
use shared::app::power_on_homing::{HomedOffsets, HomingStage, PowerOnHoming};
use shared::protocol::{ActuatorCommand, CellConfig, GripperCommand, PickPhase, SensorSample};

/// Where the control loop's homing stands.
pub struct Homing {
    run: Option<Run>,
    /// The offsets the pick's samples are corrected with, once known.
    offsets: Option<HomedOffsets>,
}

/// A homing under way (or failed).
struct Run {
    homing: PowerOnHoming,
    counts_per_rad: [f32; 6],
    telemetry_period_ticks: u16,
    ticks: u32,
    /// The interlock's offsets while homing: from the first sample's
    /// potentiometers, fixed so that its speeds see no jump.
    interlock_offsets: Option<HomedOffsets>,
    last: Option<(u32, u64, ActuatorCommand)>,
    /// The failure was logged.
    logged: bool,
}

/// One homing period's result.
pub struct HomingPeriod {
    pub command: ActuatorCommand,
    /// The sample as the interlock is to see it (coarse offsets applied).
    pub interlock_sample: SensorSample,
    /// A sample sent again: the same command, no period.
    pub repeated: bool,
    /// The pick's phase the period stands for (reconfiguration gate, interlock).
    pub phase: PickPhase,
    /// Homing failed: why, for telemetry due this period.
    pub report: Option<HomingError>,
    /// Homing just finished: the pick starts with the next sample, and the
    /// interlock's speeds start over on homed counts.
    pub homed: bool,
}

impl Homing {
    pub const fn new() -> Self {
        Self {
            run: None,
            offsets: None,
        }
    }

    /// A configuration was accepted: homing starts unless the counters
    /// need none. Out of line: the homing's model is
    /// built in this frame, not in the control loop's.
    #[inline(never)]
    pub fn configure(&mut self, config: &CellConfig) {
        if !config.home_at_power_on {
            self.run = None;
            self.offsets = Some(HomedOffsets::ZERO);
            return;
        }
        self.offsets = None;
        self.run = match PowerOnHoming::new(&config.joint_counts_per_rad) {
            Ok(homing) => Some(Run {
                homing,
                counts_per_rad: config.joint_counts_per_rad,
                telemetry_period_ticks: config.telemetry_period_ticks,
                ticks: 0,
                interlock_offsets: None,
                last: None,
                logged: false,
            }),
            Err(e) => {
                defmt::error!(
                    "homing: commissioning data unusable: {}",
                    defmt::Debug2Format(&e)
                );
                None
            }
        };
    }

    /// The offsets of the pick's samples, once homed (or none needed).
    pub fn offsets(&self) -> Option<HomedOffsets> {
        self.offsets
    }

    /// Whether this sample is a homing period.
    pub fn active(&self) -> bool {
        self.offsets.is_none() && self.run.is_some()
    }

    /// The counts per radian homing runs with (the interlock's scale).
    pub fn counts_per_rad(&self) -> Option<[f32; 6]> {
        self.run.as_ref().map(|run| run.counts_per_rad)
    }

    /// One homing period for `sample`.
    pub fn period(&mut self, sample: &SensorSample) -> Option<HomingPeriod> {
        if self.offsets.is_some() {
            return None;
        }
        let run = self.run.as_mut()?;
        let interlock_offsets = *run
            .interlock_offsets
            .get_or_insert_with(|| HomedOffsets::from_potentiometers(sample, &run.counts_per_rad));
        let mut interlock_sample = *sample;
        interlock_offsets.apply(&mut interlock_sample);
        let repeated = run
            .last
            .is_some_and(|(seq, time_us, _)| seq == sample.seq && time_us == sample.time_us);
        let command = match run.last {
            Some((_, _, command)) if repeated => command,
            _ => {
                let command = ActuatorCommand {
                    seq: sample.seq,
                    joint_torque_nm: run.homing.period(sample),
                    gripper: GripperCommand::Open,
                    camera_trigger: None,
                };
                run.last = Some((sample.seq, sample.time_us, command));
                run.ticks = run.ticks.wrapping_add(1);
                command
            }
        };
        let mut homed = false;
        let mut report = None;
        let mut phase = PickPhase::Idle;
        match run.homing.stage() {
            HomingStage::Homed(offsets) if !repeated => {
                defmt::info!("homing: done, offsets {}", offsets.counts);
                self.offsets = Some(offsets);
                homed = true;
            }
            HomingStage::Failed(error) => {
                phase = PickPhase::Faulted;
                let every = u32::from(run.telemetry_period_ticks.max(1));
                if !repeated && run.ticks % every == 0 {
                    report = Some(error);
                }
                if !run.logged {
                    run.logged = true;
                    defmt::error!("homing: {}", defmt::Display2Format(&error));
                }
            }
            _ => {}
        }
        Some(HomingPeriod {
            command,
            interlock_sample,
            repeated,
            phase,
            report,
            homed,
        })
    }
}
