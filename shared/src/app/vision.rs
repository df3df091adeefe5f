//! From a camera feature frame and the encoder values latched at its trigger to
//! one observation of the contract (`docs/reference/frames-and-log.md`), ready for the
//! self-calibrator.
//!
//! The frame carries labelled pixels; the latch carries the conveyor count and
//! the joint angles at the instant the camera exposed, so `conveyor_angle_rad`
//! is the angle at capture however late the frame arrives, and the end
//! effector's marks are placed in the base frame by the kinematics of the joint
//! angles at capture (the paper's Section 3.2: "known from the robot's encoders").

use heapless::Vec;

use super::tool::effector_marks_base;
use crate::fusion::LatchedSample;
use crate::observation::{
    EffectorSighting, ObservationFrame, PixelPoint, RimObservation, MAX_PART_FEATURES,
};
use crate::protocol::{CameraFeatureFrame, PointLabel};
use crate::robot::{JointVector, Puma560};

/// Why a camera frame could not become an observation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VisionError {
    /// The frame's trigger id matches no pending trigger (unknown, stale or repeated).
    UnknownTrigger {
        /// The frame's trigger id.
        trigger_id: u32,
    },
    /// A label appears twice in one frame.
    DuplicateLabel {
        /// The frame's trigger id.
        trigger_id: u32,
        /// The repeated label.
        label: PointLabel,
    },
    /// A part feature or effector mark index beyond the configured count.
    LabelOutOfRange {
        /// The frame's trigger id.
        trigger_id: u32,
        /// The label out of range.
        label: PointLabel,
    },
}

impl core::fmt::Display for VisionError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::UnknownTrigger { trigger_id } => {
                write!(
                    f,
                    "camera frame {trigger_id}: no pending trigger with this id"
                )
            }
            Self::DuplicateLabel { trigger_id, label } => {
                write!(
                    f,
                    "camera frame {trigger_id}: label {label:?} appears twice"
                )
            }
            Self::LabelOutOfRange { trigger_id, label } => {
                write!(f, "camera frame {trigger_id}: label {label:?} out of range")
            }
        }
    }
}

impl core::error::Error for VisionError {}

/// The frame's points sorted by what they are.
#[derive(Debug, Default)]
struct Sorted {
    centre: Option<PixelPoint>,
    reference: Option<PixelPoint>,
    part: [Option<PixelPoint>; MAX_PART_FEATURES],
    effector: [Option<PixelPoint>; 2],
}

fn put(
    slot: Option<&mut Option<PixelPoint>>,
    pixel: PixelPoint,
    trigger_id: u32,
    label: PointLabel,
) -> Result<(), VisionError> {
    match slot {
        None => Err(VisionError::LabelOutOfRange { trigger_id, label }),
        Some(Some(_)) => Err(VisionError::DuplicateLabel { trigger_id, label }),
        Some(slot) => {
            *slot = Some(pixel);
            Ok(())
        }
    }
}

/// The observation for `frame`, captured when `latched` was latched, at
/// `t_s` seconds and conveyor angle `theta_rad` (unwrapped). Points outside the
/// image or not finite are left for the calibrator to refuse with its typed error.
pub fn observation_from_frame(
    frame: &CameraFeatureFrame,
    latched: &LatchedSample,
    t_s: f64,
    theta_rad: f64,
    part_feature_count: usize,
    robot: &Puma560<f64>,
) -> Result<ObservationFrame, VisionError> {
    let trigger_id = frame.trigger_id;
    let mut sorted = Sorted::default();
    for point in &frame.points {
        let pixel = [f64::from(point.u_px), f64::from(point.v_px)];
        let slot = match point.label {
            PointLabel::DiscCenter => Some(&mut sorted.centre),
            PointLabel::Reference => Some(&mut sorted.reference),
            PointLabel::Part(i) => {
                let i = usize::from(i);
                if i < part_feature_count {
                    sorted.part.get_mut(i)
                } else {
                    None
                }
            }
            PointLabel::Effector(i) => sorted.effector.get_mut(usize::from(i)),
        };
        put(slot, pixel, trigger_id, point.label)?;
    }
    // The contract: every feature of the part, or none.
    let mut part: Vec<PixelPoint, MAX_PART_FEATURES> = Vec::new();
    for pixel in sorted.part.iter().take(part_feature_count) {
        match pixel {
            Some(p) if part.push(*p).is_ok() => {}
            _ => {
                part.clear();
                break;
            }
        }
    }
    let effector = match sorted.effector {
        [Some(first), Some(second)] => {
            let q = JointVector::from_fn(|i, _| {
                f64::from(latched.joint_q.get(i).copied().unwrap_or(f32::NAN))
            });
            let marks = effector_marks_base(&robot.forward_kinematics(&q));
            let [a, b] = marks.map(|m| [m.x, m.y, m.z]);
            Some(EffectorSighting {
                px: [first, second],
                base_m: [a, b],
            })
        }
        _ => None,
    };
    Ok(ObservationFrame {
        t_s,
        conveyor_angle_rad: theta_rad,
        center_px: sorted.centre,
        reference_px: sorted.reference,
        part_px: (!part.is_empty()).then_some(part),
        effector,
        rim: frame.rim.map(|rim| RimObservation {
            centre_px: rim.centre_px.map(f64::from),
            semi_axes_px: rim.semi_axes_px.map(f64::from),
            angle_rad: f64::from(rim.angle_rad),
            sigma_px: f64::from(rim.sigma_px),
        }),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::LabeledPoint;

    fn latched() -> LatchedSample {
        LatchedSample {
            trigger_id: 4,
            conveyor_counts: 100,
            time_us: 0,
            joint_q: [0.0, 0.7, -2.9, 0.0, -0.6, 0.0],
        }
    }

    fn frame(points: &[(PointLabel, f32, f32)]) -> CameraFeatureFrame {
        let mut out = CameraFeatureFrame {
            trigger_id: 4,
            capture_time_us: 0,
            points: Vec::new(),
            rim: None,
        };
        for &(label, u_px, v_px) in points {
            out.points.push(LabeledPoint { label, u_px, v_px }).unwrap();
        }
        out
    }

    #[test]
    fn sorts_labels_and_places_the_marks_by_the_latched_joint_angles() {
        let robot = Puma560::<f64>::new();
        let f = frame(&[
            (PointLabel::Part(1), 11.0, 12.0),
            (PointLabel::Reference, 3.0, 4.0),
            (PointLabel::Effector(1), 21.0, 22.0),
            (PointLabel::Part(0), 9.0, 10.0),
            (PointLabel::Effector(0), 19.0, 20.0),
        ]);
        let obs = observation_from_frame(&f, &latched(), 1.5, 0.25, 2, &robot).unwrap();
        assert_eq!(obs.center_px, None);
        assert_eq!(obs.reference_px, Some([3.0, 4.0]));
        assert_eq!(
            obs.part_px.unwrap().as_slice(),
            &[[9.0, 10.0], [11.0, 12.0]]
        );
        let sighting = obs.effector.unwrap();
        assert_eq!(sighting.px, [[19.0, 20.0], [21.0, 22.0]]);
        let q = JointVector::from_fn(|i, _| f64::from(latched().joint_q[i]));
        let marks = effector_marks_base(&robot.forward_kinematics(&q));
        assert!((marks[0].x - sighting.base_m[0][0]).abs() < 1e-12);
        assert_eq!((obs.t_s, obs.conveyor_angle_rad), (1.5, 0.25));
    }

    #[test]
    fn a_partial_part_is_not_detected_and_bad_labels_are_refused() {
        let robot = Puma560::<f64>::new();
        let partial = frame(&[
            (PointLabel::Part(0), 1.0, 1.0),
            (PointLabel::Effector(0), 2.0, 2.0),
        ]);
        let obs = observation_from_frame(&partial, &latched(), 0.0, 0.0, 3, &robot).unwrap();
        assert_eq!(obs.part_px, None);
        assert_eq!(obs.effector, None, "one mark alone is no sighting");
        let twice = frame(&[
            (PointLabel::Reference, 1.0, 1.0),
            (PointLabel::Reference, 2.0, 2.0),
        ]);
        assert!(matches!(
            observation_from_frame(&twice, &latched(), 0.0, 0.0, 3, &robot),
            Err(VisionError::DuplicateLabel { .. })
        ));
        let beyond = frame(&[(PointLabel::Part(3), 1.0, 1.0)]);
        assert!(matches!(
            observation_from_frame(&beyond, &latched(), 0.0, 0.0, 3, &robot),
            Err(VisionError::LabelOutOfRange { .. })
        ));
        let mark = frame(&[(PointLabel::Effector(2), 1.0, 1.0)]);
        assert!(matches!(
            observation_from_frame(&mark, &latched(), 0.0, 0.0, 3, &robot),
            Err(VisionError::LabelOutOfRange { .. })
        ));
    }
}
