//! The one background job the pick may have in flight (an estimate or an
//! intercept plan). Its outcome is applied a fixed delay after the request,
//! not when the worker is done, so the run does not depend on how fast the
//! worker is, as long as it is done by then. A worker slower than that (a
//! real board's: the jobs take what the M4F takes) delivers late: the
//! outcome is applied when it comes, and the pick sees how late
//! ([`JobSlot::ready_late_by_s`]) to judge whether it still holds.

use super::handoff::{JobOutcome, JobRequest, JobResult, JobTicket};

/// What a job is for: the pick acts on its outcome by it, and a job opened
/// over another replaces it, kind and all.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum JobKind {
    /// The preliminary estimate asked for as the search turns back over
    /// the marks: it lands in `EstimatePreliminary`, or, refused, is asked
    /// for again with the arm at rest.
    PreliminaryOnTheWay,
    /// An estimate asked for with the arm at rest (preliminary or final).
    Estimate,
    /// An early estimate asked for at a calibration pose (see `early`).
    Early,
    /// The intercept's refresh of the estimate (see `refresh`).
    Refresh,
    /// An intercept plan.
    Plan,
}

/// A job in flight: requested, maybe computed, applied at `apply_at_s`.
#[derive(Debug, Clone, PartialEq)]
struct Job {
    kind: JobKind,
    job_id: u32,
    outcome: Option<JobOutcome>,
    apply_at_s: f32,
    /// When the outcome came (controller time), once it has.
    came_at_s: f32,
}

/// The job in flight, if any, and the numbering of jobs.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct JobSlot {
    /// Tells this configuration's results from an older one's.
    session: u32,
    next_job_id: u32,
    job: Option<Job>,
}

impl JobSlot {
    /// No job yet; results of another `session` are ignored.
    pub(super) fn new(session: u32) -> Self {
        Self {
            session,
            next_job_id: 1,
            job: None,
        }
    }

    /// Opens a job of `kind` for `request`, its outcome due at
    /// `apply_at_s`; the ticket goes to the worker. Any job in flight is
    /// forgotten.
    pub(super) fn open(
        &mut self,
        request: JobRequest,
        kind: JobKind,
        apply_at_s: f32,
    ) -> JobTicket {
        let job_id = self.next_job_id;
        self.next_job_id = self.next_job_id.wrapping_add(1);
        self.job = Some(Job {
            kind,
            job_id,
            outcome: None,
            apply_at_s,
            came_at_s: apply_at_s,
        });
        JobTicket {
            session: self.session,
            job_id,
            request,
        }
    }

    /// Keeps `result` if it answers the job in flight (first answer only).
    /// True when it came after its due time (the worker was too slow).
    pub(super) fn accept(&mut self, result: &JobResult, now_s: f32) -> bool {
        if result.session != self.session {
            return false;
        }
        let Some(job) = self.job.as_mut() else {
            return false;
        };
        if job.job_id != result.job_id || job.outcome.is_some() {
            return false;
        }
        let late = now_s > job.apply_at_s;
        job.outcome = Some(result.outcome.clone());
        job.came_at_s = now_s;
        late
    }

    /// The job's outcome once its delay has passed; the slot is then free.
    pub(super) fn take_ready(&mut self, now_s: f32) -> Option<JobOutcome> {
        let ready = self
            .job
            .as_ref()
            .is_some_and(|job| job.outcome.is_some() && now_s >= job.apply_at_s);
        if ready {
            self.job.take().and_then(|job| job.outcome)
        } else {
            None
        }
    }

    /// How long after its due time the outcome that [`JobSlot::take_ready`]
    /// would now return came (0 for one that came in time); `None` when none
    /// is ready.
    pub(super) fn ready_late_by_s(&self, now_s: f32) -> Option<f32> {
        self.job
            .as_ref()
            .filter(|job| job.outcome.is_some() && now_s >= job.apply_at_s)
            .map(|job| (job.came_at_s - job.apply_at_s).max(0.0))
    }

    /// True when a job's outcome is due at `now_s` and has not come.
    pub(super) fn awaits(&self, now_s: f32) -> bool {
        self.job
            .as_ref()
            .is_some_and(|job| job.outcome.is_none() && now_s >= job.apply_at_s)
    }

    /// No job is in flight.
    pub(super) fn is_idle(&self) -> bool {
        self.job.is_none()
    }

    /// The slot holds a job of `kind` (in flight, or its outcome not yet
    /// taken).
    pub(super) fn holds(&self, kind: JobKind) -> bool {
        self.job.as_ref().is_some_and(|job| job.kind == kind)
    }

    /// Forgets the job in flight: its outcome, when it comes, is ignored.
    pub(super) fn cancel(&mut self) {
        self.job = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planning::{ArcPoint, PlanError};
    use crate::robot::JointVector;

    fn request() -> JobRequest {
        JobRequest::Estimate {
            preliminary: true,
            time_us: 0,
            start_pose: ArcPoint {
                radius_m: 0.5,
                azimuth_rad: 0.0,
                z_m: 0.4,
                yaw_rad: 0.0,
            },
            q_now: JointVector::zeros(),
            from: ArcPoint {
                radius_m: 0.5,
                azimuth_rad: 0.0,
                z_m: 0.4,
                yaw_rad: 0.0,
            },
            waist_centre_azimuth: 0.0,
        }
    }

    fn result(session: u32, job_id: u32) -> JobResult {
        JobResult {
            session,
            job_id,
            outcome: JobOutcome::Plan(Err(PlanError::NoFeasibleIntercept)),
        }
    }

    #[test]
    fn an_outcome_is_applied_at_its_due_time_and_not_before() {
        let mut slot = JobSlot::new(7);
        let ticket = slot.open(request(), JobKind::Estimate, 2.0);
        assert_eq!((ticket.session, ticket.job_id), (7, 1));
        assert!(!slot.awaits(1.0));
        assert!(slot.awaits(2.0));
        assert!(!slot.accept(&result(7, 1), 1.5));
        assert!(!slot.awaits(2.0));
        assert_eq!(slot.ready_late_by_s(1.9), None);
        assert_eq!(slot.ready_late_by_s(2.0), Some(0.0));
        assert_eq!(slot.take_ready(1.9), None);
        assert!(slot.take_ready(2.0).is_some());
        assert!(slot.is_idle());
    }

    /// The slot says what its job is for until the outcome is taken, the
    /// job is cancelled or another replaces it.
    #[test]
    fn the_slot_holds_its_jobs_kind_until_it_is_taken_or_replaced() {
        let mut slot = JobSlot::new(7);
        assert!(!slot.holds(JobKind::Early));
        let _ = slot.open(request(), JobKind::Early, 2.0);
        assert!(slot.holds(JobKind::Early) && !slot.holds(JobKind::Estimate));
        assert!(!slot.accept(&result(7, 1), 1.0));
        assert!(slot.holds(JobKind::Early), "came, not yet taken");
        assert!(slot.take_ready(2.0).is_some());
        assert!(!slot.holds(JobKind::Early));
        let _ = slot.open(request(), JobKind::PreliminaryOnTheWay, 3.0);
        let _ = slot.open(request(), JobKind::Estimate, 4.0);
        assert!(!slot.holds(JobKind::PreliminaryOnTheWay) && slot.holds(JobKind::Estimate));
        slot.cancel();
        assert!(!slot.holds(JobKind::Estimate));
    }

    #[test]
    fn results_of_another_session_or_job_are_ignored_and_late_ones_counted() {
        let mut slot = JobSlot::new(7);
        let _ = slot.open(request(), JobKind::Estimate, 2.0);
        assert!(!slot.accept(&result(6, 1), 1.0));
        assert!(!slot.accept(&result(7, 2), 1.0));
        assert_eq!(slot.take_ready(3.0), None);
        assert!(slot.accept(&result(7, 1), 3.0));
        assert_eq!(slot.ready_late_by_s(3.5), Some(1.0));
        assert!(slot.take_ready(3.5).is_some());
        let second = slot.open(request(), JobKind::Plan, 5.0);
        assert_eq!(second.job_id, 2);
        slot.cancel();
        assert!(!slot.accept(&result(7, 2), 4.0));
        assert!(slot.is_idle());
    }
}
