//! The application: identical on both boards. It only uses the board seam
//! (`crate::board`) and embassy.
//!
//! - `link_task`: reads the host link in whatever chunks arrive and answers.
//! - `control_tick_task`: the 1 kHz control tick; for now it counts ticks so
//!   the host can see (in `Status`) that the executor and time driver run.

use core::sync::atomic::{AtomicU32, Ordering};

use embassy_executor::Spawner;
use embassy_time::{Duration, Ticker};
use embedded_io_async::{Read, Write};

use crate::board::{active, ActiveBoard};

/// Control loop rate (paper Section 4: the computed-torque loop runs at a
/// fixed rate; 1 kHz is the skeleton's rate).
pub const CONTROL_RATE_HZ: u32 = 1_000;

/// Control ticks since boot, written by the tick task, read by the link task.
static CONTROL_TICKS: AtomicU32 = AtomicU32::new(0);

/// Bytes read from the link per `read` call at most.
const READ_CHUNK: usize = 64;

/// Spawns the application's tasks on the board's devices.
pub fn start(spawner: Spawner, board: ActiveBoard) {
    defmt::info!("board {} up, control tick {} Hz", board.name, CONTROL_RATE_HZ);
    spawner.spawn(control_tick_task().unwrap_or_else(|_| halt("control tick task")));
    spawner.spawn(link_task(board.name, board.serial).unwrap_or_else(|_| halt("link task")));
}

fn halt(what: &str) -> ! {
    defmt::panic!("cannot spawn the {}", what)
}

#[embassy_executor::task]
async fn control_tick_task() {
    let mut ticker = Ticker::every(Duration::from_hz(u64::from(CONTROL_RATE_HZ)));
    loop {
        ticker.next().await;
        CONTROL_TICKS.fetch_add(1, Ordering::Relaxed);
    }
}

#[embassy_executor::task]
async fn link_task(board_name: &'static str, mut serial: active::Serial) {
    let mut chunk = [0u8; READ_CHUNK];
    defmt::info!("link up on {}", board_name);
    loop {
        let n = match serial.read(&mut chunk).await {
            Ok(n) => n,
            Err(e) => {
                defmt::warn!("link read error {}", defmt::Debug2Format(&e));
                continue;
            }
        };
        let Some(bytes) = chunk.get(..n) else { continue };
        if let Err(e) = serial.write_all(bytes).await {
            defmt::warn!("link write error {}", defmt::Debug2Format(&e));
        }
    }
}
