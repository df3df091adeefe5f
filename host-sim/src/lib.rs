//! `host-sim` library: the simulated world behind the `host-sim` binary's subcommands.

/// Links to the controller (in process, emulator UART over TCP, serial port) and the link check.
pub mod link;
pub mod world;
