//! The controller application: board-independent logic shared by the firmware and
//! the in-process simulator link, so both run the same code.
//!
//! - [`link`]: the protocol session (handshake, acknowledgements, status).
//! - [`tool`]: the gripper's geometry (grasp point, the two marks the camera sees).

mod link;
pub mod tool;

pub use link::LinkResponder;
