//! `host-sim` library: everything behind the `host-sim` binary's subcommands.
//!
//! - [`commands`]: the subcommands, one module each with its `Args` and `run`.
//! - [`scenario`]: the scenarios: pick scenario files (TOML) and named recording scenarios.
//! - [`world`]: the simulated world: workcell geometry and its generator, camera and vision, plant, conveyor, gripper, and the pick's [`world::World`].
//! - [`pick`]: the full pick against the controller: lock-step runner, records, reports, CSV, plots, Monte Carlo, fault campaign.
//! - [`recording`]: synthetic observation logs and their truth files from random workcells.
//! - [`calibration`]: self-calibration of an observation log on the host.
//! - [`batch_ml`]: the maximum-likelihood limit of a log: a full batch solve over every frame.
//! - [`accuracy`]: the seeded Monte-Carlo accuracy runs of the self-calibration.
//! - [`log`]: the observation log (JSON Lines) reader and writer.
//! - [`link`]: links to the controller (in process, emulator UART over TCP, serial port) and the link check.
//! - [`vision_check`]: the mark detector on rendered camera frames, against the truth.
//! - [`live_camera`]: a V4L2 camera as a recording's source (frames; the `v4l2` feature).
//! - [`overlay`]: pictures drawn over camera frames (PNG, animated GIF).
//! - [`rerun_view`]: a pick as a Rerun recording (the `rerun` feature).
//! - [`geometry`]: small geometric helpers with the contract's conventions.
//! - [`homing`]: power-on homing trials against the drawn counter offsets.

pub mod accuracy;
pub mod batch_ml;
pub mod calibration;
pub mod camera_recording;
pub mod commands;
pub mod front_end;
pub mod geometry;
pub mod homing;
pub mod link;
pub mod live_camera;
pub mod log;
pub mod overlay;
pub mod pick;
pub mod recording;
#[cfg(feature = "rerun")]
pub mod rerun_view;
pub mod scenario;
pub mod vision_check;
pub mod world;
