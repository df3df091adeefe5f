//! The time interrupt handlers take out of whatever they preempt, so that a
//! thread-mode job (the worker's estimates and per-frame updates) is charged
//! its own instructions only.
//!
//! Why: the worker runs under both interrupt levels. Counted from its start
//! to its end, a per-frame update of about 200,000 instructions also held
//! every byte the link's receive interrupt took while it ran and every
//! control period that fell inside it, and how many of those fall inside
//! depends on when the host's bytes arrive, which in the emulator follows the
//! host machine's speed: the same firmware on the same data measured 234,240
//! instructions on one machine and 310,400 on another. Excluding the
//! handlers makes a job's figure its own and repeatable; the share of the core
//! the control loop takes is modelled apart (`host_sim::link::board_timing`).
//!
//! Every handler that does work calls [`enter`] and [`leave`]; only the outermost
//! of nested handlers is timed (its span holds the inner ones), in critical
//! sections of a few instructions, so the tally is exact up to the entry and
//! exit of the exception itself (about 12 cycles each).

use core::sync::atomic::{AtomicU32, Ordering};

use super::active::count_now;

/// Handlers running now (nested ones included).
static DEPTH: AtomicU32 = AtomicU32::new(0);
/// The counter when the outermost running handler started.
static ENTERED: AtomicU32 = AtomicU32::new(0);
/// Counts spent in handlers since boot (wraps, like the counter).
static SPENT: AtomicU32 = AtomicU32::new(0);

/// Call first in an interrupt handler that does work, and [`leave`] last:
/// the handler's time is added to [`spent`], in the board's cycle counter's
/// own counts. A pair of calls rather than a wrapper taking
/// the body: the body (an executor's poll) stays in the handler's own frame,
/// which the stack bound counts once.
#[inline(always)]
pub fn enter() {
    cortex_m::interrupt::free(|_| {
        let depth = DEPTH.load(Ordering::Relaxed);
        if depth == 0 {
            ENTERED.store(count_now(), Ordering::Relaxed);
        }
        DEPTH.store(depth.saturating_add(1), Ordering::Relaxed);
    });
}

/// See [`enter`].
#[inline(always)]
pub fn leave() {
    cortex_m::interrupt::free(|_| {
        let depth = DEPTH.load(Ordering::Relaxed).saturating_sub(1);
        DEPTH.store(depth, Ordering::Relaxed);
        if depth == 0 {
            let span = count_now().wrapping_sub(ENTERED.load(Ordering::Relaxed));
            SPENT.store(
                SPENT.load(Ordering::Relaxed).wrapping_add(span),
                Ordering::Relaxed,
            );
        }
    });
}

/// Counts spent in interrupt handlers since boot (wraps): a job's own cost is
/// its span less the growth of this over it.
pub fn spent() -> u32 {
    SPENT.load(Ordering::Relaxed)
}
