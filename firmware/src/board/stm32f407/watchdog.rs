//! The independent watchdog (IWDG): a control loop that stops running periods
//! resets the MCU, and the reset takes the drives off.
//!
//! `init` sets the IWDG up (`IndependentWatchdog::new`: prescaler and reload)
//! without starting it; the control loop's first period starts it
//! (`unleash`) and every period reloads it (`pet`). Nothing stops it again
//! but a reset.
//!
//! Timeout: [`TIMEOUT_US`] = 32 ms nominal: prescaler 4 and reload 255, so 256
//! counts of LSI / 4 at embassy-stm32's nominal 32 kHz LSI. The F407's LSI is
//! only specified to 17 to 47 kHz (datasheet, LSI oscillator
//! characteristics), so the real timeout is 21.8 ms to 60.2 ms:
//! - far over the 1 ms period: a healthy loop feeds it every millisecond,
//!   leaving more than 20 periods of margin even with the fastest LSI;
//! - over the pick's stall limit (20 ms, `PickSettings::stall_limit_s`) even
//!   with the fastest LSI: a gap the loop comes back from is the pick's to
//!   answer (`ControlStall`: a controlled stop, reported, the session kept),
//!   not a reset that drops the drives and the session; the watchdog is for
//!   the loop that does not come back;
//! - short enough to bound a hang: the PWM timers keep running at the last
//!   duties when the CPU stops, so an amplifier cannot see a hung firmware
//!   through its inputs. The drives' own 5 ms watchdog that host-sim models
//!   (braking when commands stop) exists on the real cell only if the
//!   amplifiers have one of their own; without it the last torque stays on
//!   until this watchdog fires, at most 60 ms.
//!
//! At the reset every GPIO returns to its reset state, a floating input (the
//! JTAG pins PA13-15, PB3 and PB4 return to their debug functions instead:
//! SWD and three encoder inputs, no output). The amplifier enable PE15 is
//! active high and then floats, so the drives are off only if the line has a
//! pull-down on the amplifier side (or an enable input that reads open as
//! off), as the pin map requires; it stays low through the boot until `init`
//! drives it low again (`ServoAmplifiers::new`, before any PWM pin). The PWM
//! and direction lines float too, harmless with the enable low. The gripper
//! PD0 floats, then `init` drives it low: the gripper opens and a part in its
//! jaws is dropped.
//!
//! The watchdog keeps counting while a debugger halts the core (embassy-stm32
//! leaves DBGMCU_APB1_FZ.DBG_IWDG_STOP clear): a halt once it is armed resets
//! the board within the timeout, which takes the drives off rather than
//! leaving the PWM running under a halted core. The option byte WDG_SW must
//! stay at its default (software watchdog), or the IWDG would run from reset.

use embassy_stm32::pac;
use embassy_stm32::peripherals::IWDG;
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::Peri;

use crate::board::Watchdog;

/// Nominal IWDG timeout (microseconds); see the module documentation for why
/// and for its real range.
pub const TIMEOUT_US: u32 = 32_000;

// `IndependentWatchdog::new` panics beyond its longest timeout (32.8 s) and
// underflows its reload under one count (125 us); keep well inside, on the
// smallest prescaler (4, up to 512 ms).
const _: () = assert!(TIMEOUT_US >= 1_000 && TIMEOUT_US <= 512_000);

/// The IWDG, set up but not started until the first [`Watchdog::feed`].
pub struct IndependentWatchdogFeed {
    iwdg: IndependentWatchdog<'static, IWDG>,
    armed: bool,
}

impl IndependentWatchdogFeed {
    /// Writes the prescaler and reload for [`TIMEOUT_US`]; does not start it.
    pub fn new(iwdg: Peri<'static, IWDG>) -> Self {
        IndependentWatchdogFeed {
            iwdg: IndependentWatchdog::new(iwdg, TIMEOUT_US),
            armed: false,
        }
    }
}

impl Watchdog for IndependentWatchdogFeed {
    fn feed(&mut self) {
        if !self.armed {
            // Started, it counts down from 0xFFF; the reload below makes the
            // first timeout the configured one.
            self.iwdg.unleash();
            self.armed = true;
            defmt::info!(
                "independent watchdog armed: {} ms nominal",
                TIMEOUT_US / 1_000
            );
        }
        self.iwdg.pet();
    }
}

/// Whether the last reset came from the IWDG (RCC_CSR IWDGRSTF, `wdgrstf` in
/// the PAC). Clears the reset flags (RMVF clears all of them at once), so the
/// next boot sees only its own cause. Call before anything can reset the MCU.
pub fn take_iwdg_reset_flag() -> bool {
    let csr = pac::RCC.csr();
    let by_iwdg = csr.read().wdgrstf();
    csr.modify(|w| w.set_rmvf(true));
    by_iwdg
}
