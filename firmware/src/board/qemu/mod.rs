//! The emulated board: ARM MPS2 AN386 (Cortex-M4F) under `qemu-system-arm
//! -machine mps2-an386`. UART0 carries the host link (QEMU connects it to a TCP
//! socket), the CMSDK dual timer drives embassy-time, defmt goes out over
//! semihosting. There are no motors: the simulator is the plant, in lock step
//! through the protocol (sensor samples in, actuator commands out), or, with
//! the `free-run` feature, running free on the host's clock while the control
//! loop runs on its own ticker ([`free_run`]). TIMER0 counts instructions
//! under `-icount` (nanoseconds of the host's clock without it); NVIC lines 28 and 29 run the interrupt
//! executors. The board's watchdog is a no-op ([`NoWatchdog`]).
//!
//! Drives that fail safe, here: there is no amplifier enable line, the
//! simulator's drives are driven by the actuator commands. So an unexpected
//! interrupt latches a board fault ([`crate::board::fail_safe`]) and the
//! control loop's interlock sends zero torques from the next period until
//! the host acknowledges; a panic or a HardFault ends QEMU (the simulator
//! then gets no command, and its drives' watchdog brakes the arm).

#[cfg(feature = "free-run")]
pub mod free_run;
mod mmio;
mod sim_io;
pub mod time_driver;
mod uart;

use defmt_semihosting as _;

#[cfg(not(feature = "free-run"))]
use super::lock_step::{LockStepPlant, Unwired};
#[cfg(feature = "free-run")]
pub use free_run::FreeRunPlant;
pub use sim_io::{count_now, InstructionCounter};
pub use uart::Uart0;

use super::{fail_safe, interrupt_time, Board, ControlSource, NoWatchdog};
use crate::executor::{on_interrupt, Level};

pub type Serial = Uart0;
#[cfg(not(feature = "free-run"))]
pub type Plant = LockStepPlant<Unwired>;
#[cfg(feature = "free-run")]
pub type Plant = FreeRunPlant;
pub type Cycles = InstructionCounter;
pub type Watchdog = NoWatchdog;

/// Name reported in `HelloAck`.
#[cfg(not(feature = "free-run"))]
pub const BOARD_NAME: &str = "mps2-an386";
/// Name reported in `HelloAck`: the host's plant must run free for it.
#[cfg(feature = "free-run")]
pub const BOARD_NAME: &str = "mps2-an386-free-run";

/// The clock a control period's budget is counted against: the emulator has
/// none of its own, so the STM32F407's 168 MHz (with one instruction per cycle,
/// the M4's best case; the report gives the instructions themselves).
#[cfg(not(feature = "free-run"))]
pub const CPU_HZ: u32 = 168_000_000;
/// Running free (no `-icount`), TIMER0 counts QEMU's virtual clock, which
/// follows the host's: its units (`InstructionCounter::scale` = 40 per count
/// at 25 MHz) are nanoseconds, so the budget `CPU_HZ / rate` is the whole
/// period in wall-clock time, what the host's free-running plant allows.
#[cfg(feature = "free-run")]
pub const CPU_HZ: u32 = 1_000_000_000;

/// Where control periods come from: the simulator's samples in lock step, or
/// the board's own ticker when running free.
const CONTROL_SOURCE: ControlSource = if cfg!(feature = "free-run") {
    ControlSource::Ticker
} else {
    ControlSource::LockStep
};

/// Spare NVIC lines (no device of the AN386 that QEMU models drives them)
/// for the interrupt executors.
pub const CONTROL_IRQ: u16 = 28;
pub const LINK_IRQ: u16 = 29;

/// Brings up the timebase and UART0. Call once, first thing in `main`.
pub fn init() -> Result<Board<Serial, Plant, Cycles, Watchdog>, InitError> {
    time_driver::init();
    Ok(Board {
        name: BOARD_NAME,
        serial: Uart0::init(),
        #[cfg(not(feature = "free-run"))]
        plant: LockStepPlant::holding(Unwired),
        #[cfg(feature = "free-run")]
        plant: FreeRunPlant::take(),
        cycles: InstructionCounter::start(),
        watchdog: NoWatchdog::take(),
        control_source: CONTROL_SOURCE,
    })
}

/// Bringing up the emulated board cannot fail.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum InitError {}

/// Without cortex-m-rt's `device` feature every external interrupt lands here;
/// `irqn` is the NVIC line (negative for system exceptions).
#[cortex_m_rt::exception]
unsafe fn DefaultHandler(irqn: i16) {
    interrupt_time::enter();
    match irqn {
        0 => uart::on_rx_interrupt(),
        1 => uart::on_tx_interrupt(),
        10 => time_driver::on_interrupt(),
        28 => on_interrupt(Level::Control),
        29 => on_interrupt(Level::Link),
        _ => {
            // Drives off first: from the next period on the interlock sends
            // zero torques, until the host acknowledges.
            fail_safe::latch(shared::safety::BoardFault::UnexpectedInterrupt);
            defmt::error!("unexpected interrupt {}; drives off", irqn);
        }
    }
    interrupt_time::leave();
}

#[cortex_m_rt::exception]
unsafe fn HardFault(frame: &cortex_m_rt::ExceptionFrame) -> ! {
    defmt::error!("hard fault at pc={=u32:#x}", frame.pc());
    cortex_m_semihosting::debug::exit(cortex_m_semihosting::debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    // The location only: formatting the message would link core::fmt's
    // float printing (about 10 KB of flash) for panic sites that the
    // panic-free code never reaches.
    match info.location() {
        Some(at) => defmt::error!("panic at {=str}:{=u32}", at.file(), at.line()),
        None => defmt::error!("panic"),
    }
    // Ends QEMU with a failing exit status so tests and scripts see it.
    cortex_m_semihosting::debug::exit(cortex_m_semihosting::debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
