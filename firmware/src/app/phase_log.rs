//! The pick's phase changes in the log, written at the link's priority: a
//! defmt log line costs about 900 instructions on the M4F (encoding and the
//! transport), and a phase change falls in the worst control period
//! (`RuntimeReport.control_worst_tick` found it: 19,760 instructions with the
//! line, 18,880 without). The control loop only queues the change.

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use shared::protocol::{FaultCause, PickPhase};

/// Control loop -> this task: a new phase, and the fault if it is one. A
/// change that finds the queue full is not logged (eight changes within one
/// of the link's turns do not happen in a pick).
static PHASE_CHANGES: Channel<CriticalSectionRawMutex, (PickPhase, Option<FaultCause>), 8> =
    Channel::new();

/// Queues a phase change for the log; never waits.
pub fn note(phase: PickPhase, fault: Option<FaultCause>) {
    let _ = PHASE_CHANGES.try_send((phase, fault));
}

#[embassy_executor::task]
pub async fn phase_log_task() {
    loop {
        match PHASE_CHANGES.receive().await {
            (phase, Some(cause)) => defmt::warn!("pick: {} ({})", phase, cause),
            (phase, None) => defmt::info!("pick: {}", phase),
        }
    }
}
