//! The full pick in the simulated workcell: the world ([`crate::world`])
//! against the controller application over the serial protocol.
//!
//! - [`runner`]: one pick in lock step over any link; [`free_run`]: one pick
//!   with the plant running free on the host's clock (the emulated board
//!   built with `free-run`).
//! - [`record`]: what a pick leaves behind.
//! - [`report`]: the results table and the terminal's lines; [`csv`]: the CSV
//!   files; [`plots`]: the PNG figures; [`outputs`]: all of a run's files in
//!   its folder; [`synthetic`]: a made-up run for tests and benchmarks.
//! - [`own_log`]: the observation log the controller's calibrator was fed,
//!   with the truth and the controller's final estimate beside it.
//! - [`montecarlo`]: many seeded picks over random workcells and their statistics.
//! - [`faults`]: the pick under injected faults and its safety invariants.
//! - [`watch`]: onlookers of a run (logs, recordings, viewers): the world and
//!   what crossed the link, each period.

pub mod csv;
pub mod faults;
pub mod free_run;
pub mod invariants;
pub mod ml_limit;
pub mod montecarlo;
pub mod outputs;
pub mod own_log;
pub mod plots;
pub mod record;
pub mod report;
pub mod runner;
pub mod synthetic;
pub mod watch;
