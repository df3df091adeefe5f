//! The controller application: board-independent logic shared by the firmware and
//! the in-process simulator link, so both run the same code.
//!
//! - [`ControllerApp`]: the session plus the pick, behind one message handler.
//! - [`link`]: the protocol session (handshake, acknowledgements, status).
//! - [`tool`]: the gripper's geometry (grasp point, the two marks the camera sees).
//! - [`joint_observer`]: joint angles and speeds from quantised encoders.
//! - [`homing`]: joint angles from incremental counters at power-on (potentiometers and index pulses).
//! - [`power_on_homing`]: the homing sequence before the pick (the arm held and moved in joint space).
//! - [`pick`]: the pick's state machine, fusion at control rate and background jobs.
//! - [`vision`]: camera frames paired with their trigger's encoder values, as observations.

mod controller;
pub mod homing;
pub mod joint_observer;
pub mod joint_speed;
mod link;
pub mod pick;
pub mod power_on_homing;
pub mod tool;
pub mod vision;

pub use controller::{
    configure, new_calibration_report, new_report, refusal_message, ConfigRefused, ControllerApp,
    MAX_REPLIES,
};
pub use link::LinkResponder;
