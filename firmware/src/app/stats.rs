//! What the firmware measures about itself: the control period's cost (worst
//! and mean), the worker's jobs, deadline misses, dropped hand-offs, and the
//! stack's high-water mark (the stack is painted at boot; the deepest word
//! that no longer holds the paint is the deepest the stack has been).

use core::cell::RefCell;
use core::sync::atomic::{AtomicU32, Ordering};

use critical_section::Mutex;
use shared::protocol::{CostUnit, JobCosts, PickPhase, RuntimeReport};

/// Costs since the cell was configured.
struct Costs {
    control_ticks: u64,
    control_worst: u32,
    control_sum: u64,
    jobs_run: u32,
    job_worst: JobCosts,
    deadline_misses: u32,
    late_results: u32,
    worst_tick: u64,
    worst_phase: PickPhase,
}

static COSTS: Mutex<RefCell<Costs>> = Mutex::new(RefCell::new(Costs {
    control_ticks: 0,
    control_worst: 0,
    control_sum: 0,
    jobs_run: 0,
    job_worst: JobCosts::ZERO,
    deadline_misses: 0,
    late_results: 0,
    worst_tick: 0,
    worst_phase: PickPhase::Idle,
}));

/// Outgoing messages dropped (link queue full).
pub static MESSAGES_DROPPED: AtomicU32 = AtomicU32::new(0);
/// Observations, triggers or news dropped between tasks (queue full).
pub static HANDOFFS_DROPPED: AtomicU32 = AtomicU32::new(0);

/// The last accepted reconfiguration's cost (counter units x scale).
static RECONFIGURE_COST: AtomicU32 = AtomicU32::new(0);

/// A reconfiguration (building the new pick) cost `cost` units.
pub fn record_reconfigure(cost: u32) {
    RECONFIGURE_COST.store(cost, Ordering::Relaxed);
}

/// Frames from the host the link's decoder refused (written by the link task,
/// reported by the control loop in the pick's telemetry).
pub static FRAMES_REJECTED: AtomicU32 = AtomicU32::new(0);

pub fn count_dropped_message() {
    MESSAGES_DROPPED.fetch_add(1, Ordering::Relaxed);
}

pub fn count_dropped_handoff() {
    HANDOFFS_DROPPED.fetch_add(1, Ordering::Relaxed);
}

/// One control period cost `cost` units; `missed` if it overran its deadline;
/// `phase` is the pick's phase at its end.
pub fn record_control(cost: u32, missed: bool, late_results: u32, phase: PickPhase) {
    critical_section::with(|cs| {
        let mut costs = COSTS.borrow_ref_mut(cs);
        costs.control_ticks = costs.control_ticks.saturating_add(1);
        if cost > costs.control_worst {
            costs.control_worst = cost;
            costs.worst_tick = costs.control_ticks;
            costs.worst_phase = phase;
        }
        costs.control_sum = costs.control_sum.saturating_add(u64::from(cost));
        if missed {
            costs.deadline_misses = costs.deadline_misses.saturating_add(1);
        }
        costs.late_results = late_results;
    });
}

/// The kinds of background job, each with its own worst cost.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum JobKind {
    /// The estimate after the search.
    EstimatePreliminary,
    /// The estimate after the calibration poses.
    EstimateFinal,
    /// An intercept plan.
    Plan,
    /// One observation absorbed by the calibrator (not counted as a job).
    Observation,
}

/// One background job (or observation) of `kind` cost `cost` units.
pub fn record_job(kind: JobKind, cost: u32) {
    critical_section::with(|cs| {
        let mut costs = COSTS.borrow_ref_mut(cs);
        if kind != JobKind::Observation {
            costs.jobs_run = costs.jobs_run.saturating_add(1);
        }
        let worst = match kind {
            JobKind::EstimatePreliminary => &mut costs.job_worst.estimate_preliminary,
            JobKind::EstimateFinal => &mut costs.job_worst.estimate_final,
            JobKind::Plan => &mut costs.job_worst.plan,
            JobKind::Observation => &mut costs.job_worst.observation,
        };
        *worst = (*worst).max(cost);
    });
}

/// Control periods run and deadline misses, for `Status`.
pub fn ticks_and_misses() -> (u64, u32) {
    critical_section::with(|cs| {
        let costs = COSTS.borrow_ref(cs);
        (costs.control_ticks, costs.deadline_misses)
    })
}

/// Starts counting afresh (a new cell configuration).
pub fn reset_costs() {
    critical_section::with(|cs| {
        let mut costs = COSTS.borrow_ref_mut(cs);
        costs.control_worst = 0;
        costs.control_sum = 0;
        costs.worst_tick = 0;
        costs.worst_phase = PickPhase::Idle;
        costs.jobs_run = 0;
        costs.job_worst = JobCosts::ZERO;
        costs.late_results = 0;
    });
}

/// Everything measured, for the host.
pub fn report(unit: CostUnit) -> RuntimeReport {
    let (used, size) = stack::high_water();
    critical_section::with(|cs| {
        let costs = COSTS.borrow_ref(cs);
        let mean = costs
            .control_sum
            .checked_div(costs.control_ticks)
            .and_then(|m| u32::try_from(m).ok())
            .unwrap_or(0);
        RuntimeReport {
            unit,
            uptime_us: embassy_time::Instant::now().as_micros(),
            control_ticks: costs.control_ticks,
            control_worst: costs.control_worst,
            control_mean: mean,
            jobs_run: costs.jobs_run,
            job_worst: costs.job_worst,
            stack_used_bytes: used,
            stack_size_bytes: size,
            deadline_misses: costs.deadline_misses,
            messages_dropped: MESSAGES_DROPPED.load(Ordering::Relaxed),
            handoffs_dropped: HANDOFFS_DROPPED.load(Ordering::Relaxed),
            late_results: costs.late_results,
            control_worst_tick: costs.worst_tick,
            control_worst_phase: costs.worst_phase,
            reconfigure_cost: RECONFIGURE_COST.load(Ordering::Relaxed),
        }
    })
}

/// Stack painting.
pub mod stack {
    /// The paint: a word no real frame is likely to hold by chance.
    const PAINT: u32 = 0xC0FF_EE55;
    /// Stacks deeper than this are reported as "at least" this deep (the
    /// emulated board has 4 MiB of RAM; painting it all would slow the boot;
    /// the STM32F407's stack is 128 KiB).
    const MAX_PAINTED_BYTES: usize = 1024 * 1024;

    unsafe extern "C" {
        /// Top of the stack (cortex-m-rt: end of RAM).
        static _stack_start: u32;
        /// Lowest address the stack may reach (the board's memory.x: the end of
        /// the static data, or the start of a RAM block of its own).
        static _stack_limit: u32;
    }

    fn bounds() -> (usize, usize) {
        // Only the symbols' addresses are taken, never their values.
        let top = core::ptr::addr_of!(_stack_start) as usize;
        let bottom = core::ptr::addr_of!(_stack_limit) as usize;
        (bottom.max(top.saturating_sub(MAX_PAINTED_BYTES)), top)
    }

    /// Paints the unused stack below the current frame. Call first thing in
    /// `main`, before any interrupt is enabled.
    pub fn paint() {
        let (bottom, _) = bounds();
        // Leave a margin below this function's own frame.
        let sp = cortex_m::register::msp::read() as usize;
        let end = sp.saturating_sub(256) & !3;
        let mut address = (bottom + 3) & !3;
        while address < end {
            // SAFETY: [bottom, sp - 256) is stack memory below every live frame
            // (the stack grows down from `_stack_start`, and nothing else is
            // placed between `_stack_limit` and it); nothing reads it before
            // it is used as stack.
            unsafe { core::ptr::write_volatile(address as *mut u32, PAINT) };
            address += 4;
        }
    }

    /// Deepest use seen and the painted stack's size, in bytes.
    pub fn high_water() -> (u32, u32) {
        let (bottom, top) = bounds();
        let mut address = (bottom + 3) & !3;
        while address < top {
            // SAFETY: reading words of the stack region; the deepest ones are
            // still paint, the first that is not marks the high-water mark.
            let word = unsafe { core::ptr::read_volatile(address as *const u32) };
            if word != PAINT {
                break;
            }
            address += 4;
        }
        let used = u32::try_from(top.saturating_sub(address)).unwrap_or(u32::MAX);
        let size = u32::try_from(top.saturating_sub(bottom)).unwrap_or(u32::MAX);
        (used, size)
    }
}
