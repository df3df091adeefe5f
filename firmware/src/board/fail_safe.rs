//! Board faults latched outside the control period, for the drive interlock.
//!
//! A fault handler (the default handler of an unexpected interrupt; on the
//! STM32 also a HardFault or a panic of the previous run, found at boot)
//! first drops the amplifier enable itself (the board's `drives_off_now`,
//! one store), then latches its cause here. The control loop reads the latch
//! every period and trips its [`shared::safety::DriveInterlock`], and the
//! board's servo code refuses to raise the enable while the latch is set, so
//! a period already past its checks when the handler ran cannot turn the
//! drives back on. Only the host's acknowledgement (an accepted
//! configuration) clears it. The rules are `shared::safety::fault_latch`'s.

use shared::safety::{BoardFault, FaultLatch};

static LATCH: FaultLatch = FaultLatch::new();

/// Latches `fault` (the first one is kept). Callable from any handler: one
/// compare-and-swap, no lock.
pub fn latch(fault: BoardFault) {
    LATCH.latch(fault);
}

/// The latched fault, if any.
pub fn latched() -> Option<BoardFault> {
    LATCH.latched()
}

/// The host has acknowledged the fault.
pub fn acknowledge() {
    LATCH.acknowledge();
}
