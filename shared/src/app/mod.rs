//! The controller application: board-independent logic shared by the firmware and
//! the in-process simulator link.
