//! The emulated board's plant and cycle counter. There are no motors or
//! encoders: in lock step the simulator sends each period's encoder counts as
//! a sensor-sample frame and receives the torques as an actuator-command
//! frame, so the plant here only refuses to pretend and keeps the drives off.
//!
//! The cycle counter is the AN386's CMSDK TIMER0 (25 MHz) running free. Under
//! `qemu-system-arm -icount shift=0` each instruction advances virtual time by
//! 1 ns, so one count is 40 instructions: costs are reported in instructions
//! with a 40-instruction resolution. Without `-icount` the counter follows the
//! host's clock and the figures mean nothing (the tests that report them run
//! with it).

use shared::protocol::CostUnit;

use super::mmio::Reg;
use crate::board::CycleCounter;
#[cfg(not(feature = "free-run"))]
use crate::board::{validate_torques, BoardError, PlantIo, PlantReading, JOINTS};

const TIMER0: Reg = Reg(0x4000_0000);
const CTRL: Reg = TIMER0.at(0x00);
const VALUE: Reg = TIMER0.at(0x04);
const RELOAD: Reg = TIMER0.at(0x08);
const CTRL_ENABLE: u32 = 1 << 0;

/// Instructions per TIMER0 count with `-icount shift=0` (1 ns each, 25 MHz).
const INSTRUCTIONS_PER_COUNT: u32 = 40;

/// The simulator's plant, reached through the link (in lock step; running
/// free the plant is `free_run::FreeRunPlant`).
#[cfg(not(feature = "free-run"))]
pub struct LockStepPlant {
    _owned: (),
}

#[cfg(not(feature = "free-run"))]
impl LockStepPlant {
    pub(super) fn take() -> Self {
        LockStepPlant { _owned: () }
    }
}

#[cfg(not(feature = "free-run"))]
impl PlantIo for LockStepPlant {
    fn reading_time_us(&mut self, _now_us: u64) -> Result<u64, BoardError> {
        Err(BoardError::NotOnThisBoard { device: "encoders" })
    }

    fn read_sample(&mut self, _camera_trigger: bool) -> Result<PlantReading, BoardError> {
        Err(BoardError::NotOnThisBoard { device: "encoders" })
    }

    fn apply(
        &mut self,
        torque_nm: &[f32; JOINTS],
        _gripper_closed: bool,
    ) -> Result<(), BoardError> {
        validate_torques(torque_nm)?;
        Err(BoardError::NotOnThisBoard {
            device: "servo amplifiers",
        })
    }

    fn disable(&mut self) {}

    /// The simulator's arm has no brake output of ours: its drives' own
    /// watchdog brakes it.
    fn set_brakes(&mut self, _engaged: bool) {}
}

/// TIMER0, free-running.
#[derive(Clone, Copy)]
pub struct InstructionCounter {
    _owned: (),
}

impl InstructionCounter {
    pub(super) fn start() -> Self {
        CTRL.write(0);
        RELOAD.write(u32::MAX);
        VALUE.write(u32::MAX);
        CTRL.write(CTRL_ENABLE);
        InstructionCounter { _owned: () }
    }
}

impl CycleCounter for InstructionCounter {
    fn now(&self) -> u32 {
        // The timer counts down; flip it so the difference of two readings is
        // the time between them.
        u32::MAX - VALUE.read()
    }

    fn scale(&self) -> u32 {
        INSTRUCTIONS_PER_COUNT
    }

    fn cost_unit(&self) -> CostUnit {
        // Running free there is no `-icount`: a count is 40 ns of the host's
        // clock (see `board::qemu::CPU_HZ`).
        if cfg!(feature = "free-run") {
            CostUnit::Nanoseconds
        } else {
            CostUnit::Instructions
        }
    }
}
