//! `host-sim` library: the simulated world behind the `host-sim` binary's subcommands.

pub mod world;
