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
//! configuration) clears it.

use core::sync::atomic::{AtomicU8, Ordering};

use shared::safety::BoardFault;

/// 0: no fault; otherwise [`to_code`] of the first fault latched.
static LATCHED: AtomicU8 = AtomicU8::new(0);

/// The code a fault is stored as (here, and across a reset by the STM32 board).
pub(crate) fn to_code(fault: BoardFault) -> u8 {
    match fault {
        BoardFault::Panic => 1,
        BoardFault::HardFault => 2,
        BoardFault::UnexpectedInterrupt => 3,
        BoardFault::WatchdogReset => 4,
    }
}

pub(crate) fn from_code(code: u8) -> Option<BoardFault> {
    match code {
        1 => Some(BoardFault::Panic),
        2 => Some(BoardFault::HardFault),
        3 => Some(BoardFault::UnexpectedInterrupt),
        4 => Some(BoardFault::WatchdogReset),
        _ => None,
    }
}

/// Latches `fault` (the first one is kept). Callable from any handler: one
/// compare-and-swap, no lock.
pub fn latch(fault: BoardFault) {
    let _ = LATCHED.compare_exchange(0, to_code(fault), Ordering::SeqCst, Ordering::SeqCst);
}

/// The latched fault, if any.
pub fn latched() -> Option<BoardFault> {
    from_code(LATCHED.load(Ordering::SeqCst))
}

/// The host has acknowledged the fault.
pub fn acknowledge() {
    LATCHED.store(0, Ordering::SeqCst);
}
