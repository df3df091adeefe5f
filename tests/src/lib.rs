//! Helpers for the integration tests in `tests/tests/`.
//!
//! - [`link`]: host-sim's controller links (in process, TCP to the emulator,
//!   serial) and link check, the same code `host-sim link-check` runs.
//! - [`qemu`]: boots the emulated-board firmware in qemu-system-arm, connects
//!   to its UART and shuts it down again.

pub use host_sim::link;
pub mod qemu;

/// When a pick started its controlled stop (NaN if it never did).
pub fn stopping_at(run: &host_sim::pick::record::PickRun) -> f64 {
    run.phases
        .iter()
        .find(|p| p.phase == shared::protocol::PickPhase::Stopping)
        .map_or(f64::NAN, |p| p.t_s)
}
