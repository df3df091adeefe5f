//! The emulated board's cycle counter. (There are no motors or encoders: in
//! lock step the simulator sends each period's encoder counts as a
//! sensor-sample frame and receives the torques as an actuator-command frame,
//! `crate::board::lock_step`.)
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

const TIMER0: Reg = Reg(0x4000_0000);
const CTRL: Reg = TIMER0.at(0x00);
const VALUE: Reg = TIMER0.at(0x04);
const RELOAD: Reg = TIMER0.at(0x08);
const CTRL_ENABLE: u32 = 1 << 0;

/// Instructions per TIMER0 count with `-icount shift=0` (1 ns each, 25 MHz).
const INSTRUCTIONS_PER_COUNT: u32 = 40;

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

/// TIMER0 now, counting up (for the interrupt handlers' tally,
/// [`crate::board::interrupt_time`], which holds no counter).
pub fn count_now() -> u32 {
    // The timer counts down; flip it so the difference of two readings is
    // the time between them.
    u32::MAX - VALUE.read()
}

impl CycleCounter for InstructionCounter {
    fn now(&self) -> u32 {
        count_now()
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
