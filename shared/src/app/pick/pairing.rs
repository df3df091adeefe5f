//! The frame pairer: the quick, link-side part of vision. It keeps the encoder
//! values the control loop latched at each camera trigger and pairs every
//! arriving frame with them by trigger id, so the frame's conveyor angle is the
//! one at exposure however late the frame arrives (Eq 1's theta without the
//! vision latency), and the effector marks are placed by the joint angles at
//! exposure (Section 3.2).

use super::handoff::{DiscView, Sighting, TriggerRecord, VisionNews};
use crate::app::vision::{observation_from_frame, VisionError};
use crate::fusion::{TriggerLatch, Triggered};
use crate::observation::ObservationFrame;
use crate::protocol::{CameraFeatureFrame, CellConfig, PointLabel};
use crate::robot::Puma560;

/// Triggers awaiting their frames (frames later than 8 periods are stale).
pub const PENDING_TRIGGERS: usize = 8;

impl Triggered for TriggerRecord {
    fn trigger_id(&self) -> u32 {
        self.latched.trigger_id
    }
}

/// The disc's centre and reference mark in `frame` (the first of each label:
/// a frame with two is refused by the calibrator anyway), if it saw either.
fn disc_view(frame: &CameraFeatureFrame, theta: f64) -> Option<DiscView> {
    let find = |wanted: PointLabel| {
        frame
            .points
            .iter()
            .find(|point| point.label == wanted)
            .map(|point| [point.u_px, point.v_px])
            .filter(|[u, v]| u.is_finite() && v.is_finite())
    };
    let centre_px = find(PointLabel::DiscCenter);
    let reference_px = find(PointLabel::Reference);
    (theta.is_finite() && (centre_px.is_some() || reference_px.is_some())).then_some(DiscView {
        theta: theta as f32,
        centre_px,
        reference_px,
        part_seen: false,
    })
}

/// Pairs camera frames with their triggers.
#[derive(Debug, Clone)]
pub struct FramePairer {
    latch: TriggerLatch<PENDING_TRIGGERS, TriggerRecord>,
    kinematics: Puma560<f64>,
    conveyor_counts_per_rev: u32,
    part_feature_count: usize,
}

/// A paired frame: the news for the control loop, and the observation for the
/// worker when the frame may feed the calibrator.
#[derive(Debug, Clone, PartialEq)]
pub struct Paired {
    /// What the control loop hears of the frame.
    pub news: VisionNews,
    /// The observation for the calibrator, when the frame may feed it.
    pub observation: Option<ObservationFrame>,
}

impl FramePairer {
    /// The pairer for the cell `config`.
    pub fn for_config(config: &CellConfig) -> Self {
        Self::new(
            config.conveyor_counts_per_rev,
            usize::from(config.part_feature_count),
        )
    }

    /// A pairer for a conveyor of `conveyor_counts_per_rev` and a part of
    /// `part_feature_count` features.
    pub fn new(conveyor_counts_per_rev: u32, part_feature_count: usize) -> Self {
        let mut pairer = Self {
            latch: TriggerLatch::new(),
            kinematics: Puma560::new(),
            conveyor_counts_per_rev: 1,
            part_feature_count: 0,
        };
        pairer.set_cell(conveyor_counts_per_rev, part_feature_count);
        pairer
    }

    /// The cell's part of the pairer, the same for a new and a reconfigured one.
    fn set_cell(&mut self, conveyor_counts_per_rev: u32, part_feature_count: usize) {
        self.latch = TriggerLatch::new();
        self.conveyor_counts_per_rev = conveyor_counts_per_rev.max(1);
        self.part_feature_count = part_feature_count;
    }

    /// The pairer for a new cell `config`, in place: the same as a new
    /// [`FramePairer::for_config`] (no trigger pending), keeping the arm's
    /// kinematics, which no configuration changes. The firmware's link
    /// reconfigures this way so that the kinematics (2.3 KB, and the 2.7 KB
    /// frame that builds them) are not on its stack again.
    pub fn reconfigure(&mut self, config: &CellConfig) {
        self.set_cell(
            config.conveyor_counts_per_rev,
            usize::from(config.part_feature_count),
        );
    }

    /// The control loop fired the camera: remember the encoders.
    pub fn on_trigger(&mut self, record: &TriggerRecord) {
        self.latch.latch(*record);
    }

    /// A camera frame arrived: pair it, and build its observation. A frame
    /// that pairs but carries bad labels (twice the same, out of range) is
    /// refused: news `Refused`, no observation. The error is an unknown trigger.
    pub fn on_frame(&mut self, frame: &CameraFeatureFrame) -> Result<Paired, VisionError> {
        let trigger_id = frame.trigger_id;
        let Some(record) = self.latch.take(trigger_id) else {
            return Err(VisionError::UnknownTrigger { trigger_id });
        };
        let latched = record.latched;
        let theta = latched.conveyor_counts as f64 * core::f64::consts::TAU
            / f64::from(self.conveyor_counts_per_rev);
        let view = disc_view(frame, theta);
        if !record.feeds_calibrator {
            return Ok(Paired {
                news: VisionNews::Paired {
                    sighting: None,
                    view,
                },
                observation: None,
            });
        }
        let t_s = latched.time_us.saturating_sub(record.start_time_us) as f64 * 1e-6;
        let observation = observation_from_frame(
            frame,
            &latched,
            t_s,
            theta,
            self.part_feature_count,
            &self.kinematics,
        );
        let observation = match observation {
            Ok(observation) => observation,
            Err(_) => {
                return Ok(Paired {
                    news: VisionNews::Refused,
                    observation: None,
                })
            }
        };
        let sighting = observation.effector.and_then(|e| {
            let [[x0, y0, z], [x1, y1, _]] = e.base_m;
            // The marks sit either side of the flange's axis: their
            // midpoint is the flange's.
            let (xf, yf) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
            let (norm, norm_flange) = (libm::hypot(x0, y0), libm::hypot(xf, yf));
            (norm > 1e-6 && norm_flange > 1e-6).then(|| Sighting {
                direction_xy: [(x0 / norm) as f32, (y0 / norm) as f32],
                flange_direction_xy: [(xf / norm_flange) as f32, (yf / norm_flange) as f32],
                mark_z_m: z as f32,
            })
        });
        let view = view.map(|view| DiscView {
            part_seen: observation.part_px.is_some(),
            ..view
        });
        Ok(Paired {
            news: VisionNews::Paired { sighting, view },
            observation: Some(observation),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(conveyor_counts_per_rev: u32, part_feature_count: u8) -> CellConfig {
        crate::test_cell::test_cell_config(conveyor_counts_per_rev, part_feature_count)
    }

    #[test]
    fn a_reconfigured_pairer_is_a_new_one() {
        let mut pairer = FramePairer::for_config(&config(4096, 4));
        pairer.on_trigger(&TriggerRecord {
            latched: crate::fusion::LatchedSample {
                trigger_id: 7,
                conveyor_counts: 100,
                time_us: 1_000,
                joint_q: [0.0; 6],
            },
            start_time_us: 0,
            feeds_calibrator: true,
        });
        // Counts per revolution 0 is taken as 1, as for a new pairer.
        let next = config(0, 2);
        pairer.reconfigure(&next);
        assert_eq!(
            format!("{pairer:?}"),
            format!("{:?}", FramePairer::for_config(&next))
        );
    }
}
