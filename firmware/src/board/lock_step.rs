//! The plant of a board in lock step: the simulator's, behind the link. Every
//! `SensorSample` frame from the host is one control period and is answered
//! with an `ActuatorCommand` frame ([`crate::board::ControlSource::LockStep`]),
//! so the board's own encoders, amplifiers and gripper take no part: reading
//! them or driving them is refused, and whatever the board has of its own
//! (the STM32F407's servo amplifiers and brakes) is held safe for the whole
//! run: amplifiers disabled, brakes engaged. The emulated board has nothing
//! of its own ([`Unwired`]); the STM32F407 built with `lock-step` holds its
//! real plant I/O here, so a real board can be driven from the simulated
//! plant over its serial port (hardware in the loop) with no arm moving.

use crate::board::{validate_torques, BoardError, PlantIo, PlantReading, JOINTS};

/// The simulator's plant, reached through the link; `held` is the board's
/// own plant I/O, kept with its drives off and brakes on.
pub struct LockStepPlant<P: PlantIo> {
    held: P,
}

impl<P: PlantIo> LockStepPlant<P> {
    /// Takes the board's own plant I/O and makes it safe: drives off,
    /// brakes engaged.
    pub fn holding(mut held: P) -> Self {
        held.disable();
        held.set_brakes(true);
        Self { held }
    }
}

impl<P: PlantIo> PlantIo for LockStepPlant<P> {
    fn reading_time_us(&mut self, _now_us: u64) -> Result<u64, BoardError> {
        Err(BoardError::NotOnThisBoard { device: "encoders" })
    }

    fn read_sample(&mut self, _camera_trigger: bool) -> Result<PlantReading, BoardError> {
        Err(BoardError::NotOnThisBoard { device: "encoders" })
    }

    fn apply(
        &mut self,
        torque_nm: &[f32; JOINTS],
        _gripper_closed: bool,
    ) -> Result<(), BoardError> {
        validate_torques(torque_nm)?;
        Err(BoardError::NotOnThisBoard {
            device: "servo amplifiers",
        })
    }

    /// The board's own drives are off already; kept so.
    fn disable(&mut self) {
        self.held.disable();
    }

    /// The simulator's arm has no brake output of ours (its drives' own
    /// watchdog brakes it); the board's own brakes stay engaged whatever is
    /// asked.
    fn set_brakes(&mut self, _engaged: bool) {
        self.held.set_brakes(true);
    }
}

/// A board with no plant I/O of its own (the emulated one).
#[cfg(feature = "board-qemu")]
pub struct Unwired;

#[cfg(feature = "board-qemu")]
impl PlantIo for Unwired {
    fn reading_time_us(&mut self, _now_us: u64) -> Result<u64, BoardError> {
        Err(BoardError::NotOnThisBoard { device: "encoders" })
    }

    fn read_sample(&mut self, _camera_trigger: bool) -> Result<PlantReading, BoardError> {
        Err(BoardError::NotOnThisBoard { device: "encoders" })
    }

    fn apply(
        &mut self,
        _torque_nm: &[f32; JOINTS],
        _gripper_closed: bool,
    ) -> Result<(), BoardError> {
        Err(BoardError::NotOnThisBoard {
            device: "servo amplifiers",
        })
    }

    fn disable(&mut self) {}

    fn set_brakes(&mut self, _engaged: bool) {}
}
