//! Helpers for the integration tests in `tests/tests/`.
//!
//! - [`link`]: host-sim's controller links (in process, TCP to the emulator,
//!   serial) and link check, the same code `host-sim link-check` runs.
//! - [`qemu`]: boots the emulated-board firmware in qemu-system-arm and shuts
//!   it down again.

pub use host_sim::link;
pub mod qemu;
