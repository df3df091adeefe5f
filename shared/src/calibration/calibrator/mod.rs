//! The fixed-memory incremental self-calibrator: absorbs frames one at a time and
//! produces the paper's estimate (Sections 2 and 3) or the refined maximum-likelihood one.
//!
//! One stage a module:
//! - `admit`: admitting the header, the configuration and each frame (the contract's rules).
//! - `track`: the reference track and the centre's image (Steps 2 and 3), checked and robust.
//! - `paper`: the paper's closed-form estimate (Eq 8 with two frames, Eq 15 with one pose).
//! - `initial`: the initial estimate the refinement starts from (every frame, every sighting).
//! - here: the store and the driver, [`SelfCalibrator`] itself: it keeps what was
//!   admitted, runs the stages and the refinement, and writes the result.

mod admit;
mod initial;
mod paper;
mod track;

pub use admit::{MAX_CONVEYOR_ANGLE_RAD, MAX_EFFECTOR_COORDINATE_M};

use heapless::Vec as HVec;
use nalgebra::{Vector2, Vector3};

use super::config::CalibrationConfig;
use super::conic::{Conic, ConicFit};
use super::error::CalibrationError;
use super::folded::{FoldLoss, FoldedInformation};
use super::frame_store::{FrameStore, FULL_FRAME_PIXELS};
use super::model::WorkcellModel;
use super::pinhole::Pinhole;
use super::records::EffectorRecord;
use super::refine::{refine, Problem, Refined};
use super::rim::{RimAccumulator, RimSummary};
use super::store::ThinningStore;
use super::uncertainty::EstimateUncertainty;
use crate::angle::wrap_pi;
use crate::observation::{
    BaseFromDisc, CalibrationQuality, CalibrationResult, CameraEstimate, LogHeader,
    ObservationFrame, PartEstimate, RigidTransform, MAX_PART_FEATURES,
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
    /// The last estimate, its loss and whether it estimated the base: what
    /// [`SelfCalibrator::adopt_last_estimate`] linearises at.
    last_estimate: Option<(WorkcellModel, FoldLoss, bool)>,
    /// What the stores had no room for since an estimate was adopted.
    folded: Option<FoldedInformation>,
    /// Times the folded information was found inconsistent and dropped.
    folds_discarded: u32,
    /// The frames' rims averaged (where the header gives the disc's radius).
    rim: RimAccumulator,
    /// What the refinement weighs of it, kept up to date with each rim.
    rim_summary: Option<RimSummary>,
}

/// What an estimate does when no sighting places `base_from_disc` yet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum BaseUnplaced {
    /// Refuses: the caller needs the base (Eqs 10 to 15).
    Refuse,
    /// Holds it where it stands (the base's parameters are then not
    /// estimated, see `refine::freedom`): the camera and the part alone.
    HoldIt,
}

/// A small instance: 96 frames, 16 effector sightings (9 696 B on x86-64).
pub type FirmwareCalibrator = SelfCalibrator<96, 16>;
/// The host's instance: 1024 frames, 256 effector sightings (101 888 B on x86-64).
pub type HostCalibrator = SelfCalibrator<1024, 256>;

impl<const FRAMES: usize, const EFFECTOR_FRAMES: usize, const PIXELS_PER_FRAME: usize>
    SelfCalibrator<FRAMES, EFFECTOR_FRAMES, PIXELS_PER_FRAME>
{
    /// A calibrator for the log `header` with `config`; refuses a header or configuration
    /// no workcell fits (see `admit`).
    pub fn new(header: &LogHeader, config: CalibrationConfig) -> Result<Self, CalibrationError> {
        admit::check_header(header)?;
        admit::check_config(&config)?;
        Ok(Self {
            header: *header,
            config,
            pinhole: Pinhole::new(&header.camera),
            conic: ConicFit::new(),
            frames: FrameStore::new(header.part_feature_count),
            effectors: ThinningStore::new(),
            offered: 0,
            frames_used: 0,
            last_t_s: None,
            last_estimate: None,
            folded: None,
            folds_discarded: 0,
            rim: RimAccumulator::default(),
            rim_summary: None,
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
        let pinhole = self.pinhole;
        if let Some(sighting) = &frame.effector {
            let sighting = EffectorRecord::from_sighting(sighting);
            match &mut self.folded {
                Some(folded) if folded.base_estimated() => self
                    .effectors
                    .offer_folding(sighting, |leaving| folded.fold_sighting(&pinhole, leaving)),
                _ => self.effectors.offer(sighting),
            }
        }
        if detected || frame.effector.is_some() {
            self.frames_used = self.frames_used.saturating_add(1);
        }
        if let (Some(rim), Some(radius)) = (&frame.rim, self.header.disc_radius_m) {
            // A refused rim is counted ([`SelfCalibrator::rims`]), the frame kept.
            if self.rim.add(rim).is_ok() {
                self.rim_summary = self.rim.summary(radius);
            }
        }
        if detected {
            let (feature_count, radius) = (
                self.header.part_feature_count,
                self.header.reference_radius_m,
            );
            match &mut self.folded {
                Some(folded) => self.frames.offer_folding(&record, |leaving| {
                    folded.fold_frame(&pinhole, leaving, feature_count, radius)
                }),
                None => self.frames.offer(&record),
            }
        }
        Ok(())
    }

    /// From now on, what the stores have no room for is folded into normal
    /// equations linearised at the last estimate (see [`super::folded`]) instead of
    /// being thinned away. Call it with an
    /// estimate the caller trusts: the pick does once its checks pass. Each later
    /// call moves the linearisation to the newer estimate. False when there is no
    /// estimate to adopt.
    pub fn adopt_last_estimate(&mut self) -> bool {
        let Some((model, loss, base_estimated)) = self.last_estimate else {
            return false;
        };
        match &mut self.folded {
            Some(folded) => folded.move_to(&model, base_estimated, loss),
            None => self.folded = Some(FoldedInformation::new(model, base_estimated, loss)),
        }
        true
    }

    /// Whether the next frame or sighting may find its store full: from then on
    /// what does not fit is thinned away unless an estimate has been adopted (a
    /// host tool estimates and adopts here; the pick adopts its own estimates).
    pub fn stores_full(&self) -> bool {
        !self.frames.has_room() || self.effectors.items().len() >= EFFECTOR_FRAMES
    }

    /// How many times folded information disagreed with the estimate and was
    /// discarded (see [`FoldedInformation::consistent_with`]).
    pub fn folds_discarded(&self) -> u32 {
        self.folds_discarded
    }

    /// What has been folded so far (`None` before [`SelfCalibrator::adopt_last_estimate`]).
    pub fn folded(&self) -> Option<&FoldedInformation> {
        self.folded.as_ref()
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
        self.refine_stored(BaseUnplaced::Refuse, |calibrator, refined| {
            let geometry = refined.model.grasp_geometry();
            let uncertainty = refined
                .covariance
                .as_ref()
                .map(|covariance| EstimateUncertainty::from_covariance(covariance, &geometry))
                .ok_or(CalibrationError::NumericalFailure {
                    stage: "covariance of the estimate",
                })?;
            Ok((
                calibrator.result(
                    &refined.model,
                    refined.rms_px,
                    refined.outliers,
                    refined.pixel_sigma_px,
                ),
                uncertainty,
            ))
        })
    }

    /// Estimates from what is stored and adopts the estimate
    /// ([`SelfCalibrator::adopt_last_estimate`]), the camera and the part
    /// alone when no sighting places the base yet (the base is then held
    /// and no sighting is folded until an estimate places it). For a caller
    /// that must not lose what its stores have no room for: once they are
    /// full, frames are folded at this estimate rather than thinned away.
    /// False when no estimate could be made (nothing is adopted then).
    pub fn estimate_and_adopt(&mut self) -> bool {
        self.refine_stored(BaseUnplaced::HoldIt, |_, _| Ok(()))
            .is_ok()
            && self.adopt_last_estimate()
    }

    /// Whether the stores are full and nothing has been adopted: the next
    /// frame or sighting would be thinned away, not folded. A calibrator fed
    /// for a long time before anyone asks for an estimate (a 30 Hz camera
    /// fills 256 frames in 8.5 s) calls [`SelfCalibrator::estimate_and_adopt`]
    /// then.
    pub fn about_to_thin(&self) -> bool {
        self.folded.is_none() && self.stores_full()
    }

    /// The refined estimate from the stores and the folded information (the
    /// folds dropped first when they disagree with it), remembered as the
    /// last estimate for [`SelfCalibrator::adopt_last_estimate`]; `finish`
    /// reads it where it lies. Inlined into its two callers, and the large
    /// [`Refined`] never moved: one copy in one frame (the firmware's deepest
    /// stack lies under it).
    #[inline(always)]
    fn refine_stored<T>(
        &mut self,
        unplaced: BaseUnplaced,
        finish: impl FnOnce(&Self, &Refined) -> Result<T, CalibrationError>,
    ) -> Result<T, CalibrationError> {
        let initial = self.initial_model(unplaced)?;
        let mut refined = refine(&self.problem(), initial, &self.config)?;
        let inconsistent = self
            .folded
            .as_ref()
            .is_some_and(|folded| !folded.consistent_with(&refined.model, refined.pixel_sigma_px));
        if inconsistent {
            self.folded = None;
            self.folds_discarded = self.folds_discarded.saturating_add(1);
            refined = refine(&self.problem(), initial, &self.config)?;
        }
        let sigma = refined.pixel_sigma_px;
        let loss = FoldLoss {
            huber_px: self.config.huber_k * sigma,
            gate_px: self.config.outlier_gate_sigma * sigma.max(self.config.pixel_sigma),
        };
        self.last_estimate = Some((refined.model, loss, self.base_observed()));
        finish(self, &refined)
    }

    /// Whether any sighting, stored or folded, constrains the base.
    fn base_observed(&self) -> bool {
        !self.effectors.items().is_empty()
            || self
                .folded
                .as_ref()
                .is_some_and(|folded| folded.sightings() > 0)
    }

    fn problem(&self) -> Problem<'_> {
        Problem {
            pinhole: self.pinhole,
            frames: self.frames.view(),
            effectors: self.effectors.items(),
            feature_count: self.header.part_feature_count,
            reference_radius_m: self.header.reference_radius_m,
            fix_base_height: self.config.disc_height_in_base_m.is_some(),
            folded: self.folded.as_ref(),
            rim: self.rim_summary.as_ref(),
        }
    }

    /// Rims averaged and rims gated away so far.
    pub fn rims(&self) -> (u32, u32) {
        (self.rim.count(), self.rim.gated())
    }

    fn rms_reprojection(&self, model: &WorkcellModel) -> f64 {
        let problem = self.problem();
        let mut squares = 0.0;
        let mut count = 0u32;
        let projector = super::model::Projector::<f64>::new(model, &self.pinhole);
        problem.for_each_observation(|observation| {
            if let Some(r) = projector.residual(observation) {
                squares += r.norm_squared();
                count += 1;
            }
        });
        if count == 0 {
            0.0
        } else {
            libm::sqrt(squares / f64::from(count))
        }
    }

    fn result(
        &self,
        model: &WorkcellModel,
        rms_px: f64,
        outliers: u32,
        pixel_sigma_px: f64,
    ) -> CalibrationResult {
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
                    .unwrap_or(u32::MAX)
                    .saturating_add(self.folded.as_ref().map_or(0, |f| f.sightings())),
                outliers_rejected: outliers,
                pixel_sigma_px,
            },
        }
    }
}
