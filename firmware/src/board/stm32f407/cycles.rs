//! The control cycle's cost in core clock cycles, from the Cortex-M4's DWT
//! cycle counter (CYCCNT, 32 bits: wraps every 2^32 / 168 MHz = 25.6 s, far
//! longer than any cycle measured with it).

use cortex_m::peripheral::{DCB, DWT};

use crate::board::CycleCounter;

/// Owns the DWT so nothing else can stop or reset the counter.
pub struct DwtCycles {
    _dwt: DWT,
}

impl DwtCycles {
    /// Turns on the trace block (DEMCR.TRCENA, without which the DWT does not
    /// count) and the cycle counter. Works without a debugger attached.
    pub fn start(mut dcb: DCB, mut dwt: DWT) -> Self {
        dcb.enable_trace();
        dwt.enable_cycle_counter();
        DwtCycles { _dwt: dwt }
    }
}

impl CycleCounter for DwtCycles {
    fn now(&self) -> u32 {
        DWT::cycle_count()
    }

    fn scale(&self) -> u32 {
        1
    }

    fn unit(&self) -> &'static str {
        "cycles"
    }
}
