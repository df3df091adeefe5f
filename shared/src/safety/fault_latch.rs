//! A board fault latched by a handler until the host acknowledges it, and
//! the same cause kept across the reset that may follow.
//!
//! Why here and not in the firmware: the rules (the first fault is kept, only
//! an acknowledgement clears it, a word left in RAM by a previous run is
//! trusted only with its mark) are what keeps the drives off after a fault,
//! so they are unit-tested on the host; the board only owns the static and
//! the RAM word.

use core::sync::atomic::{AtomicU8, Ordering};

use super::BoardFault;

impl BoardFault {
    /// A non-zero code for each fault (0 stands for none).
    pub fn code(self) -> u8 {
        match self {
            BoardFault::Panic => 1,
            BoardFault::HardFault => 2,
            BoardFault::UnexpectedInterrupt => 3,
            BoardFault::WatchdogReset => 4,
            BoardFault::EmergencyStop => 5,
            BoardFault::DriveFault => 6,
            BoardFault::DeadlineMissed => 7,
            BoardFault::StackOverflow => 8,
        }
    }

    /// The fault of `code`, if it is one ([`BoardFault::code`]).
    pub fn from_code(code: u8) -> Option<BoardFault> {
        match code {
            1 => Some(BoardFault::Panic),
            2 => Some(BoardFault::HardFault),
            3 => Some(BoardFault::UnexpectedInterrupt),
            4 => Some(BoardFault::WatchdogReset),
            5 => Some(BoardFault::EmergencyStop),
            6 => Some(BoardFault::DriveFault),
            7 => Some(BoardFault::DeadlineMissed),
            8 => Some(BoardFault::StackOverflow),
            _ => None,
        }
    }
}

/// The latch: lock-free (one compare-and-swap), so a fault handler can set
/// it whatever it interrupted.
#[derive(Debug, Default)]
pub struct FaultLatch {
    code: AtomicU8,
}

impl FaultLatch {
    /// Nothing latched.
    pub const fn new() -> Self {
        FaultLatch {
            code: AtomicU8::new(0),
        }
    }

    /// Latches `fault`; an earlier fault, if any, is kept.
    pub fn latch(&self, fault: BoardFault) {
        let _ = self
            .code
            .compare_exchange(0, fault.code(), Ordering::SeqCst, Ordering::SeqCst);
    }

    /// The fault latched, if any.
    pub fn latched(&self) -> Option<BoardFault> {
        BoardFault::from_code(self.code.load(Ordering::SeqCst))
    }

    /// The host has acknowledged the fault.
    pub fn acknowledge(&self) {
        self.code.store(0, Ordering::SeqCst);
    }
}

/// The upper 24 bits of a word that carries a fault across a reset: RAM's
/// contents at power-on match it with a chance of 2^-24 per boot (and then
/// only keep the drives off until acknowledged, the safe side).
pub const RESET_MARK: u32 = 0xFA17_5A00;

/// The word a handler leaves in RAM that survives a reset.
pub fn reset_word(fault: BoardFault) -> u32 {
    RESET_MARK | u32::from(fault.code())
}

/// The fault a previous run left, if `word` carries one.
pub fn fault_from_reset_word(word: u32) -> Option<BoardFault> {
    if word & 0xFFFF_FF00 != RESET_MARK {
        return None;
    }
    BoardFault::from_code(u8::try_from(word & 0xFF).ok()?)
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: [BoardFault; 8] = [
        BoardFault::Panic,
        BoardFault::HardFault,
        BoardFault::UnexpectedInterrupt,
        BoardFault::WatchdogReset,
        BoardFault::EmergencyStop,
        BoardFault::DriveFault,
        BoardFault::DeadlineMissed,
        BoardFault::StackOverflow,
    ];

    #[test]
    fn the_first_fault_stays_until_acknowledged() {
        let latch = FaultLatch::new();
        assert_eq!(latch.latched(), None);
        latch.latch(BoardFault::UnexpectedInterrupt);
        latch.latch(BoardFault::HardFault);
        for _ in 0..3 {
            assert_eq!(latch.latched(), Some(BoardFault::UnexpectedInterrupt));
        }
        latch.acknowledge();
        assert_eq!(latch.latched(), None);
    }

    #[test]
    fn a_fault_survives_a_reset_only_with_its_mark() {
        for fault in ALL {
            assert_eq!(BoardFault::from_code(fault.code()), Some(fault));
            assert_ne!(fault.code(), 0);
            assert_eq!(fault_from_reset_word(reset_word(fault)), Some(fault));
        }
        for word in [
            0,
            u32::MAX,
            0xFA17_5A00,
            0xFA17_5A09,
            0xFA17_5AFF,
            0x0000_0001,
            0xFA17_5B01,
        ] {
            assert_eq!(fault_from_reset_word(word), None, "{word:#x}");
        }
    }
}
