//! The conveyor encoder, decoded in software: no timer is left for it (TIM1,
//! 8, 2, 5, 3, 4 decode the joints, TIM12 is the time driver, TIM9-11, 13 and
//! 14 drive the servos; TIM6/7 are basic timers without inputs), so its A and B
//! channels come in on two EXTI lines that interrupt on both edges, and the
//! interrupt handler steps the x4 state table in [`super::quadrature`].
//!
//! | channel | pin | EXTI line | vector |
//! | --- | --- | --- | --- |
//! | A | PD2 | 2 | EXTI2 |
//! | B | PD3 | 3 | EXTI3 |
//!
//! Lines 2 and 3 have vectors of their own (lines 5-9 and 10-15 share one),
//! and no other pin of the board uses an EXTI line.
//!
//! The count lives in an atomic: the interrupt handler is its only writer and
//! the control loop only loads it, so neither ever waits for the other. The
//! handler's own state (the pins and the last A/B state) sits behind a
//! critical section that only the handler takes; the two vectors have the
//! same priority, so they never preempt each other either.
//!
//! Priority: the two vectors keep the reset priority, like the UART and the
//! time driver, so an edge waits at most for one of those short handlers; all
//! of them preempt the control loop, which runs in thread mode.
//!
//! Limits: each edge costs one interrupt (about 12 cycles of entry and exit
//! plus the handler's body, well under a microsecond at 168 MHz, not measured
//! on hardware). If the next edge arrives before the handler has sampled the
//! pins, both channels appear to change at once: that step is not counted
//! (direction unknown) and [`ConveyorEncoder::skipped_steps`] goes up. Noisy
//! encoder lines need an RC filter or line receiver in front of the pins.

use core::cell::RefCell;
use core::sync::atomic::{AtomicU32, Ordering};

use critical_section::Mutex;
use embassy_stm32::exti::{ExtiInput, TriggerEdge};
use embassy_stm32::gpio::Pull;
use embassy_stm32::interrupt::typelevel::{Handler, Interrupt, EXTI2, EXTI3};
use embassy_stm32::mode::Blocking;
use embassy_stm32::peripherals::{EXTI2 as EXTI2_CH, EXTI3 as EXTI3_CH, PD2, PD3};
use embassy_stm32::Peri;

use super::quadrature::{quadrature_step, QuadratureState, QuadratureStep};

/// Conveyor count, x4 counts since boot, wrapping at 2^32 (the controller
/// unwraps it).
static COUNT: AtomicU32 = AtomicU32::new(0);
/// Transitions where both channels changed at once (edges lost).
static SKIPPED: AtomicU32 = AtomicU32::new(0);
/// Interrupts that found the decoder not set up; the handler then masks both
/// vectors so a pending line cannot lock the core up (never expected: the
/// decoder is stored before the lines are unmasked).
static FAULTS: AtomicU32 = AtomicU32::new(0);

/// What the interrupt handler owns.
struct Decoder {
    a: ExtiInput<'static, Blocking>,
    b: ExtiInput<'static, Blocking>,
    previous: QuadratureState,
}

static DECODER: Mutex<RefCell<Option<Decoder>>> = Mutex::new(RefCell::new(None));

/// The interrupt handler for both channels' vectors (bound in `mod.rs`).
pub struct EdgeHandler;

impl Handler<EXTI2> for EdgeHandler {
    unsafe fn on_interrupt() {
        on_edge();
    }
}

impl Handler<EXTI3> for EdgeHandler {
    unsafe fn on_interrupt() {
        on_edge();
    }
}

fn on_edge() {
    critical_section::with(|cs| {
        let mut slot = match DECODER.borrow(cs).try_borrow_mut() {
            Ok(slot) => slot,
            Err(_) => return fault(),
        };
        let Some(decoder) = slot.as_mut() else {
            return fault();
        };
        // Clear first, then sample: an edge after the sample sets the pending
        // bit again and is decoded by the next interrupt, never lost.
        decoder.a.clear_pending();
        decoder.b.clear_pending();
        let current = QuadratureState::from_levels(decoder.a.is_high(), decoder.b.is_high());
        match quadrature_step(decoder.previous, current) {
            QuadratureStep::Hold => {}
            QuadratureStep::Skipped => {
                SKIPPED.fetch_add(1, Ordering::Relaxed);
            }
            step => {
                let count = COUNT.load(Ordering::Relaxed);
                COUNT.store(count.wrapping_add_signed(step.delta()), Ordering::Relaxed);
            }
        }
        decoder.previous = current;
    });
}

fn fault() {
    FAULTS.fetch_add(1, Ordering::Relaxed);
    EXTI2::disable();
    EXTI3::disable();
}

/// The control loop's view of the conveyor encoder.
pub struct ConveyorEncoder {
    _private: (),
}

impl ConveyorEncoder {
    /// Configures PD2/PD3 as inputs (pull-ups: open-collector encoders work
    /// unchanged, push-pull ones override them) interrupting on both edges,
    /// and starts decoding from their present state with the count at 0.
    ///
    /// Everything happens inside one critical section, so no edge interrupt
    /// can run before the decoder is in place.
    pub fn start(
        a_pin: Peri<'static, PD2>,
        a_line: Peri<'static, EXTI2_CH>,
        b_pin: Peri<'static, PD3>,
        b_line: Peri<'static, EXTI3_CH>,
    ) -> Self {
        critical_section::with(|cs| {
            let a = ExtiInput::new_blocking(a_pin, a_line, Pull::Up, TriggerEdge::Any);
            let b = ExtiInput::new_blocking(b_pin, b_line, Pull::Up, TriggerEdge::Any);
            let previous = QuadratureState::from_levels(a.is_high(), b.is_high());
            COUNT.store(0, Ordering::Relaxed);
            DECODER.borrow(cs).replace(Some(Decoder { a, b, previous }));
        });
        // embassy-stm32's init enables every EXTI vector in the NVIC; this
        // says so here rather than relying on it.
        // SAFETY: the handlers are bound (`bind_interrupts!` in mod.rs) and
        // only touch the decoder through the critical section above.
        unsafe {
            EXTI2::enable();
            EXTI3::enable();
        }
        ConveyorEncoder { _private: () }
    }

    /// The wrapping x4 count.
    #[inline(always)]
    pub fn count(&self) -> u32 {
        COUNT.load(Ordering::Relaxed)
    }

    /// Steps lost because both channels changed between two interrupts.
    pub fn skipped_steps(&self) -> u32 {
        SKIPPED.load(Ordering::Relaxed)
    }

    /// Interrupts that found no decoder (then decoding has stopped).
    pub fn faults(&self) -> u32 {
        FAULTS.load(Ordering::Relaxed)
    }
}
