//! The firmware's three priority levels, all embassy raw executors with one
//! pender:
//! - thread mode (lowest): a loop that polls and sleeps with `WFI`; the
//!   worker (self-calibration, planning) runs here and may take seconds;
//! - [`Level::Link`] (middle): an interrupt executor for the serial link, so
//!   frames are decoded and paired while the worker computes;
//! - [`Level::Control`] (highest): an interrupt executor for the control loop,
//!   which preempts both.
//!
//! The interrupt executors run in the handler of a spare NVIC line the board
//! names ([`crate::board::active::CONTROL_IRQ`], `LINK_IRQ`); the pender pends
//! that line. embassy's stock Cortex-M executors are not used: the thread one
//! sleeps with `WFE`, which QEMU 7.2 treats as a no-op (it would spin a host
//! core), and both would bring their own `__pender`.
//!
//! The thread loop's sleep check runs with interrupts masked so that a pend
//! arriving between "nothing to do" and `WFI` is not lost: a pending interrupt
//! still ends `WFI` while PRIMASK is set, and is taken once unmasked.

use core::sync::atomic::{AtomicBool, Ordering};

use cortex_m::interrupt::InterruptNumber;
use cortex_m::peripheral::NVIC;
use embassy_executor::{raw, SendSpawner, Spawner};

/// Set by the pender when a thread-mode task was woken; cleared before each poll.
static WORK_PENDING: AtomicBool = AtomicBool::new(true);

/// The pender context of the thread-mode executor; an interrupt executor's
/// context is its NVIC line plus one.
const THREAD_CONTEXT: usize = 0;

/// An NVIC line given as a number.
#[derive(Clone, Copy)]
struct Line(u16);

// SAFETY: the numbers are the board's spare NVIC lines (see `board::active`).
unsafe impl InterruptNumber for Line {
    fn number(self) -> u16 {
        self.0
    }
}

/// The pender the raw executors call when a task becomes ready. It may run in
/// any interrupt or synchronously from `poll`, so it never polls itself.
#[unsafe(export_name = "__pender")]
fn pender(context: *mut ()) {
    let context = context as usize;
    if context == THREAD_CONTEXT {
        WORK_PENDING.store(true, Ordering::Release);
    } else if let Ok(line) = u16::try_from(context - 1) {
        NVIC::pend(Line(line));
    }
}

/// An interrupt priority level.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Level {
    Control,
    Link,
}

impl Level {
    /// NVIC priority byte (lower is more urgent). The peripherals' own
    /// interrupts (UART, timers) stay at 0, above both: they only move bytes
    /// and wake tasks. The values differ in the top bit pair, which every
    /// Cortex-M4 implements (STM32F4: 4 bits, QEMU: 3 bits).
    fn priority(self) -> u8 {
        match self {
            Level::Control => 0x40,
            Level::Link => 0x80,
        }
    }

    fn line(self) -> u16 {
        match self {
            Level::Control => crate::board::active::CONTROL_IRQ,
            Level::Link => crate::board::active::LINK_IRQ,
        }
    }
}

static mut CONTROL_EXECUTOR: Option<raw::Executor> = None;
static mut LINK_EXECUTOR: Option<raw::Executor> = None;
static CONTROL_STARTED: AtomicBool = AtomicBool::new(false);
static LINK_STARTED: AtomicBool = AtomicBool::new(false);

/// Starts the interrupt executor of `level` and returns its spawner. Call once
/// per level from `main`, before the thread executor runs.
pub fn start_interrupt_executor(level: Level) -> Option<SendSpawner> {
    let started = match level {
        Level::Control => &CONTROL_STARTED,
        Level::Link => &LINK_STARTED,
    };
    if started.swap(true, Ordering::AcqRel) {
        return None;
    }
    let line = level.line();
    let context = (usize::from(line) + 1) as *mut ();
    // SAFETY: guarded by `started`, this is the only time the slot is written;
    // the interrupt that polls it is unmasked only afterwards.
    let executor: &'static raw::Executor = unsafe {
        let slot = match level {
            Level::Control => &mut *core::ptr::addr_of_mut!(CONTROL_EXECUTOR),
            Level::Link => &mut *core::ptr::addr_of_mut!(LINK_EXECUTOR),
        };
        slot.insert(raw::Executor::new(context))
    };
    // SAFETY: setting a priority and unmasking a spare line whose handler only
    // polls this executor (see `on_interrupt`).
    unsafe {
        let mut peripherals = cortex_m::Peripherals::steal();
        peripherals.NVIC.set_priority(Line(line), level.priority());
        NVIC::unmask(Line(line));
    }
    Some(executor.spawner().make_send())
}

/// Polls the interrupt executor of `level`: the board calls this from the
/// handler of that level's NVIC line, and from nowhere else.
pub fn on_interrupt(level: Level) {
    let started = match level {
        Level::Control => &CONTROL_STARTED,
        Level::Link => &LINK_STARTED,
    };
    if !started.load(Ordering::Acquire) {
        return;
    }
    // SAFETY: the slot was written before `started` was set and is only read
    // from here on; `poll` is not reentrant because an interrupt handler does
    // not preempt itself.
    unsafe {
        let slot = match level {
            Level::Control => &*core::ptr::addr_of!(CONTROL_EXECUTOR),
            Level::Link => &*core::ptr::addr_of!(LINK_EXECUTOR),
        };
        if let Some(executor) = slot.as_ref() {
            executor.poll();
        }
    }
}

/// Runs the thread-mode executor forever: `init` spawns its tasks, then
/// poll / sleep.
pub fn run(init: impl FnOnce(Spawner)) -> ! {
    static mut EXECUTOR: Option<raw::Executor> = None;
    // SAFETY: `run` is called once from `main`, and never returns, so this is
    // the only access that creates the executor; afterwards it is only read
    // through the shared `&'static` reference below.
    let executor: &'static raw::Executor = unsafe {
        let slot = &mut *core::ptr::addr_of_mut!(EXECUTOR);
        slot.insert(raw::Executor::new(THREAD_CONTEXT as *mut ()))
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
