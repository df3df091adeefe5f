//! The refinement's starting point: the camera pose from the disc-plane
//! homography (or the paper's virtual rotation when it cannot be had), Eq 8
//! over every frame for the part's features, and Eqs 10 to 15 over every
//! sighting for `base_from_disc`.

use nalgebra::{Vector2, Vector3};

use super::{BaseUnplaced, SelfCalibrator};
use crate::calibration::effector::{depth_roots, BaseFromDiscFit, DepthRoots};
use crate::calibration::error::CalibrationError;
use crate::calibration::homography::{pose_from_plane, PlanePoint, PlanePose};
use crate::calibration::model::{rotation_z, WorkcellModel};
use crate::calibration::part::{line_miss_squared, FeatureSystem, VirtualGeometry};
use crate::calibration::records::{to_f32, to_vector, EffectorRecord};
use crate::calibration::virtual_rotation::{disc_from_virtual, VirtualRotation};
use crate::observation::MAX_PART_FEATURES;

/// A sighting's two points in the disc frame, as far as Eq 10 decides them.
pub(super) enum SightingPoints {
    Resolved([Vector3<f64>; 2]),
    /// Two physically valid roots of Eq 10: both candidate pairs.
    Ambiguous([[Vector3<f64>; 2]; 2]),
    Invalid,
}

impl<const FRAMES: usize, const EFFECTOR_FRAMES: usize, const PIXELS_PER_FRAME: usize>
    SelfCalibrator<FRAMES, EFFECTOR_FRAMES, PIXELS_PER_FRAME>
{
    pub(super) fn no_effector_error(&self, first_invalid: Option<usize>) -> CalibrationError {
        match first_invalid {
            Some(position) => CalibrationError::NoValidDepthRoot {
                frame: u32::try_from(position).unwrap_or(u32::MAX),
            },
            None => CalibrationError::TooFewObservations {
                what: "end-effector sightings",
                needed: 1,
                found: 0,
            },
        }
    }

    /// Disc-frame positions of a sighting's two points (Eq 10, or the known disc height).
    pub(super) fn sighting_disc_points(
        &self,
        geometry: &VirtualGeometry,
        sighting: &EffectorRecord,
    ) -> Result<SightingPoints, CalibrationError> {
        let rotation = &geometry.rotation;
        // A mark shown level with or above the camera has no depth on the disc side:
        // that sighting is unusable, not the whole calibration.
        let virtual_mark = |which: usize| {
            let pixel = sighting.pixel(which);
            self.virtual_point(rotation, to_f32([pixel.x, pixel.y]), "effector_px")
        };
        let (Ok(m0), Ok(m1)) = (virtual_mark(0), virtual_mark(1)) else {
            return Ok(SightingPoints::Invalid);
        };
        let (b0, b1) = (sighting.base_point(0), sighting.base_point(1));
        let pair =
            |(z0, z1): (f64, f64)| [geometry.disc_point(m0, z0), geometry.disc_point(m1, z1)];
        Ok(match self.config.disc_height_in_base_m {
            // Experiment 2: heights above the disc are known, so depths are H - h directly.
            Some(disc_height) => SightingPoints::Resolved(pair((
                rotation.height_m - (b0.z - disc_height),
                rotation.height_m - (b1.z - disc_height),
            ))),
            None => match depth_roots(m0, m1, b1.z - b0.z, (b1 - b0).norm()) {
                DepthRoots::Unique(z0, z1) => SightingPoints::Resolved(pair((z0, z1))),
                DepthRoots::Ambiguous([first, second]) => {
                    SightingPoints::Ambiguous([pair(first), pair(second)])
                }
                DepthRoots::None => SightingPoints::Invalid,
            },
        })
    }

    /// The starting point of the refinement: robust virtual rotation, all-frame Eq 8 and
    /// all-sighting Eq 15.
    // Never inlined: its working set (homography, conic, Eqs 3 to 15) is not
    // on the stack while the bundle adjustment runs (firmware stack budget).
    #[inline(never)]
    pub(super) fn initial_model(
        &self,
        unplaced: BaseUnplaced,
    ) -> Result<WorkcellModel, CalibrationError> {
        self.check_reference_count()?;
        self.check_rotation_span()?;
        self.check_reference_spread()?;
        let geometry = match self.plane_pose() {
            Ok(pose) => VirtualGeometry {
                rotation: VirtualRotation::from_pose(
                    &pose.disc_from_camera,
                    &pose.camera_centre_disc,
                    self.header.reference_radius_m,
                )?,
                gamma: 0.0,
            },
            Err(CalibrationError::CameraBelowDisc) => {
                return Err(CalibrationError::CameraBelowDisc)
            }
            // The homography could not be had: the paper's virtual rotation, whose errors
            // (degenerate or non-elliptic conic, ...) then say what is wrong with the data.
            Err(_) => {
                let conic = self.robust_conic()?;
                let centre = self.robust_centre_ray()?;
                let rotation =
                    VirtualRotation::from_conic(&conic, centre, self.header.reference_radius_m)?;
                let gamma = self.disc_axis_angle(&rotation, false)?;
                VirtualGeometry { rotation, gamma }
            }
        };
        let (disc_from_camera, camera_centre_disc) =
            disc_from_virtual(&geometry.rotation, geometry.gamma);
        let features = self.locate_features(&geometry)?;
        // Without a sighting, stored or folded, nothing places the base: the
        // refinement holds it, so any start will do.
        let unplaced_held = unplaced == BaseUnplaced::HoldIt && !self.base_observed();
        let (base_yaw, base_translation) = if unplaced_held {
            (0.0, Vector3::zeros())
        } else {
            self.locate_base(&geometry)?
        };
        Ok(WorkcellModel {
            disc_from_camera,
            camera_centre_disc,
            features_rotating: features,
            feature_count: self.header.part_feature_count,
            base_yaw,
            base_translation,
        })
    }

    /// Camera pose from the disc-plane homography of the centre and reference detections.
    pub(super) fn plane_pose(&self) -> Result<PlanePose, CalibrationError> {
        let radius = self.header.reference_radius_m;
        let pinhole = self.pinhole;
        let points = || {
            self.frames.view().iter().flat_map(move |frame| {
                let (s, c) = libm::sincos(frame.theta);
                let centre = frame.centre.map(|px| PlanePoint {
                    disc_xy: Vector2::zeros(),
                    ray: pinhole.ray(to_vector(px)),
                });
                let reference = frame.reference.map(|px| PlanePoint {
                    disc_xy: Vector2::new(radius * c, radius * s),
                    ray: pinhole.ray(to_vector(px)),
                });
                centre.into_iter().chain(reference)
            })
        };
        pose_from_plane(points, self.pinhole.f_px, 4.0 * self.config.pixel_sigma)
    }

    /// Eq 8 over all frames for every feature, twice: the second pass drops frames whose
    /// line misses the first solution by more than 4 times the RMS miss (gross outliers).
    /// All features in each pass over the frames: a frame's map to the rotating
    /// frame is computed once for them all.
    pub(super) fn locate_features(
        &self,
        geometry: &VirtualGeometry,
    ) -> Result<[Vector3<f64>; MAX_PART_FEATURES], CalibrationError> {
        let count = self.header.part_feature_count.min(MAX_PART_FEATURES);
        let reflection = geometry.reflection();
        // Calls `visit(feature, line)` for every frame's line of every feature.
        let each_line = |visit: &mut dyn FnMut(usize, (Vector2<f64>, Vector2<f64>))| {
            for frame in self.frames.view().iter() {
                let Some(part) = frame.part else {
                    continue;
                };
                let map = VirtualGeometry::rotating_map(&reflection, frame.theta);
                for (index, pixel) in part.iter().take(count).enumerate() {
                    if let Ok(m) = self.virtual_point(&geometry.rotation, *pixel, "part_px") {
                        visit(index, geometry.affine_line_through(&map, m));
                    }
                }
            }
        };
        let mut systems = [FeatureSystem::default(); MAX_PART_FEATURES];
        each_line(&mut |index, line| {
            if let Some(system) = systems.get_mut(index) {
                system.add(line, 1.0);
            }
        });
        let mut features = [Vector3::zeros(); MAX_PART_FEATURES];
        for (feature, system) in features.iter_mut().zip(&systems).take(count) {
            *feature = system.solve()?;
        }
        // A feature whose gated system cannot be solved, or is the system it
        // was solved from (the same lines, to the last bit), keeps its point.
        let mut settled = [false; MAX_PART_FEATURES];
        for _ in 0..2 {
            if settled.iter().take(count).all(|settled| *settled) {
                break;
            }
            let mut misses = [(0.0f64, 0u32); MAX_PART_FEATURES];
            each_line(&mut |index, line| {
                if let (Some(point), Some((squares, lines))) =
                    (features.get(index), misses.get_mut(index))
                {
                    *squares += line_miss_squared(point, line);
                    *lines += 1;
                }
            });
            // 4 RMS misses, squared.
            let gates = misses.map(|(squares, lines)| 16.0 * squares / f64::from(lines.max(1)));
            let mut gated = [FeatureSystem::default(); MAX_PART_FEATURES];
            each_line(&mut |index, line| {
                if let (Some(point), Some(gate), Some(system)) =
                    (features.get(index), gates.get(index), gated.get_mut(index))
                {
                    if line_miss_squared(point, line) <= *gate {
                        system.add(line, 1.0);
                    }
                }
            });
            for (((feature, system), solved_from), settled) in features
                .iter_mut()
                .zip(&gated)
                .zip(systems.iter_mut())
                .zip(settled.iter_mut())
                .take(count)
            {
                if *settled {
                    continue;
                }
                if system == solved_from {
                    *settled = true;
                    continue;
                }
                match system.solve() {
                    Ok(next) => {
                        *feature = next;
                        *solved_from = *system;
                    }
                    Err(_) => *settled = true,
                }
            }
        }
        Ok(features)
    }

    /// Eq 15 over every sighting with a usable depth, least squares (see [`BaseFromDiscFit`]).
    /// Sightings with two valid roots of Eq 10 join in a second pass, with the root whose
    /// points agree better with the first pass's `base_from_disc`.
    pub(super) fn locate_base(
        &self,
        geometry: &VirtualGeometry,
    ) -> Result<(f64, Vector3<f64>), CalibrationError> {
        let known_height = self.config.disc_height_in_base_m;
        let mut fit = BaseFromDiscFit::default();
        let mut first_invalid = None;
        for (position, sighting) in self.effectors.items().iter().enumerate() {
            match self.sighting_disc_points(geometry, sighting)? {
                SightingPoints::Resolved(pair) => {
                    for (p_disc, which) in pair.iter().zip(0..2) {
                        fit.add(*p_disc, sighting.base_point(which));
                    }
                }
                SightingPoints::Ambiguous(_) | SightingPoints::Invalid => {
                    first_invalid.get_or_insert(position);
                }
            }
        }
        if fit.count() == 0 {
            return Err(self.no_effector_error(first_invalid));
        }
        let (yaw, translation) = fit.solve(known_height)?;
        let disc_from_base = |p_base: Vector3<f64>| rotation_z(-yaw) * (p_base - translation);
        let mut resolved_more = false;
        for sighting in self.effectors.items() {
            if let SightingPoints::Ambiguous(candidates) =
                self.sighting_disc_points(geometry, sighting)?
            {
                let miss = |pair: &[Vector3<f64>; 2]| -> f64 {
                    pair.iter()
                        .zip(0..2)
                        .map(|(p_disc, which)| {
                            (p_disc - disc_from_base(sighting.base_point(which))).norm()
                        })
                        .sum()
                };
                let [first, second] = candidates;
                let best = if miss(&first) <= miss(&second) {
                    first
                } else {
                    second
                };
                for (p_disc, which) in best.iter().zip(0..2) {
                    fit.add(*p_disc, sighting.base_point(which));
                }
                resolved_more = true;
            }
        }
        if resolved_more {
            fit.solve(known_height)
        } else {
            Ok((yaw, translation))
        }
    }
}
