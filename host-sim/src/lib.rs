//! `host-sim` library: everything behind the `host-sim` binary's subcommands.
//!
//! - [`log`]: the observation log (JSON Lines) reader and writer.
//! - [`workcell`]: randomised synthetic workcells, scenarios, recording and truth files.
//! - [`calibrate_cmd`]: calibration of a log (`host-sim calibrate`).
//! - [`accuracy`]: the seeded Monte-Carlo accuracy runs (`host-sim accuracy`).
//! - [`demo`]: the default run (`host-sim` without a subcommand).
//! - [`link`]: links to the controller (in process, emulator UART over TCP, serial port) and the link check.
//! - [`world`]: the simulated world's physics (robot plant, conveyor, gripper).

pub mod accuracy;
pub mod calibrate_cmd;
pub mod demo;
pub mod link;
pub mod log;
pub mod pick;
pub mod workcell;
pub mod world;
