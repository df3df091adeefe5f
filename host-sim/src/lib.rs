//! `host-sim` library: observation-log I/O, the synthetic workcell and the
//! accuracy runs behind the `host-sim` binary's subcommands.

pub mod accuracy;
pub mod calibrate_cmd;
pub mod log;
pub mod workcell;
