//! Shared, `no_std`, heap-free core of the self-calibrating workcell.
//!
//! The same code runs in the firmware (Cortex-M4F) and in the host simulator.
//! Frames, units and the observation contract follow
//! `docs/reference/frames-and-log.md`; equation numbers refer to Ghosh, Xiao,
//! Xi and Tarn, "Multisensor-based robotic manipulation in an uncalibrated
//! manufacturing workcell", summarised in `docs/reference/paper.md`.
//!
//! One concept a module:
//! - [`observation`]: the observation log's records and the calibration result (the contract).
//! - [`angle`]: angles wrapped to (-pi, pi], the one helper for every yaw.
//! - [`calibration`]: virtual rotation, part localisation, robot-to-disc self-calibration (Sections 2 and 3).
//! - [`fusion`]: the conveyor encoder's angle, speed and acceleration, and Eq 1 at control rate.
//! - [`robot`]: PUMA 560 kinematics and dynamics (Section 4, Eq 16).
//! - [`planning`]: the pick's paths (arcs, quintics, the intercept of the moving part) within the joints' limits.
//! - [`control`]: task-space computed-torque control (Eq 23).
//! - [`detection`]: bright round marks in a grayscale image, sub-pixel, in fixed memory (the vision front end).
//! - [`kernels`]: straight-line small-vector kernels of the control period.
//! - [`protocol`]: serial protocol v3 (postcard messages, CRC-checked, COBS-framed).
//! - [`safety`]: the drive interlock, parking, reconfiguration and the drives' wiring signs (drives that fail safe).
//! - [`app`]: the controller application (the session and the pick) that the firmware and the in-process simulator both run.
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
pub mod detection;
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
            message(crate::app::pick::cell::ConfigError::new(
                "f_px",
                "is out of range",
            )),
            message(crate::protocol::EncodeError::OutputTooSmall),
            message(crate::protocol::DecodeError::Corrupt),
        ];
        assert!(messages.iter().all(|m| !m.is_empty()));
    }
}
