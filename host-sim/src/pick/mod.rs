//! The full pick in the simulated workcell: the world (plant, conveyor, camera,
//! gripper) against the controller application over the serial protocol.
//!
//! - [`scenario`]: the scenario file (TOML) and its embedded default.
//! - [`world`], [`camera_sim`]: the simulated workcell.
//! - [`runner`]: one pick in lock step over any link; [`free_run`]: one pick
//!   with the plant running free on the host's clock (the emulated board
//!   built with `free-run`).
//! - [`record`]: what a pick leaves behind; [`report`], [`plots`]: tables, CSV and PNG.
//! - [`command`]: `host-sim run`; [`montecarlo`]: `host-sim montecarlo`;
//!   [`faults`]: `host-sim faults` (the pick under injected faults).

pub mod camera_sim;
pub mod command;
pub mod faults;
pub mod free_run;
pub mod montecarlo;
pub mod plots;
pub mod record;
pub mod report;
pub mod runner;
pub mod scenario;
pub mod world;
