//! The estimate goes on improving during the pick (issue 20: the estimate
//! the pick uses is always the best so far). The calibrator takes every
//! frame and sighting while the arm intercepts the part, so one more
//! estimate is asked for as the intercept ends; it lands as the arm starts
//! tracking the part, made from what came since the final calibration (in
//! the default cell, whose intercept lasts 1 s, 6 frames and 6 sightings
//! more; more where the part must first come round), and replaces the
//! estimate in use if it too is sure of the part and agrees with it. The part's state (Eq 1) then blends from the
//! replaced estimate to the new one over `estimate_fade_s` along a quintic,
//! so the reference neither leaps nor jerks.

use super::estimate::CellEstimate;
use crate::angle::wrap_pi;
use crate::planning::scaling::rest_to_rest;
use crate::planning::TaskState;

/// The refresh of one intercept.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Refresh {
    /// This intercept's refresh has been asked for.
    requested: bool,
    /// The estimate a refresh replaced, and when.
    replaced: Option<(CellEstimate, f32)>,
}

impl Refresh {
    /// Nothing asked for, nothing replaced.
    pub(super) const fn new() -> Self {
        Self {
            requested: false,
            replaced: None,
        }
    }

    /// A new intercept: it may have its own refresh.
    pub(super) fn rearm(&mut self) {
        self.requested = false;
    }

    /// Whether to ask for the refresh now, `remaining_s` before the
    /// intercept ends: once per intercept, `lead_s` (the estimate's budget)
    /// ahead, so it lands as the tracking starts with the newest frames.
    /// An intercept shorter than that less the tracking (`track_s`) gets
    /// none: it would land on the descent, and the part stays as the plan
    /// had it from there to the grasp.
    pub(super) fn due(&self, remaining_s: f32, lead_s: f32, track_s: f32) -> bool {
        !self.requested && remaining_s <= lead_s && remaining_s + track_s >= lead_s
    }

    /// The refresh has been asked for.
    pub(super) fn asked(&mut self) {
        self.requested = true;
    }

    /// `old` was replaced at `now_s`.
    pub(super) fn replaced(&mut self, old: CellEstimate, now_s: f32) {
        self.replaced = Some((old, now_s));
    }

    /// Forgets the replaced estimate once its blend is over.
    pub(super) fn expire(&mut self, now_s: f32, fade_s: f32) {
        let fading = self
            .replaced
            .is_some_and(|(_, since_s)| now_s - since_s < fade_s);
        if !fading {
            self.replaced = None;
        }
    }

    /// The grasp point's state (Eq 1) with the conveyor at `(theta, omega,
    /// alpha)` under `estimate`, blended from the replaced estimate's while
    /// the fade lasts.
    pub(super) fn grasp_point(
        &self,
        estimate: &CellEstimate,
        conveyor: [f32; 3],
        now_s: f32,
        fade_s: f32,
    ) -> TaskState<f32> {
        let [theta, omega, alpha] = conveyor;
        let new = estimate.grasp_point(theta, omega, alpha);
        let Some((old, since_s)) = self.replaced else {
            return new;
        };
        let elapsed_s = now_s - since_s;
        let fading = elapsed_s < fade_s && fade_s > 0.0;
        if !fading {
            return new;
        }
        // Weight of the old estimate: 1 - s(t) of a rest-to-rest quintic.
        let progress = rest_to_rest(elapsed_s.max(0.0) / fade_s, fade_s);
        let (w, w_rate, w_acceleration) =
            (1.0 - progress.s, -progress.rate, -progress.acceleration);
        let old = old.grasp_point(theta, omega, alpha);
        let dp = old.position - new.position;
        let dv = old.velocity - new.velocity;
        let da = old.acceleration - new.acceleration;
        let dyaw = wrap_pi(old.yaw - new.yaw);
        let dyaw_rate = old.yaw_rate - new.yaw_rate;
        let dyaw_acceleration = old.yaw_acceleration - new.yaw_acceleration;
        TaskState {
            position: new.position + dp * w,
            velocity: new.velocity + dv * w + dp * w_rate,
            acceleration: new.acceleration + da * w + dv * (2.0 * w_rate) + dp * w_acceleration,
            yaw: new.yaw + dyaw * w,
            yaw_rate: new.yaw_rate + dyaw_rate * w + dyaw * w_rate,
            yaw_acceleration: new.yaw_acceleration
                + dyaw_acceleration * w
                + dyaw_rate * (2.0 * w_rate)
                + dyaw * w_acceleration,
        }
    }
}

/// Whether `new` may replace `old`: the grasp point (with the conveyor at
/// `theta`) moves by at most `max_shift_m`. More data moves a sure estimate
/// by a sigma or two (about a millimetre); a refresh further off than the
/// gripper's capture speaks of bad data, not of more of it.
pub(super) fn agrees(old: &CellEstimate, new: &CellEstimate, theta: f32, max_shift_m: f32) -> bool {
    let shift = (old.grasp_point(theta, 0.0, 0.0).position
        - new.grasp_point(theta, 0.0, 0.0).position)
        .norm();
    shift <= max_shift_m
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Vector3};

    fn estimate(part_x_m: f32, part_yaw_rad: f32) -> CellEstimate {
        CellEstimate {
            base_yaw: 0.1,
            base_translation: Vector3::new(0.6, -0.2, -0.3),
            part_rotating: Vector3::new(part_x_m, 0.02, 0.04),
            part_yaw_rotating: part_yaw_rad,
            disc_from_camera: Matrix3::identity(),
            camera_centre_disc: Vector3::new(0.0, 0.0, 2.5),
            pixel_sigma_px: 0.5,
            report: super::super::sure_tests::report(0.001, 0.001, 0.001),
        }
    }

    /// The conveyor at `t`: turning evenly at 0.6 rad/s.
    fn conveyor(t: f32) -> [f32; 3] {
        [0.3 + 0.6 * t, 0.6, 0.0]
    }

    #[test]
    fn a_refreshed_estimate_takes_over_without_a_leap() {
        let (old, new) = (estimate(0.25, 0.3), estimate(0.252, 0.31));
        let fade_s = 0.5;
        let mut refresh = Refresh::new();
        refresh.replaced(old, 10.0);
        let at = |t: f32| refresh.grasp_point(&new, conveyor(t), t, fade_s);
        // At the replacement the part is where the old estimate had it ...
        let before = old.grasp_point(0.3 + 6.0, 0.6, 0.0);
        let start = at(10.0);
        assert!((start.position - before.position).norm() < 1e-5);
        assert!((start.velocity - before.velocity).norm() < 1e-5);
        assert!((start.yaw - before.yaw).abs() < 1e-5);
        // ... and it moves there smoothly: the rates are the derivatives.
        let h = 1e-3;
        for k in 1..10 {
            let t = 10.0 + 0.05 * k as f32;
            let (m, p, s) = (at(t - h), at(t + h), at(t));
            let velocity = (p.position - m.position) / (2.0 * h);
            assert!((velocity - s.velocity).norm() < 2e-4, "velocity at {t}");
            let acceleration = (p.velocity - m.velocity) / (2.0 * h);
            assert!(
                (acceleration - s.acceleration).norm() < 5e-3,
                "acceleration at {t}"
            );
            let yaw_rate = (p.yaw - m.yaw) / (2.0 * h);
            assert!((yaw_rate - s.yaw_rate).abs() < 1e-3, "yaw rate at {t}");
        }
        // After the fade it is the new estimate's, and the old one is forgotten.
        let after = new.grasp_point(0.3 + 6.0 + 0.36, 0.6, 0.0);
        assert!((at(10.6).position - after.position).norm() < 1e-6);
        refresh.expire(10.6, fade_s);
        assert_eq!(refresh.replaced, None);
    }

    #[test]
    fn a_refresh_far_from_the_estimate_in_use_is_not_adopted() {
        let old = estimate(0.25, 0.3);
        assert!(agrees(&old, &estimate(0.252, 0.3), 1.0, 0.01));
        assert!(!agrees(&old, &estimate(0.27, 0.3), 1.0, 0.01));
        assert!(!agrees(&old, &estimate(f32::NAN, 0.3), 1.0, 0.01));
    }

    #[test]
    fn one_refresh_is_asked_for_per_intercept_to_land_while_tracking() {
        let mut refresh = Refresh::new();
        assert!(!refresh.due(3.0, 1.0, 0.3));
        assert!(refresh.due(0.9, 1.0, 0.3));
        refresh.asked();
        assert!(!refresh.due(0.8, 1.0, 0.3));
        refresh.rearm();
        assert!(refresh.due(0.8, 1.0, 0.3));
        // Too short to land before the tracking ends: none.
        assert!(!refresh.due(0.6, 1.0, 0.3));
    }
}
