//! Admitting what the calibrator is given: a log header and a configuration it
//! can calibrate with, and frames whose every value is finite, in range and
//! inside the image (the contract's rules, `docs/reference/frames-and-log.md`).
//! A refusal names the frame and the field, and changes nothing stored.

use super::SelfCalibrator;
use crate::calibration::config::CalibrationConfig;
use crate::calibration::error::CalibrationError;
use crate::calibration::exceeds;
use crate::calibration::records::{to_f32, FrameRecord, PixelF32};
use crate::observation::{LogHeader, ObservationFrame, PixelPoint, LOG_VERSION, MAX_PART_FEATURES};

/// Largest focal length, and inverse of the smallest, in image sides (`f_px /
/// max(width, height)`): 1e3 is a field of view of 0.06 degree, 1e-3 one of 179.9
/// degrees. Beyond either, every pixel ray is numerically the optical axis (or
/// the image plane) and Step 2's conic degenerates.
const MAX_FOCAL_IN_SIDES: f64 = 1e3;
/// How far the principal point may lie from the image centre, in image sides.
const MAX_PRINCIPAL_OFFSET_IN_SIDES: f64 = 10.0;
/// Range of the paper's L, metres. Every length the calibration estimates scales
/// with L; outside these bounds their squares in the refinement overflow or lose
/// all precision (a disc of 1e250 m would give a "singular" virtual rotation
/// rather than an error naming the header field).
const REFERENCE_RADIUS_RANGE_M: (f64, f64) = (1e-3, 1e3);
/// Largest conveyor angle accepted, radians (159,000 revolutions, 18 days at the
/// paper's 10 s a turn). Up to it an f64 angle resolves 1.2e-10 rad; at 1e300 it
/// resolves nothing, and the frame would silently join the fit with a random angle.
pub const MAX_CONVEYOR_ANGLE_RAD: f64 = 1e6;
/// Largest coordinate of an end-effector point in the base frame, metres (the
/// PUMA reaches under a metre; a point kilometres away is a unit or sensor error).
pub const MAX_EFFECTOR_COORDINATE_M: f64 = 1e3;

/// A frame that passed `validate`, its pixels already in the store's precision.
pub(super) struct ValidFrame {
    theta: f64,
    centre: Option<PixelF32>,
    reference: Option<PixelF32>,
    part: Option<[PixelF32; MAX_PART_FEATURES]>,
}

impl ValidFrame {
    pub(super) fn record(&self, part_feature_count: usize) -> FrameRecord<'_> {
        FrameRecord {
            theta: self.theta,
            centre: self.centre,
            reference: self.reference,
            part: self
                .part
                .as_ref()
                .map(|part| part.get(..part_feature_count).unwrap_or(part)),
        }
    }
}

fn finite(pixel: &PixelPoint) -> bool {
    pixel.iter().all(|v| v.is_finite())
}

/// Refuses a header no workcell fits: a focal length or principal point
/// outside the ranges above, a reference radius outside
/// [`REFERENCE_RADIUS_RANGE_M`], fewer than two part features or more than
/// the contract's maximum.
pub(super) fn check_header(header: &LogHeader) -> Result<(), CalibrationError> {
    let camera = &header.camera;
    if header.version != LOG_VERSION {
        return Err(CalibrationError::InvalidHeader { field: "version" });
    }
    let side_px = f64::from(camera.width.max(camera.height));
    let focal_in_sides = camera.f_px / side_px;
    if !(camera.f_px.is_finite()
        && camera.f_px > 0.0
        && (1.0 / MAX_FOCAL_IN_SIDES..=MAX_FOCAL_IN_SIDES).contains(&focal_in_sides))
    {
        return Err(CalibrationError::InvalidHeader {
            field: "camera.f_px",
        });
    }
    let offset_limit_px = MAX_PRINCIPAL_OFFSET_IN_SIDES * side_px;
    for (centre_px, size_px, field) in [
        (camera.cx, camera.width, "camera.cx"),
        (camera.cy, camera.height, "camera.cy"),
    ] {
        let offset_px = centre_px - 0.5 * f64::from(size_px);
        if !(offset_px.is_finite() && offset_px.abs() <= offset_limit_px) {
            return Err(CalibrationError::InvalidHeader { field });
        }
    }
    let (min_radius_m, max_radius_m) = REFERENCE_RADIUS_RANGE_M;
    if let Some(disc_radius_m) = header.disc_radius_m {
        if !(disc_radius_m.is_finite() && (min_radius_m..=max_radius_m).contains(&disc_radius_m)) {
            return Err(CalibrationError::InvalidHeader {
                field: "disc_radius_m",
            });
        }
    }
    if !(header.reference_radius_m.is_finite()
        && (min_radius_m..=max_radius_m).contains(&header.reference_radius_m))
    {
        return Err(CalibrationError::InvalidHeader {
            field: "reference_radius_m",
        });
    }
    if !(2..=MAX_PART_FEATURES).contains(&header.part_feature_count) {
        return Err(CalibrationError::InvalidHeader {
            field: "part_feature_count",
        });
    }
    Ok(())
}

/// Refuses a configuration the estimate cannot run with: non-positive
/// weights, gates and spans, no iterations, a non-finite known disc height.
pub(super) fn check_config(config: &CalibrationConfig) -> Result<(), CalibrationError> {
    let positive = |value: f64| value.is_finite() && value > 0.0;
    for (value, field) in [
        (config.pixel_sigma, "pixel_sigma"),
        (config.huber_k, "huber_k"),
        (config.outlier_gate_sigma, "outlier_gate_sigma"),
        (config.min_rotation_rad, "min_rotation_rad"),
    ] {
        if !positive(value) {
            return Err(CalibrationError::InvalidConfig { field });
        }
    }
    if config.max_iterations == 0 {
        return Err(CalibrationError::InvalidConfig {
            field: "max_iterations",
        });
    }
    if config
        .disc_height_in_base_m
        .is_some_and(|height| !height.is_finite())
    {
        return Err(CalibrationError::InvalidConfig {
            field: "disc_height_in_base_m",
        });
    }
    Ok(())
}

impl<const FRAMES: usize, const EFFECTOR_FRAMES: usize, const PIXELS_PER_FRAME: usize>
    SelfCalibrator<FRAMES, EFFECTOR_FRAMES, PIXELS_PER_FRAME>
{
    /// `frame`, the `index`-th offered, as the store keeps it; or why it is refused.
    pub(super) fn validate(
        &self,
        index: u32,
        frame: &ObservationFrame,
    ) -> Result<ValidFrame, CalibrationError> {
        let non_finite = |field| CalibrationError::NonFiniteValue {
            frame: index,
            field,
        };
        if !frame.t_s.is_finite() {
            return Err(non_finite("t_s"));
        }
        if !frame.conveyor_angle_rad.is_finite() {
            return Err(non_finite("conveyor_angle_rad"));
        }
        if frame.conveyor_angle_rad.abs() > MAX_CONVEYOR_ANGLE_RAD {
            return Err(CalibrationError::ValueOutOfRange {
                frame: index,
                field: "conveyor_angle_rad",
                limit: MAX_CONVEYOR_ANGLE_RAD,
            });
        }
        if let Some(previous) = self.last_t_s {
            if frame.t_s < previous {
                return Err(CalibrationError::TimeWentBackwards {
                    frame: index,
                    t_s: frame.t_s,
                    previous_t_s: previous,
                });
            }
        }
        // Finite and inside the image (the contract's detection rule): a point far
        // outside would poison the conic's scatter matrix for the rest of the run.
        let camera = self.header.camera;
        let check = |p: &PixelPoint, field| -> Result<(), CalibrationError> {
            if !finite(p) {
                Err(non_finite(field))
            } else if !camera.contains(*p) {
                Err(CalibrationError::OutsideImage {
                    frame: index,
                    field,
                })
            } else {
                Ok(())
            }
        };
        if let Some(p) = &frame.center_px {
            check(p, "center_px")?;
        }
        if let Some(p) = &frame.reference_px {
            check(p, "reference_px")?;
        }
        let part = match &frame.part_px {
            None => None,
            Some(points) => {
                if points.len() != self.header.part_feature_count {
                    return Err(CalibrationError::WrongFeatureCount {
                        frame: index,
                        expected: self.header.part_feature_count,
                        found: points.len(),
                    });
                }
                let mut stored: [PixelF32; MAX_PART_FEATURES] = [[0.0; 2]; MAX_PART_FEATURES];
                for (slot, point) in stored.iter_mut().zip(points.iter()) {
                    check(point, "part_px")?;
                    *slot = to_f32(*point);
                }
                Some(stored)
            }
        };
        if let Some(sighting) = &frame.effector {
            for p in &sighting.px {
                check(p, "effector_px")?;
            }
            if !sighting.base_m.iter().flatten().all(|v| v.is_finite()) {
                return Err(non_finite("effector_base_m"));
            }
            if sighting
                .base_m
                .iter()
                .flatten()
                .any(|v| v.abs() > MAX_EFFECTOR_COORDINATE_M)
            {
                return Err(CalibrationError::ValueOutOfRange {
                    frame: index,
                    field: "effector_base_m",
                    limit: MAX_EFFECTOR_COORDINATE_M,
                });
            }
            let [b0, b1] = sighting.base_m;
            let distance_squared: f64 = b0
                .iter()
                .zip(b1.iter())
                .map(|(a, b)| (a - b) * (a - b))
                .sum();
            if !exceeds(distance_squared, 1e-12) {
                return Err(CalibrationError::CoincidingEffectorPoints { frame: index });
            }
        }
        if let Some(rim) = &frame.rim {
            let numbers = rim
                .centre_px
                .iter()
                .chain(&rim.semi_axes_px)
                .chain([&rim.angle_rad, &rim.sigma_px]);
            if !numbers.into_iter().all(|v| v.is_finite()) {
                return Err(non_finite("rim"));
            }
            if !(rim.semi_axes_px.iter().all(|&a| a > 0.0) && rim.sigma_px > 0.0) {
                return Err(CalibrationError::ValueOutOfRange {
                    frame: index,
                    field: "rim",
                    limit: 0.0,
                });
            }
        }
        Ok(ValidFrame {
            theta: frame.conveyor_angle_rad,
            centre: frame.center_px.map(to_f32),
            reference: frame.reference_px.map(to_f32),
            part,
        })
    }
}
