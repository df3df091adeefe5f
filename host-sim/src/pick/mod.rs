//! The full pick in the simulated workcell: the world ([`crate::world`])
//! against the controller application over the serial protocol.
//!
//! - [`runner`]: one pick in lock step over any link.
//! - [`record`]: what a pick leaves behind; [`report`], [`plots`]: tables, CSV and PNG.
//! - [`montecarlo`]: many seeded picks over random workcells and their statistics.
//! - [`faults`]: the pick under injected faults and its safety invariants.

pub mod faults;
pub mod montecarlo;
pub mod plots;
pub mod record;
pub mod report;
pub mod runner;
