//! The controller application: board-independent logic shared by the firmware and
//! the in-process simulator link, so both run the same code.
//!
//! - [`link`]: the protocol session (handshake, acknowledgements, status).
//! - [`tool`]: the gripper's geometry (grasp point, the two marks the camera sees).
//! - [`joint_observer`]: joint angles and speeds from quantised encoders.
//! - [`vision`]: camera frames paired with their trigger's encoder values, as observations.

pub mod joint_observer;
mod link;
pub mod tool;
pub mod vision;

pub use link::LinkResponder;
