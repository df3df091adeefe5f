//! Shared, `no_std`, heap-free core of the self-calibrating workcell.
//!
//! The same code runs in the firmware (Cortex-M4F) and in the host simulator.
//! Frames, units and the observation contract follow
//! `docs/reference/frames-and-log.md`; equation numbers refer to Ghosh, Xiao,
//! Xi and Tarn, "Multisensor-based robotic manipulation in an uncalibrated
//! manufacturing workcell".
//!
//! Layout, one concept per module:
//! - [`observation`]: the observation log's records and the calibration result (the spec's contract).
//! - [`protocol`]: serial protocol v1 (postcard messages, CRC-checked, COBS-framed).
//! - [`calibration`]: virtual rotation, part localisation, robot-to-disc self-calibration (Sections 2 and 3).
//! - [`robot`]: PUMA 560 kinematics and dynamics (Section 4, Eq 16).
//! - [`control`]: task-space computed-torque control (Eq 23).
//! - [`kernels`]: straight-line small-vector kernels of the control period (the firmware is built for size).
//! - [`safety`]: the drive interlock and the drives' wiring signs (drives that fail safe).
//! - [`app`]: the controller application that the firmware and the in-process simulator both run.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing
    )
)]

pub mod angle;
pub mod app;
pub mod calibration;
pub mod control;
pub mod fusion;
pub mod kernels;
pub mod observation;
pub mod planning;
pub mod protocol;
pub mod robot;
pub mod safety;

#[cfg(test)]
mod test_cell;
#[cfg(test)]
mod test_rng;

#[cfg(test)]
mod tests {
    /// Every error type of the crate is a `core::error::Error` whose message
    /// says what went wrong.
    #[test]
    fn errors_are_errors() {
        fn message<E: core::error::Error>(error: E) -> String {
            error.to_string()
        }
        let messages = [
            message(crate::planning::PlanError::InvalidDuration),
            message(crate::robot::RobotError::MassMatrixNotPositiveDefinite),
            message(crate::fusion::FusionError::ZeroCountsPerRevolution),
            message(crate::control::ControlError::NonPositivePeriod),
            message(crate::calibration::CalibrationError::CameraBelowDisc),
            message(crate::app::vision::VisionError::UnknownTrigger { trigger_id: 7 }),
            message(crate::app::joint_observer::JointObserverError::NonFinite),
            message(crate::app::pick::cell::ConfigError { field: "f_px" }),
            message(crate::protocol::EncodeError::OutputTooSmall),
            message(crate::protocol::DecodeError::Corrupt),
        ];
        assert!(messages.iter().all(|m| !m.is_empty()));
    }
}
