//! The emulated board: ARM MPS2 AN386 (Cortex-M4F) under `qemu-system-arm
//! -machine mps2-an386`. UART0 carries the host link (QEMU connects it to a TCP
//! socket), the CMSDK dual timer drives embassy-time, defmt goes out over
//! semihosting. There are no motors: encoders and servo outputs are fed and
//! read by the simulator through the protocol.

mod mmio;
mod sim_io;
pub mod time_driver;
mod uart;

use defmt_semihosting as _;

#[allow(unused_imports, reason = "read back by the control issue's plant link")]
pub use sim_io::last_servo_duties;
pub use sim_io::{SimulatedEncoders, SimulatedServos};
pub use uart::Uart0;

use super::Board;

pub type Serial = Uart0;
pub type Encoders = SimulatedEncoders;
pub type Servos = SimulatedServos;

/// Name reported in `HelloAck`.
pub const BOARD_NAME: &str = "mps2-an386";

/// Brings up the timebase and UART0. Call once, first thing in `main`.
pub fn init() -> Result<Board<Serial, Encoders, Servos>, InitError> {
    time_driver::init();
    Ok(Board {
        name: BOARD_NAME,
        serial: Uart0::init(),
        encoders: SimulatedEncoders::take(),
        servos: SimulatedServos::take(),
    })
}

/// Bringing up the emulated board cannot fail.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum InitError {}

/// A host-side plant sent its joint encoder counts: on the emulated board they
/// are what the encoders read.
pub fn on_host_sensor_sample(joint_counts: &super::JointCounts) {
    sim_io::feed_encoder_counts(*joint_counts);
}

/// Without cortex-m-rt's `device` feature every external interrupt lands here;
/// `irqn` is the NVIC line (negative for system exceptions).
#[cortex_m_rt::exception]
unsafe fn DefaultHandler(irqn: i16) {
    match irqn {
        0 => uart::on_rx_interrupt(),
        1 => uart::on_tx_interrupt(),
        10 => time_driver::on_interrupt(),
        _ => {
            defmt::error!("unexpected interrupt {}", irqn);
        }
    }
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
    defmt::error!("panic: {}", defmt::Display2Format(info));
    // Ends QEMU with a failing exit status so tests and scripts see it.
    cortex_m_semihosting::debug::exit(cortex_m_semihosting::debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
