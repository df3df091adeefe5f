//! The fixed-memory incremental self-calibrator: absorbs frames one at a time and
//! produces the paper's estimate (Section 2 and 3) or the refined maximum-likelihood one.

use super::exceeds;
use heapless::Vec as HVec;
use nalgebra::{Vector2, Vector3};

use super::config::CalibrationConfig;
use super::conic::{Conic, ConicFit};
use super::effector::{depth_roots, BaseFromDiscFit, DepthRoots};
use super::error::CalibrationError;
use super::frame_store::{FrameStore, FULL_FRAME_PIXELS};
use super::homography::{pose_from_plane, PlanePoint, PlanePose};
use super::model::{rotation_z, WorkcellModel};
use super::part::{intersect_two_lines, line_residual, FeatureSystem, VirtualGeometry};
use super::pinhole::Pinhole;
use super::records::{to_f32, to_vector, EffectorRecord, FrameRecord, PixelF32};
use super::refine::{refine, Problem};
use super::store::ThinningStore;
use super::uncertainty::EstimateUncertainty;
use super::virtual_rotation::{disc_from_virtual, VirtualRotation};
use crate::angle::wrap_pi;
use crate::observation::{
    BaseFromDisc, CalibrationQuality, CalibrationResult, CameraEstimate, LogHeader,
    ObservationFrame, PartEstimate, PixelPoint, RigidTransform, LOG_VERSION, MAX_PART_FEATURES,
};

/// Fixed-memory incremental estimator; `FRAMES` and `EFFECTOR_FRAMES` bound the stored
/// observations (evenly thinned when more arrive; see [`ThinningStore`]), and
/// `PIXELS_PER_FRAME` is the frames' pixel budget (see [`FrameStore`]: with fewer than
/// `2 + part_feature_count` pixels a frame, fewer than `FRAMES` frames fit).
///
/// Memory: `size_of` is `512 + (9 + 8 * PIXELS_PER_FRAME) * FRAMES + 40 * EFFECTOR_FRAMES`
/// bytes on x86-64 (a frame is an f64 angle, a presence byte and f32 pixels; an
/// [`EffectorRecord`] 40 B; the rest is the header, config, the 6x6 RLS conic state and
/// counters), a little less on thumbv7em where `usize` is 4 B. Measured by the tests
/// `calibrator_sizes_are_documented` and `pick_calibrator_packs_its_frames`:
/// [`FirmwareCalibrator`] 9 696 B, [`HostCalibrator`] 101 888 B, the pick's 18 176 B.
/// [`SelfCalibrator::estimate`] additionally needs stack for the refinement's
/// arrowhead normal equations (2.8 KiB of blocks, see [`super::normal_blocks`]),
/// independent of the instance size.
#[derive(Debug, Clone)]
pub struct SelfCalibrator<
    const FRAMES: usize,
    const EFFECTOR_FRAMES: usize,
    const PIXELS_PER_FRAME: usize = FULL_FRAME_PIXELS,
> {
    header: LogHeader,
    config: CalibrationConfig,
    pinhole: Pinhole,
    /// Step 2's recursive least-squares conic, fed with every reference detection.
    conic: ConicFit,
    frames: FrameStore<FRAMES, PIXELS_PER_FRAME>,
    effectors: ThinningStore<EffectorRecord, EFFECTOR_FRAMES>,
    /// Frames offered to `push` (accepted or not): numbers frames in errors.
    offered: u32,
    /// Accepted frames with at least one detection.
    frames_used: u32,
    last_t_s: Option<f64>,
}

/// A small instance: 96 frames, 16 effector sightings (9 696 B on x86-64).
pub type FirmwareCalibrator = SelfCalibrator<96, 16>;
/// The host's instance: 1024 frames, 256 effector sightings (101 888 B on x86-64).
pub type HostCalibrator = SelfCalibrator<1024, 256>;

/// A frame that passed `validate`, its pixels already in the store's precision.
struct ValidFrame {
    theta: f64,
    centre: Option<PixelF32>,
    reference: Option<PixelF32>,
    part: Option<[PixelF32; MAX_PART_FEATURES]>,
}

impl ValidFrame {
    fn record(&self, part_feature_count: usize) -> FrameRecord<'_> {
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

/// A sighting's two points in the disc frame, as far as Eq 10 decides them.
enum SightingPoints {
    Resolved([Vector3<f64>; 2]),
    /// Two physically valid roots of Eq 10: both candidate pairs.
    Ambiguous([[Vector3<f64>; 2]; 2]),
    Invalid,
}

/// Largest focal length, and inverse of the smallest, in image sides (`f_px /
/// max(width, height)`): 1e3 is a field of view of 0.06 degree, 1e-3 one of 179.9
/// degrees. Beyond either, every pixel ray is numerically the optical axis (or
/// the image plane) and Step 2's conic degenerates.
const MAX_FOCAL_IN_SIDES: f64 = 1e3;
/// How far the principal point may lie from the image centre, in image sides.
const MAX_PRINCIPAL_OFFSET_IN_SIDES: f64 = 10.0;
/// Range of the paper's L, metres. Every length the calibration estimates scales
/// with L; outside these bounds their squares in the refinement overflow or lose
/// all precision (a disc of 1e250 m gave a "singular" virtual rotation rather
/// than an error naming the header field).
const REFERENCE_RADIUS_RANGE_M: (f64, f64) = (1e-3, 1e3);
/// Smallest spread of the reference track across its principal direction, in
/// pixel sigmas: pure noise about a line gives one sigma; 2 needs an ellipse whose
/// minor semi-axis is at least 2.4 sigmas (1.2 px at the paper's 0.5 px).
const MIN_TRACK_SPREAD_IN_SIGMAS: f64 = 2.0;
/// Largest conveyor angle accepted, radians (159,000 revolutions, 18 days at the
/// paper's 10 s a turn). Up to it an f64 angle resolves 1.2e-10 rad; at 1e300 it
/// resolves nothing, and the frame would silently join the fit with a random angle.
pub const MAX_CONVEYOR_ANGLE_RAD: f64 = 1e6;
/// Largest coordinate of an end-effector point in the base frame, metres (the
/// PUMA reaches under a metre; a point kilometres away is a unit or sensor error).
pub const MAX_EFFECTOR_COORDINATE_M: f64 = 1e3;

fn finite(pixel: &PixelPoint) -> bool {
    pixel.iter().all(|v| v.is_finite())
}

impl<const FRAMES: usize, const EFFECTOR_FRAMES: usize, const PIXELS_PER_FRAME: usize>
    SelfCalibrator<FRAMES, EFFECTOR_FRAMES, PIXELS_PER_FRAME>
{
    pub fn new(header: &LogHeader, config: CalibrationConfig) -> Result<Self, CalibrationError> {
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
        Ok(Self {
            header: *header,
            config,
            pinhole: Pinhole::new(camera),
            conic: ConicFit::new(),
            frames: FrameStore::new(header.part_feature_count),
            effectors: ThinningStore::new(),
            offered: 0,
            frames_used: 0,
            last_t_s: None,
        })
    }

    /// Validate and absorb one frame (RLS conic update etc.); a frame that is invalid
    /// (NaN, wrong feature count, time going backwards, coinciding effector points) is
    /// rejected with an error and leaves the estimator's observations unchanged (only the
    /// count of offered frames, which numbers frames in errors, advances).
    pub fn push(&mut self, frame: &ObservationFrame) -> Result<(), CalibrationError> {
        let index = self.offered;
        self.offered = self.offered.saturating_add(1);
        let validated = self.validate(index, frame)?;
        let record = validated.record(self.header.part_feature_count);
        self.last_t_s = Some(frame.t_s);
        if let Some(reference) = frame.reference_px {
            let [u, v] = reference;
            self.conic.add(self.pinhole.ray(Vector2::new(u, v)), 1.0);
        }
        let detected =
            record.centre.is_some() || record.reference.is_some() || record.part.is_some();
        if let Some(sighting) = &frame.effector {
            self.effectors
                .offer(EffectorRecord::from_sighting(sighting));
        }
        if detected || frame.effector.is_some() {
            self.frames_used = self.frames_used.saturating_add(1);
        }
        if detected {
            self.frames.offer(&record);
        }
        Ok(())
    }

    fn validate(
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
        Ok(ValidFrame {
            theta: frame.conveyor_angle_rad,
            centre: frame.center_px.map(to_f32),
            reference: frame.reference_px.map(to_f32),
            part,
        })
    }

    /// Frames offered to `push` so far (accepted or rejected).
    pub fn frames_offered(&self) -> u32 {
        self.offered
    }

    /// The recursive least-squares conic of Step 2 over every reference detection so far.
    pub fn conic(&self) -> Result<Conic, CalibrationError> {
        self.conic.solve()
    }

    /// The refined (maximum-likelihood) estimate from everything absorbed so far.
    pub fn estimate(&mut self) -> Result<CalibrationResult, CalibrationError> {
        self.estimate_with_uncertainty().map(|(result, _)| result)
    }

    /// [`SelfCalibrator::estimate`] with the standard deviations of its parameters (from the
    /// Gauss-Newton covariance at the optimum, scaled by the measured reprojection noise).
    /// Out of line: the caller's frame lies under the bundle adjustment's (the
    /// firmware's deepest stack), and this one's locals only have to.
    #[inline(never)]
    pub fn estimate_with_uncertainty(
        &mut self,
    ) -> Result<(CalibrationResult, EstimateUncertainty), CalibrationError> {
        let initial = self.initial_model()?;
        let problem = self.problem();
        let refined = refine(&problem, initial, &self.config)?;
        let uncertainty = refined
            .covariance
            .as_ref()
            .map(EstimateUncertainty::from_covariance)
            .ok_or(CalibrationError::NumericalFailure {
                stage: "covariance of the estimate",
            })?;
        Ok((
            self.result(&refined.model, refined.rms_px, refined.outliers),
            uncertainty,
        ))
    }

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
        Ok(self.result(&model, rms, 0))
    }

    fn no_effector_error(&self, first_invalid: Option<usize>) -> CalibrationError {
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

    fn problem(&self) -> Problem<'_> {
        Problem {
            pinhole: self.pinhole,
            frames: self.frames.view(),
            effectors: self.effectors.items(),
            feature_count: self.header.part_feature_count,
            reference_radius_m: self.header.reference_radius_m,
            fix_base_height: self.config.disc_height_in_base_m.is_some(),
        }
    }

    /// `pixel` (an image of `field`) in the virtual camera looking straight down the
    /// disc's axis (Step 3). A ray that does not point down towards the disc plane has
    /// no such image: the point is level with or above the camera.
    fn virtual_point(
        &self,
        rotation: &VirtualRotation,
        pixel: PixelF32,
        field: &'static str,
    ) -> Result<Vector2<f64>, CalibrationError> {
        rotation
            .to_virtual(self.pinhole.ray(to_vector(pixel)))
            .ok_or(CalibrationError::AboveCamera { field })
    }

    /// Mean image of the disc centre in ray coordinates; with `gate_px` only points within
    /// that distance of the previous mean count (a robust re-estimate).
    fn mean_centre_ray(
        &self,
        gate_px: Option<(Vector2<f64>, f64)>,
    ) -> Result<Vector2<f64>, CalibrationError> {
        let mut sum = Vector2::zeros();
        let mut count = 0u32;
        for centre in self.frames.view().iter().filter_map(|f| f.centre) {
            let pixel = to_vector(centre);
            if let Some((previous, gate)) = gate_px {
                if (pixel - previous).norm() > gate {
                    continue;
                }
            }
            sum += pixel;
            count += 1;
        }
        if count == 0 {
            return Err(CalibrationError::TooFewObservations {
                what: "disc centre images",
                needed: 1,
                found: 0,
            });
        }
        Ok(self.pinhole.ray(sum / f64::from(count)))
    }

    /// The centre's image with gross outliers removed: re-centred mean within a shrinking gate.
    fn robust_centre_ray(&self) -> Result<Vector2<f64>, CalibrationError> {
        let mut centre_ray = self.mean_centre_ray(None)?;
        let floor = 4.0 * self.config.pixel_sigma;
        let mut gate = 64.0 * floor;
        for _ in 0..6 {
            let centre_px =
                centre_ray * self.pinhole.f_px + Vector2::new(self.pinhole.cx, self.pinhole.cy);
            match self.mean_centre_ray(Some((centre_px, gate))) {
                Ok(ray) => centre_ray = ray,
                Err(_) => break,
            }
            gate = (gate / 4.0).max(floor * 1.5);
        }
        Ok(centre_ray)
    }

    /// Re-fits the conic on the stored reference points without gross outliers. The start is
    /// the best of a few exact five-point conics through detections spread evenly along the
    /// track (a deterministic consensus search: one stray detection far from the ellipse
    /// drags an algebraic fit badly, a five-point fit through clean points not at all), or the
    /// RLS conic when those fail; then Sampson-distance gating and refitting.
    fn robust_conic(&self) -> Result<Conic, CalibrationError> {
        let rls = self.conic.solve();
        let rays = || {
            self.frames
                .view()
                .iter()
                .filter_map(|f| f.reference)
                .map(|pixel| self.pinhole.ray(to_vector(pixel)))
        };
        let count = rays().count();
        let f_px = self.pinhole.f_px;
        let consensus_gate_px = (4.0 * self.config.pixel_sigma).max(2.0);
        let support = |conic: &Conic| {
            rays()
                .filter(|ray| conic.sampson_distance(*ray) * f_px <= consensus_gate_px)
                .count()
        };
        let mut best: Option<(usize, Conic)> =
            rls.as_ref().ok().map(|conic| (support(conic), *conic));
        if count >= 10 {
            const TRIALS: usize = 16;
            let stride = (count / (5 * TRIALS)).max(1);
            for trial in 0..TRIALS {
                let mut fit = ConicFit::new();
                for k in 0..5 {
                    let index = (trial * stride + k * count / 5) % count;
                    if let Some(ray) = rays().nth(index) {
                        fit.add(ray, 1.0);
                    }
                }
                if let Ok(candidate) = fit.solve() {
                    let candidate_support = support(&candidate);
                    if best.is_none_or(|(best_support, _)| candidate_support > best_support) {
                        best = Some((candidate_support, candidate));
                    }
                }
            }
        }
        // No usable start: the RLS conic's own error says what is wrong with the track.
        let Some((_, mut conic)) = best else {
            return rls;
        };
        let floor_px = 4.0 * self.config.pixel_sigma;
        let mut gate_px = 2.0 * consensus_gate_px;
        for _ in 0..4 {
            let mut fit = ConicFit::new();
            let (mut squares, mut kept) = (0.0, 0u32);
            for ray in rays() {
                let distance = conic.sampson_distance(ray) * f_px;
                if distance <= gate_px {
                    fit.add(ray, 1.0);
                    squares += distance * distance;
                    kept += 1;
                }
            }
            // The points the gate keeps are the track: if they form no ellipse, say so.
            conic = fit.solve()?;
            gate_px = (3.5 * libm::sqrt(squares / f64::from(kept.max(1)))).max(floor_px);
        }
        Ok(conic)
    }

    /// Five reference detections at least: the conic of Step 2 has five degrees of freedom,
    /// and the homography needs four points besides the centre.
    fn check_reference_count(&self) -> Result<(), CalibrationError> {
        let found = self
            .frames
            .view()
            .iter()
            .filter(|f| f.reference.is_some())
            .count();
        if found < 5 {
            return Err(CalibrationError::TooFewObservations {
                what: "reference point images",
                needed: 5,
                found: u32::try_from(found).unwrap_or(u32::MAX),
            });
        }
        Ok(())
    }

    /// The reference point's image track must be an ellipse the pixel noise cannot
    /// fake: its spread across its own principal direction (the smallest standard
    /// deviation of the detections) must exceed [`MIN_TRACK_SPREAD_IN_SIGMAS`] pixel
    /// sigmas. A camera in (or grazing) the disc plane sees the track as a line, and
    /// noise alone then fits a random conic, a random Step 2 and a confident wrong
    /// answer (a camera in the plane was reported as "below the disc").
    fn check_reference_spread(&self) -> Result<(), CalibrationError> {
        let mut count = 0.0;
        let mut sum = Vector2::<f64>::zeros();
        let mut squares = nalgebra::Matrix2::<f64>::zeros();
        for reference in self.frames.view().iter().filter_map(|f| f.reference) {
            let pixel = to_vector(reference);
            count += 1.0;
            sum += pixel;
            squares += pixel * pixel.transpose();
        }
        let points = || CalibrationError::DegenerateConic {
            points: u32::try_from(
                self.frames
                    .view()
                    .iter()
                    .filter(|f| f.reference.is_some())
                    .count(),
            )
            .unwrap_or(u32::MAX),
        };
        if !exceeds(count, 0.0) {
            return Err(points());
        }
        let mean = sum / count;
        let covariance = squares / count - mean * mean.transpose();
        let (sxx, syy, sxy) = (covariance.m11, covariance.m22, covariance.m12);
        let half_trace = 0.5 * (sxx + syy);
        let half_gap = libm::sqrt(0.25 * (sxx - syy) * (sxx - syy) + sxy * sxy);
        let smallest_variance_px2 = (half_trace - half_gap).max(0.0);
        let needed_px = MIN_TRACK_SPREAD_IN_SIGMAS * self.config.pixel_sigma;
        if !exceeds(smallest_variance_px2, needed_px * needed_px) {
            return Err(points());
        }
        Ok(())
    }

    fn check_rotation_span(&self) -> Result<(), CalibrationError> {
        let mut lowest = f64::INFINITY;
        let mut highest = f64::NEG_INFINITY;
        for frame in self
            .frames
            .view()
            .iter()
            .filter(|f| f.reference.is_some() || f.part.is_some())
        {
            lowest = lowest.min(frame.theta);
            highest = highest.max(frame.theta);
        }
        let span = if highest >= lowest {
            highest - lowest
        } else {
            0.0
        };
        if span < self.config.min_rotation_rad {
            return Err(CalibrationError::InsufficientRotation {
                span_rad: span,
                needed_rad: self.config.min_rotation_rad,
            });
        }
        Ok(())
    }

    /// Image angle of the disc X axis in the virtual image. The reference point at angle
    /// theta appears at image angle `gamma - theta` around the centre (the spec's
    /// orientation); a resultant that fits `gamma + theta` better means the camera is below
    /// the disc. `first_only` uses only the first reference detection (the paper's choice of
    /// the initial reference line as X axis).
    fn disc_axis_angle(
        &self,
        rotation: &VirtualRotation,
        first_only: bool,
    ) -> Result<f64, CalibrationError> {
        let mut above = Vector2::zeros();
        let mut below = Vector2::zeros();
        let mut first = None;
        for frame in self.frames.view().iter() {
            let Some(reference) = frame.reference else {
                continue;
            };
            let m = self.virtual_point(rotation, reference, "reference_px")?;
            let offset = m - rotation.centre_virtual;
            let angle = libm::atan2(offset.y, offset.x);
            let (sa, ca) = libm::sincos(angle + frame.theta);
            let (sb, cb) = libm::sincos(angle - frame.theta);
            above += Vector2::new(ca, sa);
            below += Vector2::new(cb, sb);
            first.get_or_insert(angle + frame.theta);
        }
        if below.norm() > above.norm() {
            return Err(CalibrationError::CameraBelowDisc);
        }
        let gamma = if first_only {
            first
        } else {
            Some(libm::atan2(above.y, above.x))
        };
        gamma.ok_or(CalibrationError::TooFewObservations {
            what: "reference point images",
            needed: 5,
            found: 0,
        })
    }

    /// Disc-frame positions of a sighting's two points (Eq 10, or the known disc height).
    fn sighting_disc_points(
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
    fn initial_model(&self) -> Result<WorkcellModel, CalibrationError> {
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
        let (base_yaw, base_translation) = self.locate_base(&geometry)?;
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
    fn plane_pose(&self) -> Result<PlanePose, CalibrationError> {
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
    fn locate_features(
        &self,
        geometry: &VirtualGeometry,
    ) -> Result<[nalgebra::Vector3<f64>; MAX_PART_FEATURES], CalibrationError> {
        let mut features = [Vector3::zeros(); MAX_PART_FEATURES];
        for (index, slot) in features
            .iter_mut()
            .enumerate()
            .take(self.header.part_feature_count)
        {
            let lines = || {
                self.frames.view().iter().filter_map(move |frame| {
                    let pixel = frame.part.and_then(|part| part.get(index).copied())?;
                    let m = self
                        .virtual_point(&geometry.rotation, pixel, "part_px")
                        .ok()?;
                    Some(geometry.affine_line(frame.theta, m))
                })
            };
            let mut system = FeatureSystem::default();
            lines().for_each(|line| system.add(line, 1.0));
            let mut point = system.solve()?;
            for _ in 0..2 {
                let (mut squares, mut count) = (0.0, 0u32);
                for line in lines() {
                    let miss = line_residual(&point, line);
                    squares += miss * miss;
                    count += 1;
                }
                let gate = 4.0 * libm::sqrt(squares / f64::from(count.max(1)));
                let mut gated = FeatureSystem::default();
                lines()
                    .filter(|line| line_residual(&point, *line) <= gate)
                    .for_each(|line| gated.add(line, 1.0));
                match gated.solve() {
                    Ok(next) => point = next,
                    Err(_) => break,
                }
            }
            *slot = point;
        }
        Ok(features)
    }

    /// Eq 15 over every sighting with a usable depth, least squares (see [`BaseFromDiscFit`]).
    /// Sightings with two valid roots of Eq 10 join in a second pass, with the root whose
    /// points agree better with the first pass's `base_from_disc`.
    fn locate_base(
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

    fn rms_reprojection(&self, model: &WorkcellModel) -> f64 {
        let problem = self.problem();
        let mut squares = 0.0;
        let mut count = 0u32;
        super::model::for_each_observation(
            problem.frames,
            problem.effectors,
            problem.feature_count,
            problem.reference_radius_m,
            |observation| {
                if let Some(r) = model.residual(&self.pinhole, observation) {
                    squares += r.norm_squared();
                    count += 1;
                }
            },
        );
        if count == 0 {
            0.0
        } else {
            libm::sqrt(squares / f64::from(count))
        }
    }

    fn result(&self, model: &WorkcellModel, rms_px: f64, outliers: u32) -> CalibrationResult {
        let r = model.disc_from_camera.matrix();
        let c = model.camera_centre_disc;
        let mut features_m: HVec<[f64; 3], MAX_PART_FEATURES> = HVec::new();
        let mut sum = Vector3::zeros();
        for feature in model.features_rotating.iter().take(model.feature_count) {
            // Cannot overflow: feature_count <= MAX_PART_FEATURES (checked in `new`).
            let _ = features_m.push([feature.x, feature.y, feature.z]);
            sum += feature;
        }
        let count = model.feature_count.max(1) as f64;
        let position = sum / count;
        let yaw = match (
            model.features_rotating.first(),
            model.features_rotating.get(1),
        ) {
            (Some(f0), Some(f1)) => libm::atan2(f1.y - f0.y, f1.x - f0.x),
            _ => 0.0,
        };
        let t = model.base_translation;
        CalibrationResult {
            camera: CameraEstimate {
                height_m: c.z,
                disc_from_camera: RigidTransform {
                    rotation: [
                        [r.m11, r.m12, r.m13],
                        [r.m21, r.m22, r.m23],
                        [r.m31, r.m32, r.m33],
                    ],
                    translation_m: [c.x, c.y, c.z],
                },
            },
            part: PartEstimate {
                features_m,
                position_m: [position.x, position.y, position.z],
                yaw_rad: yaw,
            },
            base_from_disc: BaseFromDisc {
                yaw_rad: wrap_pi(model.base_yaw),
                translation_m: [t.x, t.y, t.z],
            },
            quality: CalibrationQuality {
                frames_used: self.frames_used,
                rms_reprojection_px: rms_px,
                effector_frames_used: u32::try_from(self.effectors.items().len())
                    .unwrap_or(u32::MAX),
                outliers_rejected: outliers,
            },
        }
    }
}
