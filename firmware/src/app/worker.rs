//! The worker, in thread mode (the lowest priority): it feeds the
//! self-calibrator with the observations the link paired, and runs the jobs
//! the control loop asks for (an estimate: Sections 2 and 3; an intercept
//! plan). A job may take seconds on the M4; both interrupt levels preempt it.

use core::future::{poll_fn, Future};
use core::pin::Pin;
use core::task::{Context, Poll};

use embassy_sync::channel::TrySendError;
use shared::app::pick::handoff::{JobRequest, VisionNews, WorkItem};
use shared::app::pick::settings::PickSettings;
use shared::app::pick::worker::PickWorker;

use super::channels::{Configured, NEWS, NEWS_READY, WORK, WORKER_CONFIG};
use super::stats;
use crate::board::{active, interrupt_time, CycleCounter};

/// Hands the news in `pending` to the control loop, taking it. It never
/// drops a job's result: when the queue is full it wakes the control loop
/// (which may be waiting for this very result), puts the result back and
/// returns `true`: wait for room and call again.
#[inline(never)]
fn tell_control(pending: &mut Option<VisionNews>) -> bool {
    let Some(news) = pending.take() else {
        return false;
    };
    let is_result = matches!(news, VisionNews::Result(_));
    match NEWS.try_send(news) {
        Ok(()) => {
            if is_result {
                NEWS_READY.signal(());
            }
            false
        }
        Err(TrySendError::Full(news)) => {
            if is_result {
                NEWS_READY.signal(());
                *pending = Some(news);
                true
            } else {
                stats::count_dropped_handoff();
                false
            }
        }
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
        Err(e) => defmt::error!("worker: configuration refused: {} {}", e.field, e.reason),
    }
}

/// Waits for a new configuration (returned, for the task to replace the
/// worker) or an item of work (run if it belongs to the current session; its
/// news, if any, left in `news`). A configuration comes first, as it did when
/// both were ready. Out of line, like everything the task does between
/// awaits: the task's poll then holds no temporaries (it held 4.6 KB of them,
/// under the bundle adjustment's frames), and the item and the news never
/// cross an await by value. The worker is not built in here: this frame
/// (4.4 KB, the estimate job's) would be under the build's, at the same time
/// as the control loop builds its controller for the same configuration.
#[inline(never)]
fn poll_work(
    cx: &mut Context<'_>,
    worker: &mut Option<(u32, PickWorker)>,
    news: &mut Option<VisionNews>,
    cycles: &active::Cycles,
) -> Poll<Option<Configured>> {
    // `Signal::wait` is a stateless poll function: a new one per poll is the
    // same as keeping one.
    if let Poll::Ready(configured) = Pin::new(&mut WORKER_CONFIG.wait()).poll(cx) {
        return Poll::Ready(Some(configured));
    }
    let Poll::Ready((session, item)) = WORK.poll_receive(cx) else {
        return Poll::Pending;
    };
    // A configuration signalled before this item was queued applies to it
    // (a configuration between the two polls above: rare enough to be built
    // here).
    if let Some(configured) = WORKER_CONFIG.try_take() {
        build(worker, &configured);
    }
    let Some((current, pick_worker)) = worker.as_mut() else {
        return Poll::Ready(None);
    };
    if session != *current {
        return Poll::Ready(None);
    }
    // The job's own instructions: the interrupt handlers that preempt it are
    // charged to themselves (how many fall inside a job follows the host's
    // timing, not the job's work).
    let (started, handlers_before) = (cycles.now(), interrupt_time::spent());
    *news = pick_worker.process(&item);
    let handlers = interrupt_time::spent().wrapping_sub(handlers_before);
    let cost = cycles
        .now()
        .wrapping_sub(started)
        .saturating_sub(handlers)
        .saturating_mul(cycles.scale());
    let kind = match &item {
        WorkItem::Observation(_) => stats::JobKind::Observation,
        WorkItem::Job(ticket) => match ticket.request {
            JobRequest::Estimate {
                preliminary: true, ..
            } => stats::JobKind::EstimatePreliminary,
            JobRequest::Estimate { .. } => stats::JobKind::EstimateFinal,
            JobRequest::Plan { .. } => stats::JobKind::Plan,
        },
    };
    stats::record_job(kind, cost);
    if kind != stats::JobKind::Observation {
        defmt::info!("worker: {} done, {} {}", kind, cost, cycles.unit());
    }
    Poll::Ready(None)
}

#[embassy_executor::task]
pub async fn worker_task(cycles: active::Cycles) {
    let mut worker: Option<(u32, PickWorker)> = None;
    let mut news: Option<VisionNews> = None;
    loop {
        if let Some(configured) = poll_fn(|cx| poll_work(cx, &mut worker, &mut news, &cycles)).await
        {
            build(&mut worker, &configured);
        }
        while tell_control(&mut news) {
            poll_fn(|cx| NEWS.poll_ready_to_send(cx)).await;
        }
    }
}
