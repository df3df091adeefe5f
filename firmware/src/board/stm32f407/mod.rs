//! The real board: STM32F407VG (e.g. STM32F4-Discovery) on embassy-stm32.
//!
//! Peripheral plan (one owner each, taken here so nothing else can use them;
//! the full pin map is in `firmware/README.md`):
//! - clock: 168 MHz from the HSI through the PLL, no crystal needed
//!   ([`clock`]);
//! - host link: USART2, TX on PA2, RX on PA3, 115 200 baud, interrupt-driven
//!   with ring buffers (`BufferedUart`);
//! - time: embassy-stm32's time driver on TIM12 (cargo feature
//!   `time-driver-tim12`), so the timers below stay free;
//! - joint encoders: TIM1, TIM8, TIM2, TIM5, TIM3, TIM4 in quadrature mode
//!   ([`encoders`]);
//! - conveyor encoder: PD2/PD3 on EXTI2/EXTI3, x4-decoded in software
//!   ([`conveyor`], [`quadrature`]);
//! - servo amplifiers: sign-magnitude PWM at 20 kHz on TIM9 CH1/CH2, TIM10,
//!   TIM11, TIM13, TIM14 CH1, direction lines PE7/8/10/12/13/14, enable PE15
//!   ([`servo`], [`sign_magnitude`]);
//! - gripper PD0, camera trigger PD1, part-present switch PD4 ([`plant`]);
//! - cycle counter: the DWT's CYCCNT ([`cycles`]);
//! - the independent watchdog (IWDG), armed by the control loop's first
//!   period, 32 ms nominal ([`watchdog`]); `init` logs a reset it caused.
//!
//! The plant runs from the board's own ticker ([`ControlSource::Ticker`]).

mod clock;
mod conveyor;
mod cycles;
mod encoders;
mod plant;
mod quadrature;
mod servo;
mod sign_magnitude;
mod watchdog;

use defmt_rtt as _;
use embassy_stm32::gpio::{Input, Level, Output, Pull, Speed};
use embassy_stm32::peripherals::USART2;
use embassy_stm32::timer::qei::Qei;
use embassy_stm32::usart::{BufferedInterruptHandler, BufferedUart, Config as UartConfig};
use embassy_stm32::{bind_interrupts, interrupt};

pub use cycles::DwtCycles;
pub use encoders::QuadratureEncoders;
use encoders::{qei_config, EncoderPeripherals};
use plant::PlantDevices;
pub use plant::Stm32Plant;
use servo::{ServoAmplifiers, ServoPeripherals};
pub use watchdog::IndependentWatchdogFeed;

use super::{Board, ControlSource};

bind_interrupts!(struct Irqs {
    USART2 => BufferedInterruptHandler<USART2>;
    EXTI2 => conveyor::EdgeHandler;
    EXTI3 => conveyor::EdgeHandler;
});

pub type Serial = BufferedUart<'static>;
pub type Plant = Stm32Plant;
pub type Cycles = DwtCycles;
pub type Watchdog = IndependentWatchdogFeed;

/// Name reported in `HelloAck`.
pub const BOARD_NAME: &str = "stm32f407";

/// The core clock ([`clock`]): a control period's budget in cycles is
/// `CPU_HZ / rate`.
pub const CPU_HZ: u32 = 168_000_000;

/// Spare NVIC lines for the interrupt executors: UART4 and UART5, whose
/// peripherals this firmware never enables.
pub const CONTROL_IRQ: u16 = interrupt::UART4 as u16;
pub const LINK_IRQ: u16 = interrupt::UART5 as u16;

/// The control loop's interrupt executor.
#[interrupt]
fn UART4() {
    crate::executor::on_interrupt(crate::executor::Level::Control);
}

/// The link's interrupt executor.
#[interrupt]
fn UART5() {
    crate::executor::on_interrupt(crate::executor::Level::Link);
}

const LINK_BAUD: u32 = 115_200;
const UART_BUFFER_LEN: usize = 512;

/// Errors bringing the board up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum InitError {
    /// `BufferedUart::new` rejected the link configuration.
    UartConfig,
    /// The Cortex-M core peripherals (DWT, DCB) were already taken.
    CorePeripheralsTaken,
    /// The clock tree did not come up at the planned core clock (Hz, 0 if
    /// unknown): the PWM periods and cycle counts would be wrong.
    CoreClock { sys_hz: u32 },
}

impl core::fmt::Display for InitError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            InitError::UartConfig => write!(f, "USART2 rejected the host link configuration"),
            InitError::CorePeripheralsTaken => {
                write!(
                    f,
                    "the Cortex-M core peripherals (DWT, DCB) were already taken"
                )
            }
            InitError::CoreClock { sys_hz } => write!(
                f,
                "core clock is {} Hz, not the planned {} Hz",
                sys_hz,
                clock::SYSCLK_HZ
            ),
        }
    }
}

/// Brings up the clock tree, the time driver, USART2 and the plant I/O with
/// every amplifier disabled, and sets up the IWDG without starting it. Call
/// once, first in `main`.
pub fn init() -> Result<Board<Serial, Plant, Cycles, Watchdog>, InitError> {
    let reset_by_watchdog = watchdog::take_iwdg_reset_flag();
    let p = embassy_stm32::init(clock::config());
    if reset_by_watchdog {
        defmt::warn!(
            "last reset by the independent watchdog: the control loop had stopped, the drives went off"
        );
    }
    let sys_hz = embassy_stm32::rcc::clocks(&p.RCC)
        .sys
        .to_hertz()
        .map_or(0, |hz| hz.0);
    if sys_hz != clock::SYSCLK_HZ {
        return Err(InitError::CoreClock { sys_hz });
    }
    // First of all outputs: the amplifiers stay off until the first `apply`.
    let servos = ServoAmplifiers::new(ServoPeripherals {
        tim9: p.TIM9,
        tim10: p.TIM10,
        tim11: p.TIM11,
        tim13: p.TIM13,
        tim14: p.TIM14,
        pwm1: p.PE5,
        pwm2: p.PE6,
        pwm3: p.PB8,
        pwm4: p.PB9,
        pwm5: p.PA6,
        pwm6: p.PA7,
        dir1: p.PE7,
        dir2: p.PE8,
        dir3: p.PE10,
        dir4: p.PE12,
        dir5: p.PE13,
        dir6: p.PE14,
        enable: p.PE15,
    });

    let core = cortex_m::Peripherals::take().ok_or(InitError::CorePeripheralsTaken)?;
    let cycles = DwtCycles::start(core.DCB, core.DWT);

    static mut TX_BUFFER: [u8; UART_BUFFER_LEN] = [0; UART_BUFFER_LEN];
    static mut RX_BUFFER: [u8; UART_BUFFER_LEN] = [0; UART_BUFFER_LEN];
    // SAFETY: `init` runs once (embassy_stm32::init above would panic on a
    // second call, taking the peripherals twice), so these are the only
    // references ever made to the buffers.
    let (tx_buffer, rx_buffer) = unsafe {
        (
            &mut *core::ptr::addr_of_mut!(TX_BUFFER),
            &mut *core::ptr::addr_of_mut!(RX_BUFFER),
        )
    };
    let mut config = UartConfig::default();
    config.baudrate = LINK_BAUD;
    let serial = BufferedUart::new(p.USART2, p.PA3, p.PA2, tx_buffer, rx_buffer, Irqs, config)
        .map_err(|_| InitError::UartConfig)?;

    let joints = QuadratureEncoders::new(EncoderPeripherals {
        joint1: Qei::new(p.TIM1, p.PE9, p.PE11, qei_config()),
        joint2: Qei::new(p.TIM8, p.PC6, p.PC7, qei_config()),
        joint3: Qei::new(p.TIM2, p.PA15, p.PB3, qei_config()),
        joint4: Qei::new(p.TIM5, p.PA0, p.PA1, qei_config()),
        joint5: Qei::new(p.TIM3, p.PB4, p.PB5, qei_config()),
        joint6: Qei::new(p.TIM4, p.PB6, p.PB7, qei_config()),
    });
    let conveyor = conveyor::ConveyorEncoder::start(p.PD2, p.EXTI2, p.PD3, p.EXTI3);
    let plant = Stm32Plant::new(PlantDevices {
        joints,
        conveyor,
        servos,
        gripper: Output::new(p.PD0, Level::Low, Speed::Low),
        camera_trigger: Output::new(p.PD1, Level::Low, Speed::Low),
        part_present: Input::new(p.PD4, Pull::Down),
    });

    Ok(Board {
        name: BOARD_NAME,
        serial,
        plant,
        cycles,
        watchdog: IndependentWatchdogFeed::new(p.IWDG),
        control_source: ControlSource::Ticker,
    })
}

/// Logs where, then stops the core on an undefined instruction (a probe
/// attached sees the fault; without one the independent watchdog resets the
/// board). The location only, not the message: formatting it would link
/// core::fmt (several KB of flash) for panic sites the panic-free code never
/// reaches.
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    match info.location() {
        Some(at) => defmt::error!("panic at {=str}:{=u32}", at.file(), at.line()),
        None => defmt::error!("panic"),
    }
    cortex_m::asm::udf()
}
