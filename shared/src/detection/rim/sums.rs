//! One pass's sums over the rim's pixels: the normal equations of the
//! edges and of each sector's three levels, and the residuals' robust
//! scale. `f32` with the pixels (the Cortex-M4F's unit), `f64` once the
//! levels are eliminated.

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

use super::model::{Row, PARAMETERS};
use super::pixels::RIM_SECTORS;

/// The edges' normal matrix, `f64`.
pub type Normal = SMatrix<f64, PARAMETERS, PARAMETERS>;
/// The edges' gradient (and step), `f64`.
pub type Gradient = SVector<f64, PARAMETERS>;
/// Each sector's levels `(floor, band, surface)`, `None` where a sector
/// does not show the band.
pub type Levels = [Option<Vector3<f32>>; RIM_SECTORS];

/// Bins of 0.25 grey for the residuals' median.
const HISTOGRAM_BINS: usize = 256;
/// Least scale of the residuals, grey levels: an image without noise still
/// rounds to whole grey levels, and a real edge is no exact ramp, so that
/// a cutoff of a grey level or so would drop the edge pixels themselves.
const MIN_SCALE_GREY: f64 = 1.0;
/// Entries of a symmetric 6 x 6 matrix's upper triangle.
const PACKED: usize = PARAMETERS * (PARAMETERS + 1) / 2;

/// One pass's sums, before the levels are eliminated.
pub struct PassSums {
    /// The edges' block, its upper triangle row by row.
    normal: [f32; PACKED],
    gradient: SVector<f32, PARAMETERS>,
    /// The levels' blocks, per sector.
    level_normal: [Matrix3<f32>; RIM_SECTORS],
    cross: [SMatrix<f32, PARAMETERS, 3>; RIM_SECTORS],
    level_gradient: [Vector3<f32>; RIM_SECTORS],
    used: usize,
    histogram: [u32; HISTOGRAM_BINS],
    counted: u32,
}

impl Default for PassSums {
    /// Nothing summed.
    fn default() -> Self {
        Self {
            normal: [0.0; PACKED],
            gradient: SVector::zeros(),
            level_normal: [Matrix3::zeros(); RIM_SECTORS],
            cross: [SMatrix::zeros(); RIM_SECTORS],
            level_gradient: [Vector3::zeros(); RIM_SECTORS],
            used: 0,
            histogram: [0; HISTOGRAM_BINS],
            counted: 0,
        }
    }
}

impl PassSums {
    /// Pixels that added to the sums.
    pub fn used(&self) -> usize {
        self.used
    }

    /// Counts a residual towards the robust scale.
    #[inline]
    pub fn count_residual(&mut self, residual: f32) {
        let bin = ((residual.abs() * 4.0) as usize).min(HISTOGRAM_BINS - 1);
        if let Some(slot) = self.histogram.get_mut(bin) {
            *slot += 1;
            self.counted += 1;
        }
    }

    /// Robust scale of the residuals counted: their median absolute value
    /// over 0.6745, grey levels.
    pub fn robust_scale(&self) -> f64 {
        let half = self.counted / 2;
        let mut seen = 0;
        for (bin, &n) in self.histogram.iter().enumerate() {
            if seen + n > half && n > 0 {
                let within = f64::from(half - seen) / f64::from(n);
                return ((bin as f64 + within) * 0.25 / 0.6745).max(MIN_SCALE_GREY);
            }
            seen += n;
        }
        HISTOGRAM_BINS as f64 * 0.25
    }

    /// A pixel off both ramps, wholly in `zone` (0 floor, 1 band, 2 the
    /// disc's surface): it tells that level only.
    #[inline]
    pub fn add_level_only(&mut self, sector: usize, zone: usize, w: f32, residual: f32) {
        self.used += 1;
        if let (Some(v), Some(g)) = (
            self.level_normal
                .get_mut(sector)
                .and_then(|v| v.get_mut((zone, zone))),
            self.level_gradient
                .get_mut(sector)
                .and_then(|g| g.get_mut(zone)),
        ) {
            *v += w;
            *g += w * residual;
        }
    }

    /// A pixel on a ramp, with its shares `basis` of the levels and its
    /// `row` along the edges' parameters.
    #[inline]
    pub fn add(&mut self, sector: usize, basis: &Vector3<f32>, row: &Row, w: f32, residual: f32) {
        self.used += 1;
        let wb = basis * w;
        if let (Some(v), Some(g), Some(c)) = (
            self.level_normal.get_mut(sector),
            self.level_gradient.get_mut(sector),
            self.cross.get_mut(sector),
        ) {
            *v += wb * basis.transpose();
            *g += wb * residual;
            *c += row * wb.transpose();
        }
        let wr = row * w;
        self.gradient += wr * residual;
        // The upper triangle, row by row.
        let [r0, r1, r2, r3, r4, r5] = [row.x, row.y, row.z, row.w, row.a, row.b];
        let [w0, w1, w2, w3, w4, w5] = [wr.x, wr.y, wr.z, wr.w, wr.a, wr.b];
        let products = [
            w0 * r0,
            w0 * r1,
            w0 * r2,
            w0 * r3,
            w0 * r4,
            w0 * r5,
            w1 * r1,
            w1 * r2,
            w1 * r3,
            w1 * r4,
            w1 * r5,
            w2 * r2,
            w2 * r3,
            w2 * r4,
            w2 * r5,
            w3 * r3,
            w3 * r4,
            w3 * r5,
            w4 * r4,
            w4 * r5,
            w5 * r5,
        ];
        for (slot, p) in self.normal.iter_mut().zip(products) {
            *slot += p;
        }
    }

    /// The edges' block as a full matrix.
    fn normal_matrix(&self) -> SMatrix<f32, PARAMETERS, PARAMETERS> {
        let mut full = SMatrix::<f32, PARAMETERS, PARAMETERS>::zeros();
        let mut slots = self.normal.iter();
        for i in 0..PARAMETERS {
            for j in i..PARAMETERS {
                let value = slots.next().copied().unwrap_or(0.0);
                if let Some(upper) = full.get_mut((i, j)) {
                    *upper = value;
                }
                if let Some(lower) = full.get_mut((j, i)) {
                    *lower = value;
                }
            }
        }
        full
    }

    /// The edges' normal equations with the levels eliminated per sector by
    /// the Schur complement (variable projection: a step that ignored how
    /// the levels follow the edges crept to the optimum a little each
    /// iteration), in `f64`.
    pub fn reduced(&self) -> (Normal, Gradient) {
        let mut normal = self.normal_matrix();
        let mut gradient = self.gradient;
        for ((v, c), g) in self
            .level_normal
            .iter()
            .zip(&self.cross)
            .zip(&self.level_gradient)
        {
            if let Some(f) = v.cholesky() {
                normal -= c * f.solve(&c.transpose());
                gradient -= c * f.solve(g);
            }
        }
        (normal.cast(), gradient.cast())
    }

    /// Moves each sector's levels by their part of the joint step, given
    /// the edges' `step`: `V^-1 (g_l - C^T step)`. A sector whose band
    /// loses its contrast drops out.
    pub fn step_levels(&self, levels: &mut Levels, step: &Gradient, min_contrast: f64) {
        let step = step.cast::<f32>();
        for (((level, v), c), g) in levels
            .iter_mut()
            .zip(&self.level_normal)
            .zip(&self.cross)
            .zip(&self.level_gradient)
        {
            let Some(now) = level else { continue };
            // A zone the robust weight all but empties makes its level
            // loose, its pixels' residuals large and their weights nil: the
            // zone then fails the Cholesky and the sector drops out.
            let moved = v.cholesky().map(|f| f.solve(&(g - c.transpose() * step)));
            *level = moved.map(|m| *now + m).filter(|l| {
                l.iter().all(|v| v.is_finite()) && f64::from((l[0] - l[1]).abs()) >= min_contrast
            });
        }
    }
}
