//! The bundle adjustment's Gauss-Newton normal equations in arrowhead form, and their
//! solution by the Schur complement (beyond the paper, which has no joint refinement).
//!
//! Why arrowhead: a feature point's image depends on the camera and that one feature
//! (Eq 1), an end-effector point's on the camera and `base_from_disc` (Eq 9), a known
//! disc point's on the camera alone (see [`OtherBlock`]). Ordered camera (6), base (4),
//! features (3 each), the normal matrix `J^T W J` is therefore
//!
//! ```text
//!     [ A    W_1  ...  W_8 ]      A   10x10  camera and base
//!     [ W_1' V_1           ]      W_i 10x3   camera rows only (base rows are zero)
//!     [ ...       ...      ]      V_i  3x3   feature i
//!     [ W_8'           V_8 ]
//! ```
//!
//! and only these blocks are stored: 2.8 KiB instead of the dense 34x34 matrix's 9.2
//! KiB, with no copy of it on the firmware's stack. The features are eliminated:
//! `S = A - sum_i W_i V_i^-1 W_i^T` (10x10), `S x_a = b_a - sum_i W_i V_i^-1 b_i`, then
//! `x_i = V_i^-1 (b_i - W_i^T x_a)`; the inverse's blocks the uncertainty needs are
//! `S^-1` for the camera and base, and `V_i^-1 delta_ij + V_i^-1 W_i^T S^-1 W_j V_j^-1`
//! between features. Both are exact rearrangements of the dense solve and inverse: the
//! tests compare them with nalgebra's on random problems.

use nalgebra::{Matrix3, RealField, SMatrix, SVector, Scalar, Vector2, Vector3};

use super::cholesky::{factor_in_place, solve_in_place};
use super::model::{OtherBlock, BASE_OFFSET, FEATURE_OFFSET, PARAMETERS};
use crate::observation::MAX_PART_FEATURES;

/// Camera parameters: rotation increment (3), optical centre (3).
pub const CAMERA_PARAMETERS: usize = 6;
/// `base_from_disc` parameters: yaw, translation (3).
pub const BASE_PARAMETERS: usize = 4;
/// Camera and base together: the block `A` of the arrowhead.
pub const ARROW_PARAMETERS: usize = CAMERA_PARAMETERS + BASE_PARAMETERS;

/// A matrix over the camera and base parameters (camera first).
pub type ArrowMatrix = SMatrix<f64, ARROW_PARAMETERS, ARROW_PARAMETERS>;
type ArrowVector = SVector<f64, ARROW_PARAMETERS>;
/// A step in the layout of [`super::model::WorkcellModel::retract`].
pub type Increment = SVector<f64, PARAMETERS>;

/// Which parameters the data can move. The others (unused feature slots, the base
/// without sightings, the base height when it is known) get a zero step and a zero
/// variance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Freedom {
    /// Features `0..feature_count` are estimated.
    pub feature_count: usize,
    /// Base yaw and translation x, y, z: estimated or held.
    pub base_free: [bool; BASE_PARAMETERS],
}

impl Freedom {
    fn arrow_free(&self, k: usize) -> bool {
        k < CAMERA_PARAMETERS
            || self
                .base_free
                .get(k - CAMERA_PARAMETERS)
                .copied()
                .unwrap_or(false)
    }

    fn features(&self) -> usize {
        self.feature_count.min(MAX_PART_FEATURES)
    }
}

/// Covariance of the estimate where the uncertainty reads it: the camera and base
/// parameters and the part position (the features' mean), scaled by the pixel variance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarginalCovariance {
    /// Rotation (3), optical centre (3), base yaw, base translation (3); a held
    /// parameter's variance is zero.
    pub camera_and_base: ArrowMatrix,
    /// Of the mean of features `0..feature_count` in the rotating frame.
    pub part_position: Matrix3<f64>,
    /// Between that mean (rows) and the camera and base parameters (columns):
    /// both lean on the camera, so the part in the base frame (Eq 1) is not
    /// as uncertain as the two added apart.
    pub part_and_arrow: PartCross,
    /// Of `feature 1 - feature 0`, the line that gives the part's yaw (zero
    /// with fewer than two features).
    pub yaw_line: Matrix3<f64>,
    /// Between that line (rows) and the camera and base parameters.
    pub yaw_line_and_arrow: PartCross,
}

/// A covariance between a point of the part (3 rows) and the camera and base parameters.
pub type PartCross = SMatrix<f64, 3, ARROW_PARAMETERS>;

/// The blocks of the arrowhead normal equations `J^T W J` and gradient `J^T W r`,
/// in the scalar `T` they are summed in.
#[derive(Debug, Clone, PartialEq)]
pub struct ArrowheadBlocks<T: Scalar> {
    arrow: SMatrix<T, ARROW_PARAMETERS, ARROW_PARAMETERS>,
    arrow_gradient: SVector<T, ARROW_PARAMETERS>,
    features: [Matrix3<T>; MAX_PART_FEATURES],
    cross: [SMatrix<T, CAMERA_PARAMETERS, 3>; MAX_PART_FEATURES],
    feature_gradients: [Vector3<T>; MAX_PART_FEATURES],
}

/// The normal equations the step and the covariance are solved from (f64).
pub type NormalBlocks = ArrowheadBlocks<f64>;

/// A short run of points summed in f32 (the Cortex-M4F's FPU has no f64: every f64
/// operation is a software routine) before it is added into [`NormalBlocks`]:
/// a run of [`RUN_POINTS`] loses about 1e-6 of its sum, the matrix the steps only
/// need to ~1e-4 (docs/calibration.md, "Precision").
pub type NormalRun = ArrowheadBlocks<f32>;

/// Points summed in one [`NormalRun`] before it joins the f64 blocks.
pub const RUN_POINTS: u32 = 64;

impl Default for NormalBlocks {
    fn default() -> Self {
        Self::zeros()
    }
}

impl<T: RealField + Copy> ArrowheadBlocks<T> {
    /// All blocks zero.
    pub fn zeros() -> Self {
        Self {
            arrow: SMatrix::zeros(),
            arrow_gradient: SVector::zeros(),
            features: [Matrix3::zeros(); MAX_PART_FEATURES],
            cross: [SMatrix::zeros(); MAX_PART_FEATURES],
            feature_gradients: [Vector3::zeros(); MAX_PART_FEATURES],
        }
    }

    /// Adds one weighted residual: `camera` and `other` are its Jacobian blocks.
    pub fn accumulate(
        &mut self,
        camera: &SMatrix<T, 2, CAMERA_PARAMETERS>,
        other: &OtherBlock<T>,
        residual: &Vector2<T>,
        weight: T,
    ) {
        let camera_t = camera.transpose() * weight;
        let mut cc = self
            .arrow
            .fixed_view_mut::<CAMERA_PARAMETERS, CAMERA_PARAMETERS>(0, 0);
        cc += camera_t * camera;
        let mut gc = self
            .arrow_gradient
            .fixed_view_mut::<CAMERA_PARAMETERS, 1>(0, 0);
        gc += camera_t * residual;
        match *other {
            OtherBlock::None => {}
            OtherBlock::Feature { index, jacobian } => {
                let (Some(v), Some(w), Some(g)) = (
                    self.features.get_mut(index),
                    self.cross.get_mut(index),
                    self.feature_gradients.get_mut(index),
                ) else {
                    return;
                };
                let jacobian_t = jacobian.transpose() * weight;
                *w += camera_t * jacobian;
                *v += jacobian_t * jacobian;
                *g += jacobian_t * residual;
            }
            OtherBlock::Base(block) => {
                let block_t = block.transpose() * weight;
                let cross = camera_t * block;
                let c = CAMERA_PARAMETERS;
                let mut cb = self
                    .arrow
                    .fixed_view_mut::<CAMERA_PARAMETERS, BASE_PARAMETERS>(0, c);
                cb += cross;
                let mut bc = self
                    .arrow
                    .fixed_view_mut::<BASE_PARAMETERS, CAMERA_PARAMETERS>(c, 0);
                bc += cross.transpose();
                let mut bb = self
                    .arrow
                    .fixed_view_mut::<BASE_PARAMETERS, BASE_PARAMETERS>(c, c);
                bb += block_t * block;
                let mut gb = self
                    .arrow_gradient
                    .fixed_view_mut::<BASE_PARAMETERS, 1>(c, 0);
                gb += block_t * residual;
            }
        }
    }
}

impl NormalBlocks {
    /// Adds a run summed in f32 (its first `features` feature blocks; the others
    /// are zero) and empties the run.
    pub fn add_run(&mut self, run: &mut NormalRun, features: usize) {
        self.arrow += run.arrow.map(f64::from);
        self.arrow_gradient += run.arrow_gradient.map(f64::from);
        let blocks = self
            .features
            .iter_mut()
            .zip(self.cross.iter_mut())
            .zip(self.feature_gradients.iter_mut())
            .zip(run.features.iter().zip(&run.cross))
            .zip(run.feature_gradients.iter())
            .take(features);
        for ((((v, w), g), (run_v, run_w)), run_g) in blocks {
            *v += run_v.map(f64::from);
            *w += run_w.map(f64::from);
            *g += run_g.map(f64::from);
        }
        *run = NormalRun::zeros();
    }

    /// `N x` for an increment `x` in the layout of [`super::model::WorkcellModel::retract`]
    /// (a folded linearisation's gradient at a point `x` away from where it was taken).
    pub fn apply(&self, x: &Increment) -> Increment {
        let x_arrow = arrow_part(x);
        let mut out_arrow = self.arrow * x_arrow;
        let mut out = Increment::zeros();
        let camera = x_arrow.fixed_view::<CAMERA_PARAMETERS, 1>(0, 0);
        for (slot, (v, w)) in self.features.iter().zip(&self.cross).enumerate() {
            let x_feature = x.fixed_view::<3, 1>(FEATURE_OFFSET + 3 * slot, 0);
            let mut out_camera = out_arrow.fixed_view_mut::<CAMERA_PARAMETERS, 1>(0, 0);
            out_camera += w * x_feature;
            let feature = w.transpose() * camera + v * x_feature;
            out.fixed_view_mut::<3, 1>(FEATURE_OFFSET + 3 * slot, 0)
                .copy_from(&feature);
        }
        set_arrow_part(&mut out, &out_arrow);
        out
    }

    /// The gradient `J^T W r` in the layout of [`NormalBlocks::apply`].
    pub fn gradient(&self) -> Increment {
        let mut out = Increment::zeros();
        set_arrow_part(&mut out, &self.arrow_gradient);
        for (slot, g) in self.feature_gradients.iter().enumerate() {
            out.fixed_view_mut::<3, 1>(FEATURE_OFFSET + 3 * slot, 0)
                .copy_from(g);
        }
        out
    }

    /// Adds `other`'s matrix and its gradient, plus `gradient_shift` (layout of
    /// [`NormalBlocks::apply`]), to these blocks: a folded linearisation joins the
    /// stored observations' normal equations.
    pub fn add(&mut self, other: &NormalBlocks, gradient_shift: &Increment) {
        self.arrow += other.arrow;
        self.arrow_gradient += other.arrow_gradient + arrow_part(gradient_shift);
        let features = self
            .features
            .iter_mut()
            .zip(self.cross.iter_mut())
            .zip(self.feature_gradients.iter_mut())
            .zip(other.features.iter().zip(&other.cross))
            .zip(other.feature_gradients.iter())
            .enumerate();
        for (slot, ((((v, w), g), (other_v, other_w)), other_g)) in features {
            *v += other_v;
            *w += other_w;
            *g += other_g + gradient_shift.fixed_view::<3, 1>(FEATURE_OFFSET + 3 * slot, 0);
        }
    }

    /// Adds `shift` (layout of [`NormalBlocks::apply`]) to the gradient.
    pub fn shift_gradient(&mut self, shift: &Increment) {
        self.arrow_gradient += arrow_part(shift);
        for (slot, g) in self.feature_gradients.iter_mut().enumerate() {
            *g += shift.fixed_view::<3, 1>(FEATURE_OFFSET + 3 * slot, 0);
        }
    }

    /// `A` with every held parameter's row and column replaced by the identity's.
    fn arrow_holding(&self, freedom: &Freedom) -> ArrowMatrix {
        let mut a = self.arrow;
        for k in (0..ARROW_PARAMETERS).filter(|&k| !freedom.arrow_free(k)) {
            a.row_mut(k).fill(0.0);
            a.column_mut(k).fill(0.0);
            if let Some(e) = a.get_mut((k, k)) {
                *e = 1.0;
            }
        }
        a
    }

    /// The Levenberg-Marquardt step `(N + damping diag N + 1e-12 I) x = -g` over the
    /// free parameters (held ones step 0), by eliminating the features. `None` when the
    /// damped system is not positive definite (the caller raises the damping).
    ///
    /// Out of line: inlined, its working set (the Schur complement, the feature
    /// factors) stayed on the stack under the whole Levenberg-Marquardt loop,
    /// normal equations included: 2.5 KB more of the firmware's deepest stack.
    #[inline(never)]
    pub fn damped_step(&self, freedom: &Freedom, damping: f64) -> Option<Increment> {
        let damp = |d: &mut f64| *d = *d * (1.0 + damping) + 1e-12;
        let mut schur = self.arrow_holding(freedom);
        let mut rhs = -self.arrow_gradient;
        for k in 0..ARROW_PARAMETERS {
            if freedom.arrow_free(k) {
                if let Some(d) = schur.get_mut((k, k)) {
                    damp(d);
                }
            } else if let Some(e) = rhs.get_mut(k) {
                *e = 0.0;
            }
        }
        let mut factors = [Matrix3::<f64>::zeros(); MAX_PART_FEATURES];
        let features = self
            .features
            .iter()
            .zip(&self.cross)
            .zip(&self.feature_gradients)
            .zip(factors.iter_mut())
            .take(freedom.features());
        for (((v, w), g), factor) in features {
            *factor = *v;
            for d in 0..3 {
                if let Some(e) = factor.get_mut((d, d)) {
                    damp(e);
                }
            }
            if !factor_in_place(factor) {
                return None;
            }
            let mut inverse_cross = w.transpose();
            solve_in_place(factor, &mut inverse_cross);
            let mut inverse_rhs = -g;
            solve_in_place(factor, &mut inverse_rhs);
            let mut cc = schur.fixed_view_mut::<CAMERA_PARAMETERS, CAMERA_PARAMETERS>(0, 0);
            cc -= w * inverse_cross;
            let mut rc = rhs.fixed_view_mut::<CAMERA_PARAMETERS, 1>(0, 0);
            rc -= w * inverse_rhs;
        }
        if !factor_in_place(&mut schur) {
            return None;
        }
        solve_in_place(&schur, &mut rhs);
        let camera_step = rhs.fixed_view::<CAMERA_PARAMETERS, 1>(0, 0);
        let mut step = Increment::zeros();
        step.fixed_view_mut::<CAMERA_PARAMETERS, 1>(0, 0)
            .copy_from(&camera_step);
        step.fixed_view_mut::<BASE_PARAMETERS, 1>(BASE_OFFSET, 0)
            .copy_from(&rhs.fixed_view::<BASE_PARAMETERS, 1>(CAMERA_PARAMETERS, 0));
        let features = self
            .cross
            .iter()
            .zip(&self.feature_gradients)
            .zip(&factors)
            .take(freedom.features())
            .enumerate();
        for (slot, ((w, g), factor)) in features {
            let mut x = -g - w.transpose() * camera_step;
            solve_in_place(factor, &mut x);
            step.fixed_view_mut::<3, 1>(FEATURE_OFFSET + 3 * slot, 0)
                .copy_from(&x);
        }
        Some(step)
    }

    /// How near singular the undamped system is where the step is solved: the
    /// smallest ratio, over the free parameters, of a Cholesky pivot (the
    /// information left to a parameter once those eliminated before it are
    /// known) to its diagonal entry (its information alone), the features
    /// eliminated first as [`NormalBlocks::damped_step`] does; 0 when a factor
    /// fails. Sums in f32 move each entry by about 1e-6 of the diagonal, so a
    /// direction whose ratio is not well above that is lost in them
    /// ([`super::refine`] then sums in f64).
    #[inline(never)]
    pub fn weakest_pivot_ratio(&self, freedom: &Freedom) -> f64 {
        let mut weakest = 1.0f64;
        let mut schur = self.arrow_holding(freedom);
        let diagonal = schur.diagonal();
        let features = self
            .features
            .iter()
            .zip(&self.cross)
            .take(freedom.features());
        for (v, w) in features {
            let mut factor = *v;
            if !factor_in_place(&mut factor) {
                return 0.0;
            }
            for d in 0..3 {
                let pivot = factor.get((d, d)).copied().unwrap_or(0.0);
                let alone = v.get((d, d)).copied().unwrap_or(0.0);
                weakest = weakest.min(pivot * pivot / alone);
            }
            let mut inverse_cross = w.transpose();
            solve_in_place(&factor, &mut inverse_cross);
            let mut cc = schur.fixed_view_mut::<CAMERA_PARAMETERS, CAMERA_PARAMETERS>(0, 0);
            cc -= w * inverse_cross;
        }
        if !factor_in_place(&mut schur) {
            return 0.0;
        }
        for k in (0..ARROW_PARAMETERS).filter(|&k| freedom.arrow_free(k)) {
            let pivot = schur.get((k, k)).copied().unwrap_or(0.0);
            let alone = diagonal.get(k).copied().unwrap_or(0.0);
            weakest = weakest.min(pivot * pivot / alone);
        }
        weakest
    }

    /// The undamped inverse's camera, base and part-position blocks times `variance`
    /// (held parameters are known exactly: zero variance). `None` when the normal matrix
    /// is singular. Out of line for the reason [`NormalBlocks::damped_step`] is.
    #[inline(never)]
    pub fn covariance(&self, freedom: &Freedom, variance: f64) -> Option<MarginalCovariance> {
        let mut schur = self.arrow_holding(freedom);
        let mut sum_inverse = Matrix3::<f64>::zeros();
        // `G_i = V_i^-1 W_i^T`: how feature i follows the camera once the
        // features are eliminated; `C(f_i, f_j) = d_ij V_i^-1 + G_i C_cc G_j^T`
        // and `C(f_i, a) = -G_i C_ca`.
        let mut sum_inverse_cross = SMatrix::<f64, 3, CAMERA_PARAMETERS>::zeros();
        let mut line_inverse = Matrix3::<f64>::zeros();
        let mut line_cross = SMatrix::<f64, 3, CAMERA_PARAMETERS>::zeros();
        let features = self
            .features
            .iter()
            .zip(&self.cross)
            .take(freedom.features())
            .enumerate();
        for (slot, (v, w)) in features {
            let inverse = v.try_inverse()?;
            let inverse_cross = inverse * w.transpose();
            let mut cc = schur.fixed_view_mut::<CAMERA_PARAMETERS, CAMERA_PARAMETERS>(0, 0);
            cc -= w * inverse_cross;
            sum_inverse += inverse;
            sum_inverse_cross += inverse_cross;
            // The yaw line is feature 1 minus feature 0.
            match slot {
                0 => {
                    line_inverse += inverse;
                    line_cross -= inverse_cross;
                }
                1 => {
                    line_inverse += inverse;
                    line_cross += inverse_cross;
                }
                _ => {}
            }
        }
        if freedom.features() < 2 {
            line_inverse = Matrix3::zeros();
            line_cross = SMatrix::zeros();
        }
        let mut camera_and_base = schur.try_inverse()?;
        for k in (0..ARROW_PARAMETERS).filter(|&k| !freedom.arrow_free(k)) {
            camera_and_base.row_mut(k).fill(0.0);
            camera_and_base.column_mut(k).fill(0.0);
        }
        // The part position is the mean of the features: (1/n^2) sum_ij C(f_i, f_j).
        let camera = camera_and_base.fixed_view::<CAMERA_PARAMETERS, CAMERA_PARAMETERS>(0, 0);
        let camera_rows = camera_and_base.fixed_view::<CAMERA_PARAMETERS, ARROW_PARAMETERS>(0, 0);
        let count = freedom.feature_count.clamp(1, MAX_PART_FEATURES) as f64;
        let part_position = (sum_inverse
            + sum_inverse_cross * camera * sum_inverse_cross.transpose())
            * (variance / (count * count));
        let part_and_arrow = -(sum_inverse_cross * camera_rows) * (variance / count);
        let yaw_line = (line_inverse + line_cross * camera * line_cross.transpose()) * variance;
        let yaw_line_and_arrow = -(line_cross * camera_rows) * variance;
        camera_and_base *= variance;
        Some(MarginalCovariance {
            camera_and_base,
            part_position,
            part_and_arrow,
            yaw_line,
            yaw_line_and_arrow,
        })
    }
}

/// The camera and base entries of an increment, in the arrowhead's order.
fn arrow_part(x: &Increment) -> ArrowVector {
    let mut out = ArrowVector::zeros();
    out.fixed_view_mut::<CAMERA_PARAMETERS, 1>(0, 0)
        .copy_from(&x.fixed_view::<CAMERA_PARAMETERS, 1>(0, 0));
    out.fixed_view_mut::<BASE_PARAMETERS, 1>(CAMERA_PARAMETERS, 0)
        .copy_from(&x.fixed_view::<BASE_PARAMETERS, 1>(BASE_OFFSET, 0));
    out
}

/// Writes the arrowhead's camera and base entries into an increment.
fn set_arrow_part(x: &mut Increment, arrow: &ArrowVector) {
    x.fixed_view_mut::<CAMERA_PARAMETERS, 1>(0, 0)
        .copy_from(&arrow.fixed_view::<CAMERA_PARAMETERS, 1>(0, 0));
    x.fixed_view_mut::<BASE_PARAMETERS, 1>(BASE_OFFSET, 0)
        .copy_from(&arrow.fixed_view::<BASE_PARAMETERS, 1>(CAMERA_PARAMETERS, 0));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::splitmix;
    use nalgebra::Matrix2x3;

    type Dense = SMatrix<f64, PARAMETERS, PARAMETERS>;

    /// The dense accumulation of the full normal equations, the blocks' reference.
    fn dense_accumulate(
        normal: &mut Dense,
        gradient: &mut Increment,
        camera: &SMatrix<f64, 2, 6>,
        other: &OtherBlock,
        residual: &Vector2<f64>,
        weight: f64,
    ) {
        let camera_t = camera.transpose() * weight;
        let mut cc = normal.fixed_view_mut::<6, 6>(0, 0);
        cc += camera_t * camera;
        let mut gc = gradient.fixed_view_mut::<6, 1>(0, 0);
        gc += camera_t * residual;
        let (offset, width, block) = match *other {
            OtherBlock::None => return,
            OtherBlock::Feature { index, jacobian } => {
                let mut padded = SMatrix::<f64, 2, 4>::zeros();
                padded.fixed_view_mut::<2, 3>(0, 0).copy_from(&jacobian);
                (FEATURE_OFFSET + 3 * index, 3, padded)
            }
            OtherBlock::Base(block) => (BASE_OFFSET, 4, block),
        };
        let block_t = block.transpose() * weight;
        let cross = camera_t * block;
        for r in 0..width {
            for c in 0..6 {
                normal[(c, offset + r)] += cross[(c, r)];
                normal[(offset + r, c)] += cross[(c, r)];
            }
            for s in 0..width {
                normal[(offset + r, offset + s)] += (block_t * block)[(r, s)];
            }
            gradient[offset + r] += (block_t * residual)[r];
        }
    }

    /// The dense matrix the blocks stand for.
    fn dense(blocks: &NormalBlocks) -> (Dense, Increment) {
        let mut normal = Dense::zeros();
        let mut gradient = Increment::zeros();
        let arrow_index = |k: usize| if k < 6 { k } else { BASE_OFFSET + k - 6 };
        for r in 0..ARROW_PARAMETERS {
            for c in 0..ARROW_PARAMETERS {
                normal[(arrow_index(r), arrow_index(c))] = blocks.arrow[(r, c)];
            }
            gradient[arrow_index(r)] = blocks.arrow_gradient[r];
        }
        for i in 0..MAX_PART_FEATURES {
            let o = FEATURE_OFFSET + 3 * i;
            normal
                .fixed_view_mut::<3, 3>(o, o)
                .copy_from(&blocks.features[i]);
            normal
                .fixed_view_mut::<6, 3>(0, o)
                .copy_from(&blocks.cross[i]);
            normal
                .fixed_view_mut::<3, 6>(o, 0)
                .copy_from(&blocks.cross[i].transpose());
            gradient
                .fixed_view_mut::<3, 1>(o, 0)
                .copy_from(&blocks.feature_gradients[i]);
        }
        (normal, gradient)
    }

    fn dense_frozen(freedom: &Freedom, index: usize) -> bool {
        if (FEATURE_OFFSET..BASE_OFFSET).contains(&index) {
            return (index - FEATURE_OFFSET) / 3 >= freedom.feature_count;
        }
        index >= BASE_OFFSET && !freedom.base_free[index - BASE_OFFSET]
    }

    /// The former dense step: damped copy, held rows and columns to the identity.
    fn dense_step(
        normal: &Dense,
        gradient: &Increment,
        freedom: &Freedom,
        damping: f64,
    ) -> Increment {
        let mut damped = *normal;
        let mut rhs = -gradient;
        for i in 0..PARAMETERS {
            if dense_frozen(freedom, i) {
                damped.row_mut(i).fill(0.0);
                damped.column_mut(i).fill(0.0);
                damped[(i, i)] = 1.0;
                rhs[i] = 0.0;
            } else {
                damped[(i, i)] = damped[(i, i)] * (1.0 + damping) + 1e-12;
            }
        }
        nalgebra::Cholesky::new(damped).unwrap().solve(&rhs)
    }

    /// The former dense covariance: inverse with held rows to the identity.
    fn dense_covariance(normal: &Dense, freedom: &Freedom, variance: f64) -> Dense {
        let mut held = *normal;
        for i in (0..PARAMETERS).filter(|&i| dense_frozen(freedom, i)) {
            held.row_mut(i).fill(0.0);
            held.column_mut(i).fill(0.0);
            held[(i, i)] = 1.0;
        }
        let mut inverse = held.try_inverse().unwrap() * variance;
        for i in (0..PARAMETERS).filter(|&i| dense_frozen(freedom, i)) {
            inverse[(i, i)] = 0.0;
        }
        inverse
    }

    /// Random weighted observations of the arrowhead's shape, into blocks and dense.
    fn random_problem(seed: u64, freedom: &Freedom) -> (NormalBlocks, Dense, Increment) {
        let mut state = seed;
        let mut uniform = move || splitmix(&mut state) - 0.5;
        let mut blocks = NormalBlocks::zeros();
        let (mut normal, mut gradient) = (Dense::zeros(), Increment::zeros());
        let has_base = freedom.base_free.iter().any(|&free| free);
        let mut next_feature = 0;
        for n in 0..160 {
            let camera = SMatrix::<f64, 2, 6>::from_fn(|_, _| uniform());
            let residual = Vector2::new(uniform(), uniform());
            let weight = 1.0 + uniform();
            let other = match n % 4 {
                0 => OtherBlock::None,
                1 if has_base => OtherBlock::Base(SMatrix::<f64, 2, 4>::from_fn(|_, _| uniform())),
                _ => {
                    next_feature += 1;
                    OtherBlock::Feature {
                        index: next_feature % freedom.feature_count,
                        jacobian: Matrix2x3::from_fn(|_, _| uniform()),
                    }
                }
            };
            blocks.accumulate(&camera, &other, &residual, weight);
            dense_accumulate(
                &mut normal,
                &mut gradient,
                &camera,
                &other,
                &residual,
                weight,
            );
        }
        (blocks, normal, gradient)
    }

    const FREEDOMS: [Freedom; 4] = [
        Freedom {
            feature_count: 3,
            base_free: [true; 4],
        },
        Freedom {
            feature_count: 8,
            base_free: [true, true, true, false],
        },
        Freedom {
            feature_count: 2,
            base_free: [false; 4],
        },
        Freedom {
            feature_count: 5,
            base_free: [true; 4],
        },
    ];

    fn relative_gap(a: f64, b: f64) -> f64 {
        (a - b).abs() / b.abs().max(1e-300)
    }

    #[test]
    fn the_blocks_are_the_dense_normal_equations() {
        for (seed, freedom) in FREEDOMS.iter().enumerate() {
            let (blocks, normal, gradient) = random_problem(seed as u64 + 1, freedom);
            let (from_blocks, gradient_from_blocks) = dense(&blocks);
            assert_eq!(from_blocks, normal);
            assert_eq!(gradient_from_blocks, gradient);
        }
    }

    #[test]
    fn the_products_and_sums_are_the_dense_ones() {
        for (seed, freedom) in FREEDOMS.iter().enumerate() {
            let (blocks, normal, gradient) = random_problem(seed as u64 + 50, freedom);
            let (other, other_normal, other_gradient) = random_problem(seed as u64 + 60, freedom);
            let mut state = seed as u64;
            let x = Increment::from_fn(|_, _| splitmix(&mut state) - 0.5);
            let expected = normal * x;
            assert!((blocks.apply(&x) - expected).norm() <= 1e-12 * expected.norm());
            assert_eq!(blocks.gradient(), gradient);
            let mut sum = blocks.clone();
            sum.add(&other, &x);
            let (sum_normal, sum_gradient) = dense(&sum);
            assert!((sum_normal - (normal + other_normal)).norm() <= 1e-12 * normal.norm());
            let expected_gradient = gradient + other_gradient + x;
            assert!((sum_gradient - expected_gradient).norm() <= 1e-12 * expected_gradient.norm());
        }
    }

    #[test]
    fn the_schur_step_is_the_dense_cholesky_step() {
        for seed in 0..24u64 {
            let freedom = FREEDOMS[(seed % 4) as usize];
            let (blocks, normal, gradient) = random_problem(100 + seed, &freedom);
            for damping in [1e-9, 1e-4, 1.0, 1e3] {
                let step = blocks.damped_step(&freedom, damping).unwrap();
                let expected = dense_step(&normal, &gradient, &freedom, damping);
                assert!(
                    (step - expected).norm() <= 1e-10 * expected.norm(),
                    "seed {seed} damping {damping}: {step} vs {expected}"
                );
                for i in (0..PARAMETERS).filter(|&i| dense_frozen(&freedom, i)) {
                    assert_eq!(step[i], 0.0, "held parameter {i} moved");
                }
            }
        }
    }

    #[test]
    fn the_covariance_blocks_are_the_dense_inverse() {
        for seed in 0..24u64 {
            let freedom = FREEDOMS[(seed % 4) as usize];
            let (blocks, normal, _) = random_problem(200 + seed, &freedom);
            let variance = 0.3;
            let covariance = blocks.covariance(&freedom, variance).unwrap();
            let inverse = dense_covariance(&normal, &freedom, variance);
            let arrow_index = |k: usize| if k < 6 { k } else { BASE_OFFSET + k - 6 };
            for r in 0..ARROW_PARAMETERS {
                for c in 0..ARROW_PARAMETERS {
                    let expected = inverse[(arrow_index(r), arrow_index(c))];
                    let got = covariance.camera_and_base[(r, c)];
                    let scale = inverse[(arrow_index(r), arrow_index(r))].abs()
                        + inverse[(arrow_index(c), arrow_index(c))].abs();
                    assert!(
                        (got - expected).abs() <= 1e-10 * scale.max(1e-300),
                        "seed {seed} ({r}, {c}): {got} vs {expected}"
                    );
                }
            }
            let n = freedom.feature_count;
            let mut part = Matrix3::zeros();
            for i in 0..n {
                for j in 0..n {
                    part +=
                        inverse.fixed_view::<3, 3>(FEATURE_OFFSET + 3 * i, FEATURE_OFFSET + 3 * j);
                }
            }
            part /= (n * n) as f64;
            for d in 0..3 {
                assert!(
                    relative_gap(covariance.part_position[(d, d)], part[(d, d)]) <= 1e-10,
                    "seed {seed} axis {d}: {} vs {}",
                    covariance.part_position[(d, d)],
                    part[(d, d)]
                );
            }
            assert!((covariance.part_position - part).norm() <= 1e-10 * part.norm());
            // The part's mean and its yaw line against the camera and base.
            let mut part_cross = PartCross::zeros();
            for c in 0..ARROW_PARAMETERS {
                for i in 0..n {
                    for d in 0..3 {
                        part_cross[(d, c)] +=
                            inverse[(FEATURE_OFFSET + 3 * i + d, arrow_index(c))] / n as f64;
                    }
                }
            }
            let close = |got: &PartCross, expected: &PartCross, what: &str| {
                assert!(
                    (got - expected).norm() <= 1e-10 * expected.norm().max(1e-300),
                    "seed {seed} {what}: {got} vs {expected}"
                );
            };
            close(&covariance.part_and_arrow, &part_cross, "part and arrow");
            if n >= 2 {
                let block = |i: usize, j: usize| {
                    inverse
                        .fixed_view::<3, 3>(FEATURE_OFFSET + 3 * i, FEATURE_OFFSET + 3 * j)
                        .into_owned()
                };
                let line = block(1, 1) + block(0, 0) - block(0, 1) - block(1, 0);
                assert!(
                    (covariance.yaw_line - line).norm() <= 1e-10 * line.norm(),
                    "seed {seed} yaw line"
                );
                let line_cross = PartCross::from_fn(|d, c| {
                    inverse[(FEATURE_OFFSET + 3 + d, arrow_index(c))]
                        - inverse[(FEATURE_OFFSET + d, arrow_index(c))]
                });
                close(
                    &covariance.yaw_line_and_arrow,
                    &line_cross,
                    "yaw line and arrow",
                );
            } else {
                assert_eq!(covariance.yaw_line, Matrix3::zeros());
            }
        }
    }

    #[test]
    fn runs_summed_in_f32_are_the_f64_blocks_to_f32_rounding() {
        for (seed, freedom) in FREEDOMS.iter().enumerate() {
            let (blocks, _, _) = random_problem(seed as u64 + 300, freedom);
            // The same observations again, each run of RUN_POINTS in f32.
            let mut state = seed as u64 + 300;
            let mut uniform = move || splitmix(&mut state) - 0.5;
            let mut mixed = NormalBlocks::zeros();
            let mut run = NormalRun::zeros();
            let has_base = freedom.base_free.iter().any(|&free| free);
            let mut next_feature = 0;
            for n in 0..160u32 {
                let camera = SMatrix::<f64, 2, 6>::from_fn(|_, _| uniform());
                let residual = Vector2::new(uniform(), uniform());
                let weight = 1.0 + uniform();
                let other = match n % 4 {
                    0 => OtherBlock::None,
                    1 if has_base => OtherBlock::Base(
                        SMatrix::<f64, 2, 4>::from_fn(|_, _| uniform()).map(|v| v as f32),
                    ),
                    _ => {
                        next_feature += 1;
                        OtherBlock::Feature {
                            index: next_feature % freedom.feature_count,
                            jacobian: Matrix2x3::from_fn(|_, _| uniform() as f32),
                        }
                    }
                };
                let camera = camera.map(|v| v as f32);
                run.accumulate(&camera, &other, &residual.map(|v| v as f32), weight as f32);
                if (n + 1) % RUN_POINTS == 0 {
                    mixed.add_run(&mut run, freedom.feature_count);
                }
            }
            mixed.add_run(&mut run, freedom.feature_count);
            let (expected, expected_gradient) = dense(&blocks);
            let (got, got_gradient) = dense(&mixed);
            assert!(
                (got - expected).norm() <= 1e-5 * expected.norm(),
                "seed {seed}"
            );
            assert!(
                (got_gradient - expected_gradient).norm() <= 1e-5 * expected_gradient.norm(),
                "seed {seed}"
            );
        }
    }

    #[test]
    fn a_nearly_dependent_parameter_has_a_small_pivot_ratio() {
        let freedom = FREEDOMS[0];
        let (blocks, _, _) = random_problem(11, &freedom);
        let healthy = blocks.weakest_pivot_ratio(&freedom);
        assert!(healthy > 1e-3, "{healthy}");
        // Make the camera's last column all but a copy of its first.
        let mut nearly = NormalBlocks::zeros();
        let mut state = 12;
        for _ in 0..200 {
            let mut camera = SMatrix::<f64, 2, 6>::from_fn(|_, _| splitmix(&mut state) - 0.5);
            for r in 0..2 {
                camera[(r, 5)] = camera[(r, 0)] * (1.0 + 1e-4 * (splitmix(&mut state) - 0.5));
            }
            let jacobian = Matrix2x3::from_fn(|_, _| splitmix(&mut state) - 0.5);
            let index = (splitmix(&mut state) * 3.0) as usize % 3;
            let other = OtherBlock::Feature { index, jacobian };
            let base = OtherBlock::Base(SMatrix::<f64, 2, 4>::from_fn(|_, _| {
                splitmix(&mut state) - 0.5
            }));
            nearly.accumulate(&camera, &other, &Vector2::zeros(), 1.0);
            nearly.accumulate(&camera, &base, &Vector2::zeros(), 1.0);
        }
        let weak = nearly.weakest_pivot_ratio(&freedom);
        assert!(weak < 1e-6, "{weak}");
    }

    #[test]
    fn a_singular_feature_block_fails_the_step_and_the_covariance() {
        let freedom = FREEDOMS[0];
        let (mut blocks, _, _) = random_problem(7, &freedom);
        blocks.features[1] = -Matrix3::identity();
        assert!(blocks.damped_step(&freedom, 1e-4).is_none());
        blocks.features[1] = Matrix3::zeros();
        assert!(blocks.covariance(&freedom, 1.0).is_none());
    }
}
