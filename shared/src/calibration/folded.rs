//! Beyond the paper: the information of every observation the calibrator has no room
//! to store, folded into Gauss-Newton normal equations, so that no frame is thrown
//! away and the estimate keeps improving for as long as the cell runs, in fixed memory.
//!
//! Why this is sound: the bundle adjustment ([`super::refine`]) minimises
//! `sum w |r(x)|^2 / 2` over every observation. Linearised at a point `x0` close to
//! the optimum, one observation's term is `w |r0 + J d|^2 / 2` with `d = x - x0`, and
//! a sum of such terms is exactly the quadratic `c + g^T d + d^T N d / 2` with
//! `N = sum w J^T J` and `g = sum w J^T r0`: the same arrowhead blocks the
//! refinement accumulates ([`NormalBlocks`], 2.8 KiB), whatever the number of
//! observations. The error of the approximation is second order in `x - x0`; `x0`
//! is the calibrator's latest estimate (millimetres and hundredths of a degree from
//! the optimum once the cell has calibrated), and it follows each new estimate
//! ([`FoldedInformation::move_to`]), so observations folded later are linearised
//! closer to the optimum. The stored frames (the keyframes) are relinearised at every
//! iteration as before: they start the estimate (the closed forms of Sections 2 and
//! 3 need raw pixels), measure the pixel noise and anchor the robust gate.
//!
//! An observation is weighted as the last estimate's robust loss would weigh it
//! (Huber, then a gate at `outlier_gate_sigma` measured sigmas): a gross outlier
//! is counted and adds nothing.

use super::model::{
    for_each_frame_observation, for_each_sighting_observation, Observation, Projector,
    WorkcellModel,
};
use super::normal_blocks::{Increment, NormalBlocks};
use super::pinhole::Pinhole;
use super::recent_bias::RecentBias;
use super::records::{EffectorRecord, FrameRecord};

/// The folded observations' RMS residual at the optimum, in units of the measured
/// noise's, beyond which they no longer describe the cell (see
/// [`FoldedInformation::consistent_with`]): consistent ones sit near 1.
pub const MAX_FOLDED_RMS_IN_SIGMAS: f64 = 1.5;
/// The fraction of folded points gated as outliers beyond which the linearisation
/// point is suspect (gross detection outliers are far rarer).
pub const MAX_FOLDED_OUTLIER_FRACTION: f64 = 0.05;

/// Points over which the recent residual is averaged (about 40 frames).
pub const RECENT_POINTS: u32 = 200;

/// How folded observations are weighted: the last estimate's robust loss.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FoldLoss {
    /// Residuals up to this norm (px) get full weight, beyond it `huber_px / r`.
    pub huber_px: f64,
    /// Residuals beyond this norm (px) are outliers: counted, not folded.
    pub gate_px: f64,
}

impl FoldLoss {
    /// IRLS weight of a residual of norm `r` (0 beyond the gate or for NaN).
    fn weight(&self, r: f64) -> f64 {
        if r.is_nan() || r > self.gate_px {
            0.0
        } else if r <= self.huber_px {
            1.0
        } else {
            self.huber_px / r
        }
    }
}

/// Normal equations of the folded observations at the linearisation point `at`.
#[derive(Debug, Clone, PartialEq)]
pub struct FoldedInformation {
    at: WorkcellModel,
    /// `at`'s base was estimated from sightings: sightings may be folded there
    /// (linearised at a base nobody estimated they would pull from nowhere).
    base_estimated: bool,
    loss: FoldLoss,
    blocks: NormalBlocks,
    /// `c` of the quadratic at `at`: `sum w |r0|^2 / 2`.
    constant: f64,
    /// Image points folded (each one 2-D residual), gated ones not included.
    points: u32,
    /// Their sum of squared residual norms at linearisation (for the RMS).
    squares: f64,
    /// Image points beyond the gate.
    outliers: u32,
    /// Exponential mean of the latest folded points' squared residual norms
    /// (px^2) where they were folded, over about [`RECENT_POINTS`]: what a
    /// camera that creeps away from the adopted estimate shows first.
    recent_mean_square: f64,
    /// The latest folded points' mean residual vector, movable to any
    /// estimate: what a camera that creeps shows first ([`super::recent_bias`]).
    recent_bias: RecentBias,
    /// Frames and sightings folded.
    frames: u32,
    sightings: u32,
}

impl FoldedInformation {
    /// Nothing folded yet, linearised at `at` with the loss `loss`.
    pub fn new(at: WorkcellModel, base_estimated: bool, loss: FoldLoss) -> Self {
        Self {
            at,
            base_estimated,
            loss,
            blocks: NormalBlocks::zeros(),
            constant: 0.0,
            points: 0,
            squares: 0.0,
            outliers: 0,
            recent_mean_square: 0.0,
            recent_bias: RecentBias::new(),
            frames: 0,
            sightings: 0,
        }
    }

    /// The linearisation point: the estimate it was last moved to.
    pub fn at(&self) -> &WorkcellModel {
        &self.at
    }

    /// Whether sightings can be folded (the linearisation point has an estimated base).
    pub fn base_estimated(&self) -> bool {
        self.base_estimated
    }

    /// Folds one frame's image points (its raw pixels are then dropped by the caller).
    pub fn fold_frame(
        &mut self,
        pinhole: &Pinhole,
        frame: &FrameRecord<'_>,
        feature_count: usize,
        reference_radius_m: f64,
    ) {
        self.frames = self.frames.saturating_add(1);
        let projector = Projector::<f64>::new(&self.at, pinhole);
        for_each_frame_observation(frame, feature_count, reference_radius_m, |observation| {
            self.fold_observation(&projector, observation);
        });
    }

    /// Folds one end-effector sighting (the caller checked [`Self::base_estimated`]).
    pub fn fold_sighting(&mut self, pinhole: &Pinhole, sighting: &EffectorRecord) {
        self.sightings = self.sightings.saturating_add(1);
        let projector = Projector::<f64>::new(&self.at, pinhole);
        for_each_sighting_observation(sighting, |observation| {
            self.fold_observation(&projector, observation);
        });
    }

    fn fold_observation(&mut self, projector: &Projector<f64>, observation: &Observation) {
        let Some((residual, jacobian)) = projector.residual_with_jacobian(observation) else {
            self.outliers = self.outliers.saturating_add(1);
            return;
        };
        let squared = residual.norm_squared();
        let weight = self.loss.weight(libm::sqrt(squared));
        // Gated points count at the gate: a creep that pushes points past it
        // must not hide from the mean.
        let counted = squared.min(self.loss.gate_px * self.loss.gate_px);
        let recent = f64::from(self.points.saturating_add(self.outliers).min(RECENT_POINTS)) + 1.0;
        self.recent_mean_square += (counted - self.recent_mean_square) / recent;
        if weight == 0.0 {
            self.outliers = self.outliers.saturating_add(1);
            return;
        }
        self.recent_bias.add(&residual, &jacobian);
        self.blocks
            .accumulate(&jacobian.camera, &jacobian.other, &residual, weight);
        self.constant += 0.5 * weight * squared;
        self.squares += squared;
        self.points = self.points.saturating_add(1);
    }

    /// The increment from the linearisation point to `model`.
    fn offset(&self, model: &WorkcellModel) -> Increment {
        model.difference_from(&self.at)
    }

    /// The folded observations' cost at `model`: the quadratic `c + g^T d + d^T N d / 2`.
    pub fn cost(&self, model: &WorkcellModel) -> f64 {
        let d = self.offset(model);
        self.constant + self.blocks.gradient().dot(&d) + 0.5 * d.dot(&self.blocks.apply(&d))
    }

    /// Adds the folded normal equations, with their gradient at `model`, to `blocks`.
    pub fn add_to(&self, blocks: &mut NormalBlocks, model: &WorkcellModel) {
        let d = self.offset(model);
        blocks.add(&self.blocks, &self.blocks.apply(&d));
    }

    /// Moves the linearisation point to `model` (the quadratic re-expressed there:
    /// `g += N d`, `c += g^T d + d^T N d / 2`) and takes `loss` for what is folded
    /// from now on. `base_estimated` can only become true.
    pub fn move_to(&mut self, model: &WorkcellModel, base_estimated: bool, loss: FoldLoss) {
        let d = self.offset(model);
        let shift = self.blocks.apply(&d);
        self.recent_bias.move_by(&d);
        self.constant = self.cost(model);
        self.blocks.shift_gradient(&shift);
        self.at = *model;
        self.base_estimated |= base_estimated;
        self.loss = loss;
    }

    /// Whether the folded observations agree with `model`, an optimum that includes
    /// them, measured with a pixel noise of `pixel_sigma_px` per axis: their RMS
    /// residual within [`MAX_FOLDED_RMS_IN_SIGMAS`] of the noise's, the latest
    /// [`RECENT_POINTS`] too where they were folded, and at most
    /// [`MAX_FOLDED_OUTLIER_FRACTION`] of them gated. They do not when they were
    /// linearised at a wrong estimate (a wrong start adopted, then moved away from):
    /// the quadratic then pulls towards where it was taken, and the estimate must be
    /// made without it. Nor when the camera creeps: the latest points drift away
    /// from every adopted estimate, while the whole run's fit averages the creep:
    /// their mean residual, moved to `model`, leaves zero all one way
    /// ([`super::recent_bias`]).
    pub fn consistent_with(&self, model: &WorkcellModel, pixel_sigma_px: f64) -> bool {
        let seen = f64::from(self.points) + f64::from(self.outliers);
        if self.points == 0 {
            return self.outliers == 0;
        }
        let mean_square = 2.0 * self.cost(model) / f64::from(self.points);
        let expected = 2.0 * pixel_sigma_px * pixel_sigma_px;
        let bound = MAX_FOLDED_RMS_IN_SIGMAS * MAX_FOLDED_RMS_IN_SIGMAS * expected;
        let recent_ok = self.points.saturating_add(self.outliers) < RECENT_POINTS
            || self.recent_mean_square <= bound;
        mean_square <= bound
            && recent_ok
            && self.recent_bias.still(&self.offset(model), pixel_sigma_px)
            && f64::from(self.outliers) <= MAX_FOLDED_OUTLIER_FRACTION * seen
    }

    /// The latest full window of folded points' mean residual vector at
    /// `model` (px; `None` before a window is full): see [`super::recent_bias`].
    pub fn recent_mean_px(&self, model: &WorkcellModel) -> Option<[f64; 2]> {
        self.recent_bias
            .mean_px(&self.offset(model))
            .map(|mean| [mean.x, mean.y])
    }

    /// Image points folded and kept.
    pub fn points(&self) -> u32 {
        self.points
    }

    /// Image points folded out as outliers.
    pub fn outliers(&self) -> u32 {
        self.outliers
    }

    /// Sum of the kept points' squared residual norms where they were folded (px^2).
    pub fn squares(&self) -> f64 {
        self.squares
    }

    /// Frames folded.
    pub fn frames(&self) -> u32 {
        self.frames
    }

    /// Sightings folded.
    pub fn sightings(&self) -> u32 {
        self.sightings
    }
}
