//! embassy-time driver on the AN386's CMSDK dual timer (25 MHz).
//!
//! Timer 1 runs free (32 bit, counting down) as the timebase; it is extended to
//! 64 bits by counting wraps. A wrap is detected as the elapsed count going
//! backwards between two readings, which cannot miss or double-count a period
//! as long as the counter is read at least once per period (171 s): timer 1's
//! own wrap interrupt guarantees that. Timer 2 is a one-shot alarm for the
//! earliest entry of the timer queue. SysTick is not used: extending its
//! 24-bit counter lost periods, and QEMU without icount drops its interrupts.
//!
//! Timer 1 boots part-way through a period (a free-running CMSDK timer counts
//! down from the value written to LOAD, then wraps to `u32::MAX`), so the first
//! wrap comes [`FIRST_WRAP_COUNTS`] after boot: every boot, and so every
//! emulator test, crosses a wrap instead of only runs longer than 171 s.

use core::cell::RefCell;
use core::task::Waker;

use critical_section::{CriticalSection, Mutex};
use embassy_time_queue_utils::Queue;

use super::mmio::{self, Irq, Reg};

const DUALTIMER: Reg = Reg(0x4000_2000);
const TIMER1: Reg = DUALTIMER;
const TIMER2: Reg = DUALTIMER.at(0x20);

// Per-timer register offsets (ARM DDI 0479, CMSDK dual timer).
const LOAD: usize = 0x00;
const VALUE: usize = 0x04;
const CONTROL: usize = 0x08;
const INTCLR: usize = 0x0C;
const MIS: usize = 0x14;

const CTRL_ONESHOT: u32 = 1 << 0;
const CTRL_SIZE_32: u32 = 1 << 1;
const CTRL_INT_ENABLE: u32 = 1 << 5;
const CTRL_ENABLE: u32 = 1 << 7;

/// The dual timer's clock on the AN386.
const TIMER_HZ: u64 = 25_000_000;
/// Timer counts per embassy tick.
const COUNTS_PER_TICK: u64 = TIMER_HZ / embassy_time_driver::TICK_HZ;
const _: () = assert!(
    COUNTS_PER_TICK * embassy_time_driver::TICK_HZ == TIMER_HZ,
    "the embassy tick rate must divide 25 MHz"
);
/// Timer counts from boot to timer 1's first wrap (2 s).
const FIRST_WRAP_COUNTS: u32 = 50_000_000;
/// The 64-bit count at boot, subtracted so embassy time starts at zero.
const BOOT_COUNTS: u64 = (u32::MAX - FIRST_WRAP_COUNTS) as u64;
/// Longest alarm programmed at once; later alarms are re-armed on expiry.
const MAX_ALARM_COUNTS: u64 = 1 << 31;

struct State {
    /// Completed periods of timer 1.
    wraps: u64,
    /// Elapsed count within the period at the last reading.
    last_elapsed: u32,
    queue: Queue,
}

pub struct DualTimerDriver {
    state: Mutex<RefCell<State>>,
}

embassy_time_driver::time_driver_impl!(static DRIVER: DualTimerDriver = DualTimerDriver {
    state: Mutex::new(RefCell::new(State {
        wraps: 0,
        last_elapsed: BOOT_COUNTS as u32,
        queue: Queue::new(),
    })),
});

/// Starts the timebase and unmasks the dual timer interrupt. Call once at boot.
pub fn init() {
    TIMER1.at(CONTROL).write(0);
    TIMER1.at(LOAD).write(FIRST_WRAP_COUNTS);
    TIMER1.at(INTCLR).write(1);
    // Free-running (not periodic, not one-shot) 32-bit mode, interrupt on wrap.
    TIMER1
        .at(CONTROL)
        .write(CTRL_SIZE_32 | CTRL_INT_ENABLE | CTRL_ENABLE);
    TIMER2.at(CONTROL).write(0);
    TIMER2.at(INTCLR).write(1);
    mmio::unmask(Irq::DualTimer);
}

impl State {
    /// The 64-bit timer count (25 MHz) since `init`.
    fn counts(&mut self) -> u64 {
        let elapsed = u32::MAX - TIMER1.at(VALUE).read();
        if elapsed < self.last_elapsed {
            self.wraps += 1;
        }
        self.last_elapsed = elapsed;
        ((self.wraps << 32) | u64::from(elapsed)).saturating_sub(BOOT_COUNTS)
    }

    /// Arms timer 2 for the queue's earliest deadline `at` (ticks), waking
    /// whatever has already expired first.
    fn set_alarm(&mut self, mut at: u64) {
        loop {
            TIMER2.at(CONTROL).write(0);
            TIMER2.at(INTCLR).write(1);
            if at == u64::MAX {
                return;
            }
            let now_counts = self.counts();
            let at_counts = at.saturating_mul(COUNTS_PER_TICK);
            if at_counts <= now_counts {
                at = self.queue.next_expiration(now_counts / COUNTS_PER_TICK);
                continue;
            }
            let delta = (at_counts - now_counts).min(MAX_ALARM_COUNTS);
            TIMER2.at(LOAD).write(delta as u32);
            TIMER2
                .at(CONTROL)
                .write(CTRL_ONESHOT | CTRL_SIZE_32 | CTRL_INT_ENABLE | CTRL_ENABLE);
            return;
        }
    }
}

impl embassy_time_driver::Driver for DualTimerDriver {
    fn now(&self) -> u64 {
        critical_section::with(|cs| self.state.borrow_ref_mut(cs).counts() / COUNTS_PER_TICK)
    }

    fn schedule_wake(&self, at: u64, waker: &Waker) {
        critical_section::with(|cs| {
            let mut state = self.state.borrow_ref_mut(cs);
            if state.queue.schedule_wake(at, waker) {
                let now = state.counts() / COUNTS_PER_TICK;
                let next = state.queue.next_expiration(now);
                state.set_alarm(next);
            }
        })
    }
}

impl DualTimerDriver {
    fn on_interrupt(&self, cs: CriticalSection<'_>) {
        let mut state = self.state.borrow_ref_mut(cs);
        if TIMER1.at(MIS).read() & 1 != 0 {
            TIMER1.at(INTCLR).write(1);
            // Reading the counter here is what keeps wrap detection exact.
            state.counts();
        }
        if TIMER2.at(MIS).read() & 1 != 0 {
            TIMER2.at(INTCLR).write(1);
            let now = state.counts() / COUNTS_PER_TICK;
            let next = state.queue.next_expiration(now);
            state.set_alarm(next);
        }
    }
}

/// Dual timer interrupt (AN386 line 10).
pub fn on_interrupt() {
    critical_section::with(|cs| DRIVER.on_interrupt(cs));
}
