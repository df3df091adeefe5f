//! The application: identical on both boards. It only uses the board seam
//! (`crate::board`), `shared` and embassy. Three tasks at three priorities:
//!
//! - [`control_loop`] (highest, interrupt executor): one control period per
//!   sensor sample: the pick's control part (fusion Eq 1, state machine,
//!   Eq 23), the outputs, and the supervisor's checks;
//! - [`link`] (middle, interrupt executor): the serial protocol session, the
//!   frame pairer, and the messages the control loop queued; beside it
//!   [`phase_log`] writes the pick's phase changes to the log;
//! - [`worker`] (thread mode, lowest): the self-calibrator and the jobs
//!   (estimate, intercept plan), which may take seconds.
//!
//! They meet only in [`channels`]; [`stats`] measures them.

mod channels;
mod control_loop;
mod homing;
mod link;
mod phase_log;
pub mod stats;
mod worker;

use embassy_executor::Spawner;

use crate::board::ActiveBoard;
use crate::executor::{start_interrupt_executor, Level};

pub use control_loop::CONTROL_RATE_HZ;

/// Spawns the application's tasks on the board's devices.
pub fn start(thread_spawner: Spawner, board: ActiveBoard) {
    defmt::info!(
        "board {} up, control {} Hz, {}",
        board.name,
        CONTROL_RATE_HZ,
        board.control_source
    );
    let (Some(control), Some(link)) = (
        start_interrupt_executor(Level::Control),
        start_interrupt_executor(Level::Link),
    ) else {
        defmt::panic!("interrupt executors started twice");
    };
    match control_loop::control_loop(
        board.plant,
        board.watchdog,
        board.cycles,
        board.control_source,
    ) {
        Ok(token) => control.spawn(token),
        Err(_) => defmt::panic!("cannot spawn the control loop"),
    }
    match link::link_task(board.name, board.serial, board.control_source, board.cycles) {
        Ok(token) => link.spawn(token),
        Err(_) => defmt::panic!("cannot spawn the link task"),
    }
    match phase_log::phase_log_task() {
        Ok(token) => link.spawn(token),
        Err(_) => defmt::panic!("cannot spawn the phase log"),
    }
    match worker::worker_task(board.cycles) {
        Ok(token) => thread_spawner.spawn(token),
        Err(_) => defmt::panic!("cannot spawn the worker"),
    }
}
