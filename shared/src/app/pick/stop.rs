//! The controlled stop: decelerate to rest along a quintic, then hold. Where
//! it starts (the reference, or the arm itself when it is not following the
//! reference) and how fast it may start are capped, so a corrupt estimate or
//! reference cannot fling the stop.

use nalgebra::Vector3;

use super::motion::Motion;
use super::settings::{at_most, PickSettings};
use crate::planning::{within_reach, InterceptPlan, PlanError, TaskState};
use crate::robot::Puma560;

/// Where the arm is as the encoders measure it, and how hard the last
/// reference drove the joints.
pub(super) struct Measured {
    /// The flange's position through the joint encoders, base frame.
    pub flange: Vector3<f32>,
    /// The flange's yaw through the joint encoders.
    pub yaw: f32,
    /// The worst reference joint speed over its limit at the last period.
    pub reference_speed_ratio: f32,
}

/// Where a controlled stop starts: `reference`, unless the arm is not
/// following it (then where the arm is), with its speeds capped to what
/// the pick ever commands.
pub(super) fn stop_start(
    reference: &TaskState<f32>,
    measured: &Measured,
    settings: &PickSettings,
) -> TaskState<f32> {
    let mut start = *reference;
    let lag = (start.position - measured.flange).norm();
    if !at_most(lag, settings.tracking_error_limit_m) {
        start = TaskState::at_rest(measured.flange, measured.yaw);
    }
    // A reference that asked a joint for more than its limit: the stop
    // starts from a speed scaled back within the limits.
    let ratio = measured.reference_speed_ratio;
    let within = 0.9 * settings.reference_speed_factor;
    if !at_most(ratio, within) {
        let scale = if ratio.is_finite() {
            within / ratio
        } else {
            0.0
        };
        start.velocity *= scale;
        start.yaw_rate *= scale;
        start.acceleration = Vector3::zeros();
        start.yaw_acceleration = 0.0;
    }
    let speed = start.velocity.norm();
    if !at_most(speed, settings.stop_max_speed_m_s) {
        start.velocity = if speed.is_finite() {
            start.velocity * (settings.stop_max_speed_m_s / speed)
        } else {
            Vector3::zeros()
        };
    }
    if !at_most(start.yaw_rate.abs(), settings.stop_max_yaw_rate_rad_s) {
        start.yaw_rate = 0.0;
    }
    if !at_most(
        start.acceleration.norm(),
        settings.stop_max_acceleration_m_s2,
    ) {
        start.acceleration = Vector3::zeros();
    }
    if !start.yaw_acceleration.is_finite() {
        start.yaw_acceleration = 0.0;
    }
    start
}

/// To rest over `stop_s` from `start` (see [`stop_start`]), from `now_s`:
/// rising `stop_rise_m` clear of the part when `near_part`, never ending
/// lower than it starts before the calibration is accepted, and never
/// ending out of reach.
pub(super) fn stop_motion(
    start: &TaskState<f32>,
    near_part: bool,
    calibration_accepted: bool,
    model: &Puma560<f32>,
    settings: &PickSettings,
    now_s: f32,
) -> Result<Motion, PlanError> {
    let rise = if near_part { settings.stop_rise_m } else { 0.0 };
    let mut end = TaskState::at_rest(
        start.position + start.velocity * (0.5 * settings.stop_s) + Vector3::new(0.0, 0.0, rise),
        start.yaw + start.yaw_rate * (0.5 * settings.stop_s),
    );
    if !calibration_accepted && end.position.z < start.position.z {
        end.position.z = start.position.z;
    }
    if !within_reach(model, &end.position) {
        end.position = start.position;
    }
    InterceptPlan::between(start, &end, settings.stop_s, core::f32::consts::PI).map(|path| {
        Motion::Quintic {
            path,
            start_s: now_s,
        }
    })
}
