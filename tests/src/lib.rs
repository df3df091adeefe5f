//! Helpers for the integration tests in `tests/tests/`.
//!
//! - [`link`]: host-sim's controller links (in process, TCP to the emulator,
//!   serial) and link check, compiled from host-sim's own source so the tests
//!   exercise exactly what `host-sim link-check` runs.
//! - [`qemu`]: boots the emulated-board firmware in qemu-system-arm and shuts
//!   it down again.

#[path = "../../host-sim/src/link/mod.rs"]
#[allow(dead_code)]
pub mod link;
pub mod qemu;
