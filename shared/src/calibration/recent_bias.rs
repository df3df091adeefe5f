//! Beyond the paper: what shows a camera that creeps. A camera knocked aside
//! moves every point at once and the robust gate sees it; one that creeps (a
//! mount settling by half a degree over minutes) moves the latest points a
//! little further from every estimate, and a fit over the whole run averages
//! the creep in: its residuals grow only as the square of the shift, under
//! the noise. The shift itself does not average away: the latest points'
//! mean residual vector leaves zero, all one way, while a cell that holds
//! still keeps it within its noise (`sigma / sqrt(points)`).
//!
//! The mean is kept over windows of [`BIAS_WINDOW_POINTS`] folded points with
//! the sum of their Jacobians, so it can be moved to any later estimate to
//! first order: points folded at a stale estimate are no creep. Sums in f32
//! (the M4F's single-precision unit, a few adds a point): a window's mean is
//! read to a thousandth of a pixel, far below what is tested.

use nalgebra::{SMatrix, Vector2};

use super::model::{OtherBlock, ResidualJacobian, BASE_OFFSET, FEATURE_OFFSET, PARAMETERS};
use super::normal_blocks::Increment;

/// Folded points a window averages (about 40 frames of the part and the disc).
pub const BIAS_WINDOW_POINTS: u32 = 200;

/// The latest full window's mean residual, in measured pixel sigmas, beyond
/// which the camera is taken to creep. A still cell's mean over 200 points
/// has a standard deviation of 0.07 sigma per axis (measured: at most 0.11
/// sigma over the streaming tests); a creep of 0.5 degree over four turns
/// leaves 0.6 to 1.7 sigma.
pub const MAX_RECENT_BIAS_IN_SIGMAS: f64 = 0.4;

/// One window's sums: residuals and their Jacobians over every parameter.
#[derive(Debug, Clone, PartialEq)]
struct WindowSums {
    points: u32,
    residual: Vector2<f32>,
    jacobian: SMatrix<f32, 2, PARAMETERS>,
}

impl WindowSums {
    fn zeros() -> Self {
        Self {
            points: 0,
            residual: Vector2::zeros(),
            jacobian: SMatrix::zeros(),
        }
    }

    /// The mean residual at the increment `d` from where the points were folded.
    fn mean_at(&self, d: &Increment) -> Option<Vector2<f64>> {
        if self.points == 0 {
            return None;
        }
        let d32: SMatrix<f32, PARAMETERS, 1> = d.map(|v| v as f32);
        let sum = self.residual + self.jacobian * d32;
        Some(sum.map(f64::from) / f64::from(self.points))
    }
}

/// The current window and the last full one.
#[derive(Debug, Clone, PartialEq)]
pub struct RecentBias {
    filling: WindowSums,
    last_full: Option<WindowSums>,
}

impl Default for RecentBias {
    fn default() -> Self {
        Self::new()
    }
}

impl RecentBias {
    /// No point yet.
    pub fn new() -> Self {
        Self {
            filling: WindowSums::zeros(),
            last_full: None,
        }
    }

    /// Adds one folded point: its residual and Jacobian where it was folded.
    pub fn add(&mut self, residual: &Vector2<f64>, jacobian: &ResidualJacobian) {
        let window = &mut self.filling;
        window.points = window.points.saturating_add(1);
        window.residual += residual.map(|v| v as f32);
        let mut camera = window.jacobian.fixed_view_mut::<2, 6>(0, 0);
        camera += jacobian.camera.map(|v| v as f32);
        match &jacobian.other {
            OtherBlock::None => {}
            OtherBlock::Feature { index, jacobian } => {
                // Out of range is no feature of the model; such a point adds
                // only its camera part.
                let column = FEATURE_OFFSET.saturating_add(index.saturating_mul(3));
                if column.saturating_add(3) <= BASE_OFFSET {
                    let mut block = window.jacobian.fixed_view_mut::<2, 3>(0, column);
                    block += jacobian.map(|v| v as f32);
                }
            }
            OtherBlock::Base(base) => {
                let mut block = window.jacobian.fixed_view_mut::<2, 4>(0, BASE_OFFSET);
                block += base.map(|v| v as f32);
            }
        }
        if window.points >= BIAS_WINDOW_POINTS {
            self.last_full = Some(core::mem::replace(window, WindowSums::zeros()));
        }
    }

    /// The last full window's mean residual vector (px) at the increment `d`
    /// from the linearisation point its points were folded at; `None` before a
    /// window is full.
    pub fn mean_px(&self, d: &Increment) -> Option<Vector2<f64>> {
        self.last_full.as_ref().and_then(|window| window.mean_at(d))
    }

    /// Re-expresses the sums at a new linearisation point `d` away (the
    /// residuals become `r + J d`), so later increments are taken from there.
    pub fn move_by(&mut self, d: &Increment) {
        let d32: SMatrix<f32, PARAMETERS, 1> = d.map(|v| v as f32);
        for window in core::iter::once(&mut self.filling).chain(self.last_full.as_mut()) {
            window.residual += window.jacobian * d32;
        }
    }

    /// Whether the latest full window's mean at increment `d` stays within
    /// [`MAX_RECENT_BIAS_IN_SIGMAS`] of `pixel_sigma_px` (true before a window
    /// is full, and for a NaN sigma nothing is claimed: false).
    pub fn still(&self, d: &Increment, pixel_sigma_px: f64) -> bool {
        match self.mean_px(d) {
            None => true,
            Some(mean) => mean.norm() <= MAX_RECENT_BIAS_IN_SIGMAS * pixel_sigma_px,
        }
    }
}
