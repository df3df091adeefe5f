//! A thread-mode executor that sleeps with `WFI`.
//!
//! embassy's stock Cortex-M thread executor sleeps with `WFE` and wakes with
//! `SEV`. QEMU 7.2 treats `WFE` as a no-op, so that executor spins and keeps a
//! host core busy. This loop sleeps with `WFI` instead, which works on QEMU and
//! on real silicon alike: every wake-up source of this firmware is an
//! interrupt (UART, timers), and the pender only ever runs from one of those
//! interrupts or from the executor itself.
//!
//! The sleep check runs with interrupts masked so that a pend arriving between
//! "nothing to do" and `WFI` is not lost: a pending interrupt still ends `WFI`
//! while PRIMASK is set, and it is taken as soon as interrupts are unmasked.

use core::sync::atomic::{AtomicBool, Ordering};

use embassy_executor::{raw, Spawner};

/// Set by the pender when a task was woken; cleared before each poll.
static WORK_PENDING: AtomicBool = AtomicBool::new(true);

/// The pender the raw executor calls when a task becomes ready.
///
/// It may run in any interrupt or synchronously from `poll`, so it only
/// records that polling is due (never polls itself).
#[unsafe(export_name = "__pender")]
fn pender(_context: *mut ()) {
    WORK_PENDING.store(true, Ordering::Release);
}

/// Runs the executor forever: `init` spawns the tasks, then poll / sleep.
pub fn run(init: impl FnOnce(Spawner)) -> ! {
    static mut EXECUTOR: Option<raw::Executor> = None;
    // SAFETY: `run` is called once from `main` before any interrupt that
    // touches the executor is unmasked, and never returns, so this is the only
    // access that creates the executor; afterwards it is only read through the
    // shared `&'static` reference below.
    let executor: &'static raw::Executor = unsafe {
        let slot = &mut *core::ptr::addr_of_mut!(EXECUTOR);
        slot.insert(raw::Executor::new(core::ptr::null_mut()))
    };
    init(executor.spawner());
    loop {
        WORK_PENDING.store(false, Ordering::Release);
        // SAFETY: `poll` is only called from this loop, never reentrantly
        // (the pender above does not poll).
        unsafe { executor.poll() };
        cortex_m::interrupt::disable();
        if !WORK_PENDING.load(Ordering::Acquire) {
            cortex_m::asm::wfi();
        }
        // SAFETY: interrupts were enabled before this critical window; the
        // firmware holds no critical section across the executor loop.
        unsafe { cortex_m::interrupt::enable() };
    }
}
