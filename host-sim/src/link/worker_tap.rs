//! What the in-process controller's worker was given, item by item: the
//! observation frames its calibrator was pushed, in order, the log header and
//! the calibration configuration it was built from (as the controller built
//! them from the cell configuration it was told), and every estimate job with
//! its result. Kept on the host only: the firmware's worker is not touched.
//!
//! The controller's estimate reaches the control loop as a
//! [`CellEstimate`], in the control loop's f32. The full-precision
//! [`CalibrationResult`] it was made from comes from a twin of the worker's
//! calibrator (the same type, built from the same header and configuration,
//! pushed the same frames and asked at the same jobs) and is checked against
//! the controller's own: [`CellEstimate::new`] of the twin's result must equal
//! the job's estimate in every field (f32 and f64 alike), or the job is marked
//! as not matching. So a replay of the log can be held to the f64 result
//! rather than to its f32 rounding (about 6e-8 m on a metre).

use shared::app::pick::cell::Cell;
use shared::app::pick::estimate::CellEstimate;
use shared::app::pick::handoff::{JobOutcome, JobRequest, VisionNews, WorkItem};
use shared::app::pick::worker::adopt_before_thinning;
use shared::app::pick::PickCalibrator;
use shared::calibration::{CalibrationConfig, CalibrationError, EstimateUncertainty};
use shared::observation::{CalibrationResult, LogHeader, ObservationFrame};
use shared::protocol::{CellConfig, FaultCause};

/// One estimate job the worker ran.
#[derive(Debug, Clone)]
pub struct EstimateJob {
    /// A preliminary estimate (from the search) or a final one.
    pub preliminary: bool,
    /// The controller's time of the request, microseconds.
    pub time_us: u64,
    /// Observations the worker had been given before the job: the log's
    /// first `frames_before` frames are what the estimate was made from.
    pub frames_before: usize,
    /// The twin calibrator's estimate at the job.
    pub twin: Result<(CalibrationResult, EstimateUncertainty), CalibrationError>,
    /// What the job answered: the estimate, or why it was refused.
    pub outcome: Option<Result<CellEstimate, FaultCause>>,
    /// The twin's estimate, in the control loop's form, equals the job's
    /// (`None` when the job refused it: nothing to compare).
    pub matches_controller: Option<bool>,
}

/// What one configured session's worker was given.
#[derive(Debug, Clone)]
pub struct WorkerLog {
    /// The header the worker's calibrator was built on.
    pub header: LogHeader,
    /// The calibrator's configuration (with the disc height the controller
    /// was told, if any).
    pub config: CalibrationConfig,
    /// Every observation, in the order the worker took them.
    pub frames: Vec<ObservationFrame>,
    /// Indices (into `frames`) of the observations the calibrator refused.
    pub refused: Vec<usize>,
    /// Every estimate job, in order.
    pub estimates: Vec<EstimateJob>,
    /// The observations the worker had been given when it adopted an
    /// estimate (each estimate it used, and the one it adopts when a store
    /// fills before the pick has estimated: from then on its calibrator folds
    /// what it has no room for at that estimate). A replay adopts there too.
    pub adopted_after_frames: Vec<usize>,
    /// Observations whose refusal by the twin and by the worker disagreed
    /// (0 unless the twin is not the worker's twin).
    pub refusal_mismatches: u32,
    /// The time of the first sensor sample the pick ran on (after homing),
    /// microseconds: the log's time and conveyor angle zero.
    pub pick_start_us: Option<u64>,
    /// The twin calibrator (boxed: 18 KiB).
    twin: Box<PickCalibrator>,
}

impl WorkerLog {
    /// The last final (not preliminary) estimate job, if one ran.
    pub fn final_estimate(&self) -> Option<&EstimateJob> {
        self.estimates.iter().rev().find(|job| !job.preliminary)
    }
}

/// Records the worker's items while a session is configured.
#[derive(Debug, Clone, Default)]
pub struct WorkerTap {
    session: Option<WorkerLog>,
}

impl WorkerTap {
    /// A tap that has seen nothing yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// The controller accepted `config`: its pick (and worker) starts anew.
    /// A configuration the worker itself would refuse leaves no session.
    pub fn configured(&mut self, config: &CellConfig) {
        self.session = Cell::new(config).ok().and_then(|cell| {
            let header = cell.log_header();
            let config = cell.calibration_config();
            let twin = PickCalibrator::new(&header, config).ok()?;
            Some(WorkerLog {
                header,
                config,
                frames: Vec::new(),
                refused: Vec::new(),
                estimates: Vec::new(),
                refusal_mismatches: 0,
                adopted_after_frames: Vec::new(),
                pick_start_us: None,
                twin: Box::new(twin),
            })
        });
    }

    /// The pick is about to run on a sensor sample of time `time_us`.
    pub fn pick_sample(&mut self, time_us: u64) {
        if let Some(log) = self.session.as_mut() {
            log.pick_start_us.get_or_insert(time_us);
        }
    }

    /// The worker is about to take `item`.
    pub fn before(&mut self, item: &WorkItem) {
        let Some(log) = self.session.as_mut() else {
            return;
        };
        match item {
            WorkItem::Observation(frame) => {
                let accepted = log.twin.push(frame).is_ok();
                if !accepted {
                    log.refused.push(log.frames.len());
                }
                log.frames.push(frame.clone());
                // The worker adopts, as it absorbs the frame that fills a
                // store, an estimate of what it holds (`absorb`): after this
                // many frames.
                if accepted && adopt_before_thinning(&mut log.twin) {
                    log.adopted_after_frames.push(log.frames.len());
                }
            }
            WorkItem::Job(ticket) => {
                if let JobRequest::Estimate {
                    preliminary,
                    time_us,
                    ..
                } = ticket.request
                {
                    log.estimates.push(EstimateJob {
                        preliminary,
                        time_us,
                        frames_before: log.frames.len(),
                        twin: log.twin.estimate_with_uncertainty(),
                        outcome: None,
                        matches_controller: None,
                    });
                }
            }
        }
    }

    /// The worker took `item` and answered `news`.
    pub fn after(&mut self, item: &WorkItem, news: Option<&VisionNews>) {
        let Some(log) = self.session.as_mut() else {
            return;
        };
        match (item, news) {
            (WorkItem::Observation(_), news) => {
                let worker_refused = matches!(news, Some(VisionNews::Refused));
                let twin_refused = log.refused.last() == Some(&(log.frames.len() - 1));
                if worker_refused != twin_refused {
                    log.refusal_mismatches += 1;
                }
            }
            (WorkItem::Job(_), Some(VisionNews::Result(result))) => {
                let (JobOutcome::Estimate(outcome), Some(job)) =
                    (&result.outcome, log.estimates.last_mut())
                else {
                    return;
                };
                let outcome = match outcome {
                    Ok((estimate, _)) => Ok(*estimate),
                    Err(cause) => Err(*cause),
                };
                // The worker adopts each estimate it answers with (before the
                // answer's folding counts are taken: none change at adoption).
                if outcome.is_ok() {
                    log.twin.adopt_last_estimate();
                    log.adopted_after_frames.push(job.frames_before);
                }
                job.matches_controller = match (&outcome, &job.twin) {
                    (Ok(estimate), Ok((result, sigma))) => Some(
                        CellEstimate::new(result, sigma, job.time_us).with_folding(&*log.twin)
                            == *estimate,
                    ),
                    (Ok(_), Err(_)) => Some(false),
                    (Err(_), _) => None,
                };
                job.outcome = Some(outcome);
            }
            (WorkItem::Job(_), _) => {}
        }
    }

    /// What the current session's worker was given (`None` before a
    /// configuration was accepted).
    pub fn log(&self) -> Option<&WorkerLog> {
        self.session.as_ref()
    }

    /// The log, taken out of the tap.
    pub fn take_log(&mut self) -> Option<WorkerLog> {
        self.session.take()
    }
}
