//! The real board: STM32F407VG (e.g. STM32F4-Discovery) on embassy-stm32.
//!
//! Peripheral plan (one owner each, taken here so nothing else can use them):
//! - host link: USART2, TX on PA2, RX on PA3, 115 200 baud, interrupt-driven
//!   with ring buffers (`BufferedUart`);
//! - clock: embassy-stm32's time driver on TIM12 (cargo feature
//!   `time-driver-tim12`), so the timers below stay free;
//! - joint encoders (quadrature): TIM1, TIM8, TIM2, TIM5, TIM3, TIM4 for
//!   joints 1 to 6, pins in [`encoders`];
//! - servo PWM: TIM9 CH1/CH2 (joints 1, 2), TIM10 CH1, TIM11 CH1, TIM13 CH1,
//!   TIM14 CH1 (joints 3 to 6).
//!
//! The PWM timers are reserved now; the issue that brings up the amplifiers
//! (PWM pins, direction outputs, enable) wires them. Until then
//! `ServoOutputs` answers `BoardError::NotWired` instead of pretending.
//!
//! The core runs from the 16 MHz HSI (embassy-stm32's default configuration),
//! so the firmware does not assume a particular crystal.

mod encoders;

use defmt_rtt as _;
use embassy_stm32::peripherals::{TIM10, TIM11, TIM13, TIM14, TIM9, USART2};
use embassy_stm32::timer::qei::Qei;
use embassy_stm32::usart::{BufferedInterruptHandler, BufferedUart, Config as UartConfig};
use embassy_stm32::{bind_interrupts, Peri};
use panic_probe as _;

pub use encoders::QuadratureEncoders;
use encoders::{qei_config, EncoderPeripherals};

use super::{validate_duties, Board, BoardError, JointCounts, JointDuties, ServoOutputs};

bind_interrupts!(struct Irqs {
    USART2 => BufferedInterruptHandler<USART2>;
});

pub type Serial = BufferedUart<'static>;
pub type Encoders = QuadratureEncoders;
pub type Servos = PwmServos;

/// Name reported in `HelloAck`.
pub const BOARD_NAME: &str = "stm32f407";

const LINK_BAUD: u32 = 115_200;
const UART_BUFFER_LEN: usize = 512;

/// The PWM timers, reserved for the servo amplifier inputs.
pub struct PwmServos {
    /// CH1 joint 1, CH2 joint 2.
    _joints12: Peri<'static, TIM9>,
    _joint3: Peri<'static, TIM10>,
    _joint4: Peri<'static, TIM11>,
    _joint5: Peri<'static, TIM13>,
    _joint6: Peri<'static, TIM14>,
}

impl ServoOutputs for PwmServos {
    fn set_duties(&mut self, duties: JointDuties) -> Result<(), BoardError> {
        validate_duties(&duties)?;
        Err(BoardError::NotWired {
            device: "servo PWM",
            peripherals: "TIM9 TIM10 TIM11 TIM13 TIM14",
        })
    }

    fn disable(&mut self) {
        // Nothing is driven until the PWM pins are wired: already disabled.
    }
}

/// A host-side plant sent joint encoder counts. The real board reads its own
/// encoders, so a host's counts are only telemetry here and do not overwrite them.
pub fn on_host_sensor_sample(_joint_counts: &JointCounts) {}

/// Errors bringing the board up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum InitError {
    /// `BufferedUart::new` rejected the link configuration.
    UartConfig,
}

/// Brings up clocks, the time driver and USART2. Call once, first in `main`.
pub fn init() -> Result<Board<Serial, Encoders, Servos>, InitError> {
    let p = embassy_stm32::init(embassy_stm32::Config::default());

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

    Ok(Board {
        name: BOARD_NAME,
        serial,
        encoders: QuadratureEncoders::new(EncoderPeripherals {
            joint1: Qei::new(p.TIM1, p.PE9, p.PE11, qei_config()),
            joint2: Qei::new(p.TIM8, p.PC6, p.PC7, qei_config()),
            joint3: Qei::new(p.TIM2, p.PA15, p.PB3, qei_config()),
            joint4: Qei::new(p.TIM5, p.PA0, p.PA1, qei_config()),
            joint5: Qei::new(p.TIM3, p.PB4, p.PB5, qei_config()),
            joint6: Qei::new(p.TIM4, p.PB6, p.PB7, qei_config()),
        }),
        servos: PwmServos {
            _joints12: p.TIM9,
            _joint3: p.TIM10,
            _joint4: p.TIM11,
            _joint5: p.TIM13,
            _joint6: p.TIM14,
        },
    })
}
