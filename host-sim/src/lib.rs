//! `host-sim` library: everything behind the `host-sim` binary's subcommands.

pub mod accuracy;
pub mod calibration;
pub mod commands;
pub mod geometry;
pub mod link;
pub mod log;
pub mod pick;
pub mod recording;
pub mod scenario;
pub mod world;
