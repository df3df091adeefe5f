//! `host-sim` library: observation-log I/O, the synthetic workcell and the
//! accuracy runs behind the `host-sim` binary's subcommands.

pub mod log;
pub mod workcell;
