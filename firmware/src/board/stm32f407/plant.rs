//! The board's side of the control loop ([`PlantIo`]): joint and conveyor
//! encoders in; servo amplifiers, gripper and camera trigger out.
//!
//! | signal | pin | direction | level |
//! | --- | --- | --- | --- |
//! | gripper | PD0 | out | high = close |
//! | camera trigger | PD1 | out | high for one control period per trigger |
//! | part present | PD4 | in, pull-down | high = a part between the closed jaws |
//! | emergency stop | PD8 | in, pull-down | high = chain closed (run); low = pressed or a wire broken |
//! | amplifier fault | PD9 | in, pull-up | low = a drive's fault output is active (open-collector outputs, wired-OR) |
//! | holding brakes | PD10 | out | high = released; low (and at reset, with the brake driver's pull-down) = engaged |
//!
//! The emergency-stop and fault inputs are read with every sample and latch
//! a board fault (`crate::board::fail_safe`): the drive interlock turns the
//! drives off in that period and keeps them off until the host's next
//! accepted configuration, whatever the input does in between. The
//! emergency-stop input is active low so that a broken wire stops the cell
//! too. It is the controller's side of the stop only: the emergency-stop
//! chain must also cut the amplifiers' power in hardware (a category 0 stop),
//! which no firmware can guarantee. The brake line is separate from the
//! amplifier enable, so that the brakes can bite while the drives still hold
//! the arm (parking, `shared::safety::parking`); `disable` drops both.
//!
//! The camera trigger is a pulse one control period wide (1 ms at the 1 kHz
//! control rate): `read_sample(true)` raises it and latches every counter in
//! the same critical section ([`super::latch`]), the next `read_sample(false)`
//! lowers it. The trigger id travels over the link (the control loop's
//! `TriggerEvent`), not on the pin; the camera exposes on the rising edge,
//! which is when the encoders for that id were latched. Triggers in consecutive
//! periods merge into one longer pulse and one exposure: the later ids get no
//! frame, which the host sees as a camera dropout. Delaying them instead
//! would pair an image with encoder counts latched a period earlier, a silent
//! error in the calibration data. (The pick fires the camera every few tens
//! of periods, so this does not arise there.)

use embassy_stm32::gpio::{Input, Level, Output};

use super::conveyor::ConveyorEncoder;
use super::encoders::QuadratureEncoders;
use super::homing_inputs::HomingSensors;
use super::latch::{latch, LatchHardware};
use super::servo::ServoAmplifiers;
use super::JOINT_SIGNS;
use crate::board::{validate_torques, BoardError, HomingInputs, PlantIo, PlantReading, JOINTS};

/// Everything the control loop drives or reads, owned in one place.
pub struct Stm32Plant {
    joints: QuadratureEncoders,
    conveyor: ConveyorEncoder,
    servos: ServoAmplifiers,
    gripper: Output<'static>,
    camera_trigger: Output<'static>,
    part_present: Input<'static>,
    emergency_stop_ok: Input<'static>,
    drive_fault_n: Input<'static>,
    brake_release: Output<'static>,
    /// Conveyor decoder trouble already logged, and samples since.
    conveyor_reported: ConveyorReport,
    homing: HomingSensors,
    /// The joint counters as the last `read_sample` latched them: raw and
    /// unwrapped (an index latch is turned into a count against them).
    last_raw: [u16; JOINTS],
    last_counts: [i32; JOINTS],
}

/// Rate-limits the conveyor decoder's warnings: the log goes over RTT, which
/// blocks when a probe is attached and its buffer is full, so a noisy encoder
/// must not put a log line into every control period.
struct ConveyorReport {
    skipped: u32,
    faults: u32,
    samples_since: u32,
}

/// At most one conveyor warning per this many samples (1 s at 1 kHz).
const CONVEYOR_REPORT_EVERY: u32 = 1000;

/// The devices the plant is built from.
pub struct PlantDevices {
    pub joints: QuadratureEncoders,
    pub conveyor: ConveyorEncoder,
    pub servos: ServoAmplifiers,
    /// PD0, created low (open).
    pub gripper: Output<'static>,
    /// PD1, created low.
    pub camera_trigger: Output<'static>,
    /// PD4, pulled down: the gripper's part-present switch (high = a part
    /// between the closed jaws).
    pub part_present: Input<'static>,
    /// PD8, pulled down: the emergency-stop chain (high = closed, run).
    pub emergency_stop_ok: Input<'static>,
    /// PD9, pulled up: the amplifiers' fault outputs, wired-OR (low = fault).
    pub drive_fault_n: Input<'static>,
    /// PD10, created low (brakes engaged): high releases the holding brakes.
    pub brake_release: Output<'static>,
    /// The potentiometers and index inputs (`homing_inputs`).
    pub homing: HomingSensors,
}

impl Stm32Plant {
    pub fn new(devices: PlantDevices) -> Self {
        Stm32Plant {
            joints: devices.joints,
            conveyor: devices.conveyor,
            servos: devices.servos,
            gripper: devices.gripper,
            camera_trigger: devices.camera_trigger,
            part_present: devices.part_present,
            emergency_stop_ok: devices.emergency_stop_ok,
            drive_fault_n: devices.drive_fault_n,
            brake_release: devices.brake_release,
            conveyor_reported: ConveyorReport {
                skipped: 0,
                faults: 0,
                samples_since: CONVEYOR_REPORT_EVERY,
            },
            homing: devices.homing,
            last_raw: [0; JOINTS],
            last_counts: [0; JOINTS],
        }
    }

    /// The seam has no error for a lossy conveyor decoder (its count stays
    /// usable, a few counts short), so lost steps and decoder faults are
    /// logged, at most once a second.
    fn report_conveyor_trouble(&mut self) {
        let report = &mut self.conveyor_reported;
        report.samples_since = report.samples_since.saturating_add(1);
        if report.samples_since < CONVEYOR_REPORT_EVERY {
            return;
        }
        let skipped = self.conveyor.skipped_steps();
        let faults = self.conveyor.faults();
        if faults != report.faults {
            defmt::error!(
                "conveyor encoder: decoder fault ({} so far), decoding stopped",
                faults
            );
        } else if skipped != report.skipped {
            defmt::warn!(
                "conveyor encoder: {} steps lost so far (edges closer than the EXTI handler's latency)",
                skipped
            );
        } else {
            return;
        }
        report.skipped = skipped;
        report.faults = faults;
        report.samples_since = 0;
    }
}

/// The trigger line and the counters, as the latch sees them.
struct TriggerAndCounters<'a> {
    trigger: &'a mut Output<'static>,
    joints: &'a QuadratureEncoders,
    conveyor: &'a ConveyorEncoder,
}

impl LatchHardware for TriggerAndCounters<'_> {
    #[inline(always)]
    fn set_trigger(&mut self, high: bool) {
        self.trigger
            .set_level(if high { Level::High } else { Level::Low });
    }

    #[inline(always)]
    fn joint_counters(&self) -> [u16; 6] {
        self.joints.raw()
    }

    #[inline(always)]
    fn conveyor_counter(&self) -> u32 {
        self.conveyor.count()
    }
}

impl PlantIo for Stm32Plant {
    /// The encoders are read now: the period's start.
    fn reading_time_us(&mut self, now_us: u64) -> Result<u64, BoardError> {
        Ok(now_us)
    }

    fn read_sample(&mut self, camera_trigger: bool) -> Result<PlantReading, BoardError> {
        // One critical section: the trigger edge, then every counter, with
        // no interrupt between them (the skew is in firmware/README.md).
        let latched = critical_section::with(|_| {
            latch(
                &mut TriggerAndCounters {
                    trigger: &mut self.camera_trigger,
                    joints: &self.joints,
                    conveyor: &self.conveyor,
                },
                camera_trigger,
            )
        });
        let joint_counts = self.joints.unwrap_counts(latched.joints)?;
        self.last_raw = latched.joints;
        self.last_counts = joint_counts;
        self.report_conveyor_trouble();
        Ok(PlantReading {
            joint_counts,
            conveyor_counts: latched.conveyor,
            part_in_gripper: self.part_present.is_high(),
            emergency_stop: self.emergency_stop_ok.is_low(),
            drive_fault: self.drive_fault_n.is_low(),
        })
    }

    fn read_homing_inputs(&mut self) -> Result<HomingInputs, BoardError> {
        let signs: [i32; JOINTS] = core::array::from_fn(|j| {
            JOINT_SIGNS
                .encoder_count(j, 1)
                .and_then(|s| i32::try_from(s).ok())
                .unwrap_or(1)
        });
        Ok(HomingInputs {
            joint_pots_rad: self.homing.potentiometers(),
            joint_index_counts: self
                .homing
                .index_counts(&self.last_raw, &self.last_counts, &signs),
        })
    }

    fn apply(&mut self, torque_nm: &[f32; JOINTS], gripper_closed: bool) -> Result<(), BoardError> {
        if let Err(error) = validate_torques(torque_nm) {
            self.disable();
            return Err(error);
        }
        self.servos.drive(torque_nm);
        if gripper_closed {
            self.gripper.set_high();
        } else {
            self.gripper.set_low();
        }
        Ok(())
    }

    fn disable(&mut self) {
        self.servos.disable();
        self.brake_release.set_low();
    }

    fn set_brakes(&mut self, engaged: bool) {
        // Never released without the drives on (a latched fault keeps the
        // enable low even when `apply` ran).
        if engaged || !self.servos.enabled() {
            self.brake_release.set_low();
        } else {
            self.brake_release.set_high();
        }
    }
}
