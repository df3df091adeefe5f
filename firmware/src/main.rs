//! Workcell controller firmware for a Cortex-M4F.
//!
//! Two boards, chosen at build time (exactly one feature):
//! - `board-stm32f407` (default): STM32F407VG; `cargo run --release` inside
//!   `firmware/` flashes it with probe-rs.
//! - `board-qemu`: the ARM MPS2 AN386 that `qemu-system-arm -machine
//!   mps2-an386` emulates; `scripts/qemu-run` (or `cargo qemu` at the
//!   workspace root) builds and runs it.
//!
//! `board` holds all board-specific code behind traits; `app` is the same on
//! both boards; `executor` is the WFI-sleeping embassy executor both use.
#![no_std]
#![no_main]
#![deny(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod app;
mod board;
mod executor;

defmt::timestamp!("{=u64:us}", embassy_time::Instant::now().as_micros());

#[cortex_m_rt::entry]
fn main() -> ! {
    app::stats::stack::paint();
    let board = match board::active::init() {
        Ok(board) => board,
        Err(e) => defmt::panic!("board init failed: {}", e),
    };
    executor::run(|spawner| app::start(spawner, board))
}
