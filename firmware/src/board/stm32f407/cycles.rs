//! The control cycle's cost in core clock cycles, from the Cortex-M4's DWT
//! cycle counter (CYCCNT, 32 bits: wraps every 2^32 / 168 MHz = 25.6 s, far
//! longer than any cycle measured with it).

use cortex_m::peripheral::{DCB, DWT};

use shared::protocol::CostUnit;

use crate::board::CycleCounter;

/// A reader of the cycle counter. `start` consumes the DWT and DCB handles,
/// so nothing else can stop or reset the counter; the readers (one per task
/// that measures) only read it.
#[derive(Clone, Copy)]
pub struct DwtCycles {
    _private: (),
}

impl DwtCycles {
    /// Turns on the trace block (DEMCR.TRCENA, without which the DWT does not
    /// count) and the cycle counter. Works without a debugger attached.
    pub fn start(mut dcb: DCB, mut dwt: DWT) -> Self {
        dcb.enable_trace();
        dwt.enable_cycle_counter();
        DwtCycles { _private: () }
    }
}

/// CYCCNT now (for the interrupt handlers' tally,
/// [`crate::board::interrupt_time`], which holds no counter).
pub fn count_now() -> u32 {
    DWT::cycle_count()
}

impl CycleCounter for DwtCycles {
    fn now(&self) -> u32 {
        count_now()
    }

    fn scale(&self) -> u32 {
        1
    }

    fn cost_unit(&self) -> CostUnit {
        CostUnit::Cycles
    }
}
