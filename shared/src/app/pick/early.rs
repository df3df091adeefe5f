//! A calibration that ends when it knows enough (issue 20: the time to a
//! calibrated cell).
//!
//! The final estimate waits for the last calibration pose: 8 poses, 10 to
//! 13 s of the cell's start. A cell whose camera pins the disc (its rim seen
//! through images, or a fast camera) knows the part in the base frame far
//! better than the grasp needs after a few of them. So from
//! `PickSettings::early_estimate_after_poses` on, once the marks have been
//! shown at the lowest height, the pick asks for an estimate as the arm
//! reaches each pose and goes on meanwhile; one whose own uncertainty of the
//! part in the base frame (Eq 1's terms propagated:
//! `CalibrationReport::sigma_grasp_*`) meets the settings'
//! `calibrated_sigma_*` ends the calibration at the pose the arm is at or
//! on its way to, and the pick locates the part from there. An estimate short of it is not used:
//! the poses were planned from the preliminary one, and the final one comes
//! after them as before, so a cell that needs every pose loses no time to
//! the early ones. (Through images the sigmas understate the error 2 to 3
//! times, the front end's bias rather than noise; the cells that stop early
//! claim some 0.15 mm, far inside the target even so: docs/calibration.md.)

use super::settings::{at_most, PickSettings};
use crate::protocol::CalibrationReport;

/// The early estimates of one calibration (the job slot says whether one
/// is in flight: `JobKind::Early`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct EarlyFinish {
    /// An early estimate met the target: the calibration ends with the
    /// move in progress.
    met: bool,
}

impl EarlyFinish {
    /// Nothing met yet.
    pub(super) const fn new() -> Self {
        Self { met: false }
    }

    /// Whether to ask for an estimate as the arm leaves for pose `next` of
    /// `poses`: the job slot is free, enough poses have been shown, the
    /// lowest height among them (`lowest_shown`: the arm then goes down to
    /// the part on a calibration that has seen the marks as low as the
    /// final one would have), and another one follows (after the last, the
    /// final estimate is asked for).
    pub(super) fn due(
        &self,
        slot_idle: bool,
        next: usize,
        poses: usize,
        after: u8,
        lowest_shown: bool,
    ) -> bool {
        slot_idle && lowest_shown && !self.met && next >= usize::from(after.max(1)) && next < poses
    }

    /// The early estimate came (or failed): `met` when it meets the target.
    pub(super) fn landed(&mut self, met: bool) {
        self.met = met;
    }

    /// Whether an early estimate met the target.
    pub(super) fn met(&self) -> bool {
        self.met
    }
}

/// Whether `report` knows the part in the base frame to the settings'
/// `calibrated_sigma_*` (a NaN fails).
pub(super) fn meets_target(report: &CalibrationReport, settings: &PickSettings) -> bool {
    at_most(
        report.sigma_grasp_horizontal_m,
        settings.calibrated_sigma_horizontal_m,
    ) && at_most(
        report.sigma_grasp_vertical_m,
        settings.calibrated_sigma_vertical_m,
    ) && at_most(
        report.sigma_grasp_yaw_rad,
        settings.calibrated_sigma_yaw_rad,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::pick::sure_tests::report;

    #[test]
    fn the_target_is_met_on_every_axis_or_not_at_all() {
        let settings = PickSettings::default();
        let h = settings.calibrated_sigma_horizontal_m;
        let v = settings.calibrated_sigma_vertical_m;
        let y = settings.calibrated_sigma_yaw_rad;
        assert!(meets_target(&report(h, v, y), &settings));
        assert!(!meets_target(&report(h * 1.01, v, y), &settings));
        assert!(!meets_target(&report(h, v * 1.01, y), &settings));
        assert!(!meets_target(&report(h, v, y * 1.01), &settings));
        assert!(!meets_target(&report(f32::NAN, v, y), &settings));
    }

    #[test]
    fn an_early_estimate_is_asked_for_only_between_poses() {
        let early = EarlyFinish::new();
        assert!(!early.due(true, 2, 8, 3, true), "before the third pose");
        assert!(early.due(true, 3, 8, 3, true));
        assert!(early.due(true, 7, 8, 3, true));
        assert!(
            !early.due(true, 4, 8, 3, false),
            "not yet down to the lowest"
        );
        assert!(
            !early.due(true, 8, 8, 3, true),
            "after the last: the final estimate"
        );
        assert!(!early.due(false, 4, 8, 3, true), "the slot is busy");
        let mut met = early;
        met.landed(false);
        assert!(!met.met() && met.due(true, 5, 8, 3, true));
        met.landed(true);
        assert!(met.met());
        assert!(!met.due(true, 5, 8, 3, true), "met: nothing more to ask");
    }
}
