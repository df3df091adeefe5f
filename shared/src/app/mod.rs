//! The controller application: board-independent logic shared by the firmware and
//! the in-process simulator link, so both run the same code.

mod link;

pub use link::LinkResponder;
