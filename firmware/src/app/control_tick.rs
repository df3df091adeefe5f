//! The control-loop tick. The computed-torque law (paper Eq 23) will run here
//! once per period; for now each period samples the joint encoders and counts
//! itself, and the servos are held disabled.

use core::sync::atomic::{AtomicU32, Ordering};

use embassy_time::{Duration, Ticker};

use crate::board::{active, JointEncoders, ServoOutputs};

/// Control-loop rate: the plant model and the gains of the control issue
/// assume a 1 ms period.
pub const CONTROL_RATE_HZ: u32 = 1_000;

/// Control periods since boot, low 32 bits (Cortex-M4 has no 64-bit atomics);
/// [`control_ticks`] extends it.
static CONTROL_TICKS: AtomicU32 = AtomicU32::new(0);

/// Extends the 32-bit tick counter to 64 bits for `ControllerStatus`.
///
/// The counter wraps after 49.7 days at 1 kHz; the reader keeps the number of
/// wraps it has seen, which is exact as long as it reads at least once per
/// wrap period (the link task reads before every reply).
pub struct TickReader {
    wraps: u64,
    last: u32,
}

impl TickReader {
    pub const fn new() -> Self {
        TickReader { wraps: 0, last: 0 }
    }

    /// Control periods since boot.
    pub fn control_ticks(&mut self) -> u64 {
        let now = CONTROL_TICKS.load(Ordering::Relaxed);
        if now < self.last {
            self.wraps += 1;
        }
        self.last = now;
        (self.wraps << 32) | u64::from(now)
    }
}

#[embassy_executor::task]
pub async fn control_tick_task(mut encoders: active::Encoders, mut servos: active::Servos) {
    // Nothing commands the arm yet: keep the drives off.
    servos.disable();
    let mut encoders_ok = true;
    let mut ticker = Ticker::every(Duration::from_hz(u64::from(CONTROL_RATE_HZ)));
    loop {
        ticker.next().await;
        if encoders_ok {
            if let Err(e) = encoders.read_counts() {
                // Reported once, not every millisecond.
                defmt::warn!("control tick: {}; encoder sampling stopped", e);
                encoders_ok = false;
            }
        }
        CONTROL_TICKS.fetch_add(1, Ordering::Relaxed);
    }
}
