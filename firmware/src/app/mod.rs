//! The application: identical on both boards. It only uses the board seam
//! (`crate::board`), `shared` and embassy.
//!
//! - [`link`]: the host link task (frames in, `shared::app::LinkResponder`
//!   replies out).
//! - [`control_tick`]: the 1 kHz control tick; it keeps the servos safe and
//!   counts periods so the host sees in `Status` that the executor and the
//!   board's time driver run.

mod control_tick;
mod link;

use embassy_executor::Spawner;

use crate::board::ActiveBoard;

pub use control_tick::CONTROL_RATE_HZ;

/// Spawns the application's tasks on the board's devices.
pub fn start(spawner: Spawner, board: ActiveBoard) {
    defmt::info!(
        "board {} up, control tick {} Hz",
        board.name,
        CONTROL_RATE_HZ
    );
    match control_tick::control_tick_task(board.encoders, board.servos) {
        Ok(token) => spawner.spawn(token),
        Err(_) => defmt::panic!("cannot spawn the control tick task"),
    }
    match link::link_task(board.name, board.serial) {
        Ok(token) => spawner.spawn(token),
        Err(_) => defmt::panic!("cannot spawn the link task"),
    }
}
