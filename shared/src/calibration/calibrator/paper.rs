//! The paper's own closed-form estimate, for comparison with the refined one:
//! the virtual rotation from the robust conic and centre (Steps 1 to 4), Eq 8
//! with two frames and Eq 15 with one robot pose, as in Sections 2 and 3.

use nalgebra::{Vector2, Vector3};

use super::initial::SightingPoints;
use super::SelfCalibrator;
use crate::calibration::effector::BaseFromDiscFit;
use crate::calibration::error::CalibrationError;
use crate::calibration::model::WorkcellModel;
use crate::calibration::part::{intersect_two_lines, VirtualGeometry};
use crate::calibration::records::FrameRecord;
use crate::calibration::refine::measured_sigma;
use crate::calibration::virtual_rotation::{disc_from_virtual, VirtualRotation};
use crate::observation::{CalibrationResult, MAX_PART_FEATURES};

impl<const FRAMES: usize, const EFFECTOR_FRAMES: usize, const PIXELS_PER_FRAME: usize>
    SelfCalibrator<FRAMES, EFFECTOR_FRAMES, PIXELS_PER_FRAME>
{
    /// The paper's own method for comparison: the virtual rotation from the RLS conic and the
    /// mean centre image (both with gross outliers gated out), Eq 8 with two frames, Eq 15
    /// with one robot pose.
    pub fn paper_estimate(&self) -> Result<CalibrationResult, CalibrationError> {
        self.check_reference_count()?;
        self.check_rotation_span()?;
        self.check_reference_spread()?;
        // The RLS conic and mean centre image, with gross outliers gated out first (the
        // paper's data had none; without the gate one stray detection can spoil Step 2).
        let conic = self.robust_conic()?;
        let centre = self.robust_centre_ray()?;
        let rotation = VirtualRotation::from_conic(&conic, centre, self.header.reference_radius_m)?;
        let gamma = self.disc_axis_angle(&rotation, true)?;
        let geometry = VirtualGeometry { rotation, gamma };
        let (disc_from_camera, camera_centre_disc) = disc_from_virtual(&rotation, gamma);
        // Eq 8 with two frames: the first showing the part and the one turned furthest from it.
        let mut part_frames = self.frames.view().iter().filter(|f| f.part.is_some());
        let first = part_frames
            .next()
            .ok_or(CalibrationError::TooFewObservations {
                what: "frames showing the part",
                needed: 2,
                found: 0,
            })?;
        let second = part_frames
            .max_by(|a, b| {
                let spread = |f: &FrameRecord| 1.0 - libm::cos(f.theta - first.theta);
                spread(a).total_cmp(&spread(b))
            })
            .ok_or(CalibrationError::TooFewObservations {
                what: "frames showing the part",
                needed: 2,
                found: 1,
            })?;
        let mut features = [Vector3::zeros(); MAX_PART_FEATURES];
        for (index, slot) in features
            .iter_mut()
            .enumerate()
            .take(self.header.part_feature_count)
        {
            let line =
                |frame: &FrameRecord| -> Result<(Vector2<f64>, Vector2<f64>), CalibrationError> {
                    let pixel = frame.part.and_then(|part| part.get(index).copied()).ok_or(
                        CalibrationError::NumericalFailure {
                            stage: "part localisation",
                        },
                    )?;
                    let m = self.virtual_point(&rotation, pixel, "part_px")?;
                    Ok(geometry.affine_line(frame.theta, m))
                };
            *slot = intersect_two_lines(line(&first)?, line(&second)?)?;
        }
        // Eq 15 with one robot pose: the first sighting with a usable depth.
        let mut fit = BaseFromDiscFit::default();
        let mut first_invalid = None;
        for (position, sighting) in self.effectors.items().iter().enumerate() {
            match self.sighting_disc_points(&geometry, sighting)? {
                SightingPoints::Resolved(pair) => {
                    for (p_disc, which) in pair.iter().zip(0..2) {
                        fit.add(*p_disc, sighting.base_point(which));
                    }
                    break;
                }
                SightingPoints::Ambiguous(_) | SightingPoints::Invalid => {
                    first_invalid.get_or_insert(position);
                }
            }
        }
        if fit.count() == 0 {
            return Err(self.no_effector_error(first_invalid));
        }
        let (base_yaw, base_translation) = fit.solve(self.config.disc_height_in_base_m)?;
        let model = WorkcellModel {
            disc_from_camera,
            camera_centre_disc,
            features_rotating: features,
            feature_count: self.header.part_feature_count,
            base_yaw,
            base_translation,
        };
        let rms = self.rms_reprojection(&model);
        let sigma = measured_sigma(&self.problem(), &model, self.config.pixel_sigma);
        Ok(self.result(&model, rms, 0, sigma))
    }
}
