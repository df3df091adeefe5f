//! The full pick in the simulated workcell: the world ([`crate::world`])
//! against the controller application over the serial protocol.
//!
//! - [`runner`]: one pick in lock step over any link.
//! - [`record`]: what a pick leaves behind; [`report`], [`plots`]: tables, CSV and PNG.
//! - [`command`]: `host-sim run`; [`montecarlo`]: `host-sim montecarlo`;
//!   [`faults`]: `host-sim faults` (the pick under injected faults).

pub mod command;
pub mod faults;
pub mod montecarlo;
pub mod plots;
pub mod record;
pub mod report;
pub mod runner;
