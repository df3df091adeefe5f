//! CMSDK APB dual timer (timer 1) of the mps2-an386 as a free-running counter.

use core::ptr::{read_volatile, write_volatile};

const TIMER1_LOAD: *mut u32 = 0x4000_2000 as *mut u32;
const TIMER1_VALUE: *const u32 = 0x4000_2004 as *const u32;
const TIMER1_CONTROL: *mut u32 = 0x4000_2008 as *mut u32;
/// Enable (bit 7), free-running (bit 6 clear), no interrupt, prescale 1, 32-bit (bit 1).
const CONTROL_FREE_RUNNING_32: u32 = 0x82;
/// Instructions per timer count under `-icount shift=0`: 1 ns per instruction, 25 MHz timer.
pub const INSTRUCTIONS_PER_COUNT: u64 = 40;

/// Down-counting 32-bit timer at 25 MHz.
pub struct DualTimer;

impl DualTimer {
    pub fn start() -> Self {
        // SAFETY: fixed MMIO registers of the mps2-an386's CMSDK dual timer,
        // written once before any measurement; nothing else uses timer 1.
        unsafe {
            write_volatile(TIMER1_CONTROL, 0);
            write_volatile(TIMER1_LOAD, u32::MAX);
            write_volatile(TIMER1_CONTROL, CONTROL_FREE_RUNNING_32);
        }
        DualTimer
    }

    fn now(&self) -> u32 {
        // SAFETY: read-only access to the current-value register.
        unsafe { read_volatile(TIMER1_VALUE) }
    }

    /// Mean instructions per call of `f` over `calls` calls (rounded down).
    pub fn measure<R>(&self, calls: u32, mut f: impl FnMut() -> R) -> u64 {
        let before = self.now();
        for _ in 0..calls {
            core::hint::black_box(f());
        }
        let after = self.now();
        u64::from(before.wrapping_sub(after)) * INSTRUCTIONS_PER_COUNT / u64::from(calls.max(1))
    }
}
