//! The board seam: everything the application needs from the hardware, behind
//! small traits, with one implementation per board selected by a cargo
//! feature. The application (`crate::app`) only sees [`Board`] and these
//! traits, so it is the same code on both boards.
//!
//! - serial link to the vision computer / simulator: [`SerialLink`]
//!   (`embedded-io-async` `Read + Write`);
//! - joint encoders: [`JointEncoders`]; servo outputs: [`ServoOutputs`];
//! - clock: the board's `embassy_time_driver::Driver` (the QEMU board's own
//!   driver on the CMSDK dual timer; embassy-stm32's TIM12 driver on the
//!   STM32F407), used through `embassy_time` by the application.

use core::fmt;

#[cfg(all(feature = "board-qemu", feature = "board-stm32f407"))]
compile_error!(
    "select exactly one board: `--no-default-features --features board-qemu` or the default `board-stm32f407`"
);
#[cfg(not(any(feature = "board-qemu", feature = "board-stm32f407")))]
compile_error!("select a board feature: board-qemu or board-stm32f407");

#[cfg(feature = "board-qemu")]
pub mod qemu;
#[cfg(feature = "board-qemu")]
pub use qemu as active;

#[cfg(all(feature = "board-stm32f407", not(feature = "board-qemu")))]
pub mod stm32f407;
#[cfg(all(feature = "board-stm32f407", not(feature = "board-qemu")))]
pub use stm32f407 as active;

/// Joints of the PUMA 560.
pub const JOINTS: usize = 6;

/// Encoder counts per joint, joint 1 first.
pub type JointCounts = [i32; JOINTS];

/// Servo drive per joint as a signed duty fraction in `[-1, 1]`, joint 1 first.
#[allow(
    dead_code,
    reason = "the servo path is driven by the control issue (Eq 23 torques to duties)"
)]
pub type JointDuties = [f32; JOINTS];

/// What went wrong at the board level.
#[allow(
    dead_code,
    reason = "the servo path is driven by the control issue (Eq 23 torques to duties)"
)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BoardError {
    /// The device's peripherals are reserved but not driven yet on this board.
    NotWired {
        device: &'static str,
        peripherals: &'static str,
    },
    /// A joint's unwrapped encoder count left the protocol's `i32` range.
    EncoderOutOfRange { joint: usize },
    /// A servo duty was NaN or infinite.
    NonFiniteDuty { joint: usize },
    /// A servo duty was outside `[-1, 1]`.
    DutyOutOfRange { joint: usize, duty: f32 },
}

impl fmt::Display for BoardError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BoardError::NotWired {
                device,
                peripherals,
            } => write!(
                f,
                "{device}: peripherals {peripherals} are reserved but not wired on this board yet"
            ),
            BoardError::EncoderOutOfRange { joint } => write!(
                f,
                "encoder count of joint {} is outside the i32 range",
                joint + 1
            ),
            BoardError::NonFiniteDuty { joint } => {
                write!(f, "servo duty for joint {} is not finite", joint + 1)
            }
            BoardError::DutyOutOfRange { joint, duty } => write!(
                f,
                "servo duty {duty} for joint {} is outside [-1, 1]",
                joint + 1
            ),
        }
    }
}

impl defmt::Format for BoardError {
    fn format(&self, f: defmt::Formatter<'_>) {
        defmt::write!(f, "{}", defmt::Display2Format(self));
    }
}

/// The byte link to the vision computer / simulator.
pub trait SerialLink: embedded_io_async::Read + embedded_io_async::Write {}

impl<T: embedded_io_async::Read + embedded_io_async::Write> SerialLink for T {}

/// Incremental joint encoders.
pub trait JointEncoders {
    /// Latest count of every joint's encoder.
    fn read_counts(&mut self) -> Result<JointCounts, BoardError>;
}

/// Servo amplifier command outputs.
pub trait ServoOutputs {
    /// Drives every joint with `duties`; rejects the whole set (changing
    /// nothing) if any duty is non-finite or outside `[-1, 1]`.
    #[allow(
        dead_code,
        reason = "the servo path is driven by the control issue (Eq 23 torques to duties)"
    )]
    fn set_duties(&mut self, duties: JointDuties) -> Result<(), BoardError>;

    /// Stops driving all joints (zero duty).
    fn disable(&mut self);
}

/// Checks a duty set before any output is touched.
#[allow(
    dead_code,
    reason = "the servo path is driven by the control issue (Eq 23 torques to duties)"
)]
pub fn validate_duties(duties: &JointDuties) -> Result<(), BoardError> {
    for (joint, &duty) in duties.iter().enumerate() {
        if !duty.is_finite() {
            return Err(BoardError::NonFiniteDuty { joint });
        }
        if !(-1.0..=1.0).contains(&duty) {
            return Err(BoardError::DutyOutOfRange { joint, duty });
        }
    }
    Ok(())
}

/// The board's devices, handed to the application once at boot.
pub struct Board<S: SerialLink, E: JointEncoders, O: ServoOutputs> {
    /// Reported to the host in `HelloAck`.
    pub name: &'static str,
    pub serial: S,
    pub encoders: E,
    pub servos: O,
}

/// The selected board's concrete devices.
pub type ActiveBoard = Board<active::Serial, active::Encoders, active::Servos>;
