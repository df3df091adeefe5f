//! The pick's telemetry: one [`PickTelemetry`] every `telemetry_period_ticks`
//! periods, built from what the period measured and decided. Frames follow
//! the contract: the part and the tool in the base frame, the conveyor's
//! angle as the filter has it (Eq 1's theta).

use nalgebra::Vector3;

use super::estimate::CellEstimate;
use super::PickCounters;
use crate::angle::wrap_pi;
use crate::app::tool::TOOL_LENGTH_M;
use crate::fusion::ConveyorState;
use crate::planning::TaskState;
use crate::protocol::{FaultCause, PickPhase, PickTelemetry};

/// Whether the `ticks`-th period (from 1) reports: the first, and every
/// `period_ticks` after it; never when the period is 0.
pub(super) fn due(ticks: u64, period_ticks: u16) -> bool {
    let period = u64::from(period_ticks);
    period != 0 && (ticks - 1).is_multiple_of(period)
}

/// What one telemetry message reports.
pub(super) struct TelemetryInputs<'a> {
    /// The sample's time, microseconds.
    pub time_us: u64,
    /// The reported phase and the fault, if any.
    pub phase: PickPhase,
    /// The fault being reported, if any.
    pub fault: Option<FaultCause>,
    /// The conveyor filter's state, once it has one.
    pub conveyor: Option<ConveyorState<f32>>,
    /// The grasp point's live state in the base frame, once calibrated.
    pub part: Option<&'a TaskState<f32>>,
    /// The estimate in use, if any.
    pub estimate: Option<&'a CellEstimate>,
    /// The tool point measured through the joint encoders, base frame.
    pub tool_measured: &'a Vector3<f32>,
    /// The flange's yaw measured through the joint encoders.
    pub tool_yaw_measured: f32,
    /// The flange reference (Eq 23's `Y^d`).
    pub reference: &'a TaskState<f32>,
    /// The controller's counters.
    pub counters: &'a PickCounters,
    /// Frames the link's decoder refused.
    pub link_frames_rejected: u32,
}

impl TelemetryInputs<'_> {
    /// The message.
    pub(super) fn message(&self) -> PickTelemetry {
        let state = self.conveyor;
        let part = self.part;
        let tool_reference = self.reference.position - Vector3::new(0.0, 0.0, TOOL_LENGTH_M as f32);
        PickTelemetry {
            time_us: self.time_us,
            phase: self.phase,
            fault: self.fault,
            theta_rad: state.map_or(0.0, |s| s.theta_wrapped),
            omega_rad_s: state.map_or(0.0, |s| s.omega),
            sigma_theta_rad: state.map_or(0.0, |s| s.sigma_theta()),
            sigma_omega_rad_s: state.map_or(0.0, |s| s.sigma_omega()),
            part_base_m: part.map(|p| [p.position.x, p.position.y, p.position.z]),
            part_yaw_base_rad: part.map_or(0.0, |p| p.yaw),
            part_velocity_base_m_s: part
                .map_or([0.0; 3], |p| [p.velocity.x, p.velocity.y, p.velocity.z]),
            part_sigma_m: self.estimate.map_or(0.0, |e| {
                libm::hypotf(
                    e.report.sigma_grasp_horizontal_m,
                    e.report.sigma_grasp_vertical_m,
                )
            }),
            tool_base_m: [
                self.tool_measured.x,
                self.tool_measured.y,
                self.tool_measured.z,
            ],
            tool_reference_base_m: [tool_reference.x, tool_reference.y, tool_reference.z],
            tool_yaw_rad: self.tool_yaw_measured,
            tool_reference_yaw_rad: wrap_pi(self.reference.yaw),
            frames_paired: self.counters.frames_paired,
            frames_unpaired: self.counters.frames_unpaired,
            saturated_ticks: self.counters.saturated_ticks,
            frames_rejected: self.link_frames_rejected,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::due;

    #[test]
    fn telemetry_is_due_on_the_first_period_and_every_period_after() {
        let reported: Vec<u64> = (1..=10).filter(|&tick| due(tick, 4)).collect();
        assert_eq!(reported, [1, 5, 9]);
        assert!((1..=10).all(|tick| due(tick, 1)));
        assert!(!(1..=10).any(|tick| due(tick, 0)));
    }
}
