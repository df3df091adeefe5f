//! Every image point of a log as one observation of the batch solve: no
//! thinning, no store, every frame and every end-effector sighting, pixels in
//! full f64 precision.

use nalgebra::{Vector2, Vector3};

use super::BatchError;
use crate::log::ObservationLog;

/// What an image point is the image of.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Target {
    /// A mark at known disc-frame coordinates: the disc centre at the origin, the
    /// reference point at `(L cos theta, L sin theta, 0)`.
    KnownDisc(Vector3<f64>),
    /// Feature `index` of the part, seen at conveyor angle `theta_rad` (Eq 1).
    Feature { index: usize, theta_rad: f64 },
    /// An end-effector point at known base-frame coordinates (Eq 9).
    Effector(Vector3<f64>),
}

/// One measured pixel, what it shows and the frame (index in the log) it came from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    pub pixel: Vector2<f64>,
    pub target: Target,
    pub frame: usize,
}

fn pixel(p: [f64; 2]) -> Vector2<f64> {
    Vector2::new(p[0], p[1])
}

/// Flattens `log` into observations, frame by frame. A part detection with a
/// feature count other than the header's is refused (the reader already
/// refuses it in a file; this guards logs built in memory).
pub fn observations_of(log: &ObservationLog) -> Result<Vec<Observation>, BatchError> {
    let header = &log.header;
    let radius_m = header.reference_radius_m;
    let mut observations = Vec::with_capacity(log.frames.len() * (2 + header.part_feature_count));
    for (frame, record) in log.frames.iter().enumerate() {
        let theta_rad = record.conveyor_angle_rad;
        if let Some(centre) = record.center_px {
            observations.push(Observation {
                pixel: pixel(centre),
                target: Target::KnownDisc(Vector3::zeros()),
                frame,
            });
        }
        if let Some(reference) = record.reference_px {
            let (sin, cos) = theta_rad.sin_cos();
            observations.push(Observation {
                pixel: pixel(reference),
                target: Target::KnownDisc(Vector3::new(radius_m * cos, radius_m * sin, 0.0)),
                frame,
            });
        }
        if let Some(part) = &record.part_px {
            if part.len() != header.part_feature_count {
                return Err(BatchError::FeatureCount {
                    frame,
                    expected: header.part_feature_count,
                    found: part.len(),
                });
            }
            observations.extend(part.iter().enumerate().map(|(index, p)| Observation {
                pixel: pixel(*p),
                target: Target::Feature { index, theta_rad },
                frame,
            }));
        }
        if let Some(sighting) = &record.effector {
            observations.extend(
                sighting
                    .px
                    .iter()
                    .zip(sighting.base_m.iter())
                    .map(|(p, base)| Observation {
                        pixel: pixel(*p),
                        target: Target::Effector(Vector3::new(base[0], base[1], base[2])),
                        frame,
                    }),
            );
        }
    }
    Ok(observations)
}
