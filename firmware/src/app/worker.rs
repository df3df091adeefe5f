//! The worker, in thread mode (the lowest priority): it feeds the
//! self-calibrator with the observations the link paired, and runs the jobs
//! the control loop asks for (an estimate: Sections 2 and 3; an intercept
//! plan). A job may take seconds on the M4; both interrupt levels preempt it.

use embassy_futures::select::{select, Either};
use shared::app::pick::handoff::{VisionNews, WorkItem};
use shared::app::pick::settings::PickSettings;
use shared::app::pick::worker::PickWorker;

use super::channels::{Configured, NEWS, NEWS_READY, WORK, WORKER_CONFIG};
use super::stats;
use crate::board::{active, CycleCounter};

/// Hands news to the control loop. It never drops a job's result: when the
/// queue is full it wakes the control loop (which may be waiting for this
/// very result) and waits for room.
async fn tell_control(news: VisionNews) {
    let is_result = matches!(news, VisionNews::Result(_));
    if let Err(embassy_sync::channel::TrySendError::Full(news)) = NEWS.try_send(news) {
        if is_result {
            NEWS_READY.signal(());
            NEWS.send(news).await;
        } else {
            stats::count_dropped_handoff();
        }
    }
    if is_result {
        NEWS_READY.signal(());
    }
}

/// Replaces the worker for a new configuration. Out of line, so that the
/// temporaries the worker is built in (its calibrator is 32 KiB) live in this
/// function's frame while it runs, not in the task's frame, which stays
/// reserved under the bundle adjustment's (inlined, they took the deepest
/// stack from 104 KB to 128 KB).
#[inline(never)]
fn build(slot: &mut Option<(u32, PickWorker)>, configured: &Configured) {
    *slot = None;
    match PickWorker::new(&configured.config, PickSettings::default()) {
        Ok(worker) => *slot = Some((configured.session, worker)),
        Err(e) => defmt::error!("worker: configuration refused: {}", e.field),
    }
}

#[embassy_executor::task]
pub async fn worker_task(cycles: active::Cycles) {
    let mut worker: Option<(u32, PickWorker)> = None;
    loop {
        let (session, item) = match select(WORKER_CONFIG.wait(), WORK.receive()).await {
            Either::First(configured) => {
                build(&mut worker, &configured);
                continue;
            }
            Either::Second(work) => work,
        };
        // A configuration signalled before this item was queued applies to it.
        if let Some(configured) = WORKER_CONFIG.try_take() {
            build(&mut worker, &configured);
        }
        let Some((current, pick_worker)) = worker.as_mut() else {
            continue;
        };
        if session != *current {
            continue;
        }
        let started = cycles.now();
        let news = pick_worker.process(&item);
        if matches!(item, WorkItem::Job(_)) {
            let cost = cycles
                .now()
                .wrapping_sub(started)
                .saturating_mul(cycles.scale());
            stats::record_job(cost);
            defmt::info!("worker: job done, {} {}", cost, cycles.unit());
        }
        if let Some(news) = news {
            tell_control(news).await;
        }
    }
}
