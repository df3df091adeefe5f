//! The rim's ellipse from every pixel near the rim band (module docs of
//! [`super`]): a model of the band explains the pixels, Gauss-Newton moves
//! the ellipse.
//!
//! Why a model and not edge points: the band is one or two pixels wide, so
//! no pixel reads the band's own level and any edge detector's two sides
//! overlap the other edge. The model pays for the band's width with one
//! parameter and reads each edge where a pixel integrates it: a pixel's value
//! is the levels it covers, weighed by how much of it each covers (a
//! one-pixel ramp across each edge, as a sensor's pixel area gives).

use heapless::Vec;
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

use super::ellipse::{Ellipse, Locator};
use super::seed::{near_a_mark, seed_ellipse};
use super::RimError;
use crate::detection::identify::lens::LensModel;
use crate::detection::MAX_BLOBS;
use crate::detection::{Blob, GrayImage};

/// Sectors round the rim, each with its own three levels (light varies
/// round the image; the disc's texture round the disc).
pub const RIM_SECTORS: usize = 32;
/// Most pixels the fit holds; more near the band are taken one in so many.
pub const MAX_RIM_PIXELS: usize = 4096;
/// Ellipse (centre x, y, semi-axes a, b, angle times the mean radius) and
/// the band's width: all in px at the rim, so the steps are alike in scale.
const PARAMETERS: usize = 6;
/// Ramp widths of the first iterations, px: a wide ramp first so that a
/// start a pixel or two off still sees the edges, then the pixel's own.
const RAMP_SCHEDULE: [f64; 3] = [3.0, 2.0, 1.5];
/// The same from the last frame's fit.
const NEAR_SCHEDULE: [f64; 1] = [1.5];
/// A step that moves no edge by more than this (px) ends the iterations:
/// a third of a frame's sigma of the mean radius. The ramps are piecewise
/// linear, so the steps do not shrink to nothing: pixels entering and
/// leaving a ramp keep them at about a thousandth of a pixel.
const CONVERGED_PX: f64 = 2e-3;
/// Finite-difference step of the ellipse's parameters, px.
const STEP_PX: f64 = 1e-4;
/// Bins of 0.25 grey for the residuals' median.
const HISTOGRAM_BINS: usize = 256;
/// Tukey's biweight constant.
const TUKEY: f64 = 4.685;
/// Least scale of the residuals, grey levels: an image without noise still
/// rounds to whole grey levels, and a real edge is no exact ramp, so that
/// a cutoff of a grey level or so would drop the edge pixels themselves.
const MIN_SCALE_GREY: f64 = 1.0;

type Normal = SMatrix<f64, PARAMETERS, PARAMETERS>;
type Gradient = SVector<f64, PARAMETERS>;

/// What the rim fit accepts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RimSettings {
    /// Pixels taken inside the rim, px from the start's outer edge: the band
    /// and a margin of the disc's surface.
    pub inner_reach_px: f64,
    /// Pixels taken outside the rim, px: a margin of the floor.
    pub outer_reach_px: f64,
    /// Least depth of the band's dip on a start ray, grey levels.
    pub min_dip_depth: f64,
    /// Least contrast between band and floor for a sector to count, grey.
    pub min_contrast: f64,
    /// Least sectors that must show the band.
    pub min_sectors: usize,
    /// Least pixels near the band.
    pub min_pixels: usize,
    /// Most Gauss-Newton iterations.
    pub max_iterations: usize,
    /// Pixels within this of a detected mark's extent are not the band's, px.
    pub mark_margin_px: f64,
    /// Farthest the fit may move any edge from its start, px.
    pub max_shift_px: f64,
}

impl Default for RimSettings {
    fn default() -> Self {
        Self {
            inner_reach_px: 6.0,
            outer_reach_px: 3.5,
            min_dip_depth: 10.0,
            min_contrast: 6.0,
            min_sectors: 20,
            min_pixels: 200,
            max_iterations: 14,
            mark_margin_px: 2.5,
            max_shift_px: 3.0,
        }
    }
}

/// The rim measured in one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RimFit {
    /// The rim (the band's outer edge) in undistorted px.
    pub ellipse: Ellipse,
    /// The band's inner edge is the image of the circle `1 - band_fraction`
    /// of the rim's radius ([`Ellipse::concentric`]).
    pub band_fraction: f64,
    /// The disc centre's image that placed the inner edge, undistorted px.
    pub pole_px: [f64; 2],
    /// Covariance of (centre x, centre y, semi-axis a, semi-axis b, angle),
    /// px and rad, from the fit's normal equations and its residuals' scale.
    pub covariance: SMatrix<f64, 5, 5>,
    /// Standard deviation of the mean radius `sqrt(a b)`, px.
    pub sigma_mean_radius_px: f64,
    /// Pixels the fit weighed.
    pub pixels: usize,
    /// Sectors that showed the band.
    pub sectors: usize,
    /// Robust scale of the residuals, grey levels (noise and texture).
    pub noise_grey: f64,
    /// Median contrast between the band and the floor, grey levels.
    pub contrast_grey: f64,
    /// Gauss-Newton iterations taken.
    pub iterations: usize,
    /// How far the last step moved an edge, px.
    pub last_step_px: f64,
}

#[derive(Debug, Clone, Copy, Default)]
struct RimPixel {
    /// Undistorted position, px.
    x: f32,
    y: f32,
    value: f32,
    weight: f32,
}

/// The ellipse and band being fitted, and the disc centre's image that
/// places the band's inner edge ([`Ellipse::concentric`]).
#[derive(Debug, Clone, Copy)]
struct Geometry {
    ellipse: Ellipse,
    band_fraction: f64,
    pole: [f64; 2],
}

/// The band's two edges, ready to place pixels.
#[derive(Debug, Clone, Copy)]
struct Edges {
    outer: Locator,
    inner: Locator,
}

impl Geometry {
    fn radius(&self) -> f64 {
        self.ellipse.mean_radius_px().max(1.0)
    }

    fn edges(&self) -> Option<Edges> {
        Some(Edges {
            outer: self.ellipse.locator(),
            inner: self
                .ellipse
                .concentric(self.pole, self.band_fraction)?
                .locator(),
        })
    }

    /// The edges with parameter `index` moved by `step` px.
    fn nudged(&self, index: usize, step: f64) -> Option<Edges> {
        let mut moved = *self;
        let e = &mut moved.ellipse;
        match index {
            0 => e.centre_px[0] += step,
            1 => e.centre_px[1] += step,
            2 => e.semi_axes_px[0] += step,
            3 => e.semi_axes_px[1] += step,
            4 => e.angle_rad += step / self.radius(),
            _ => moved.band_fraction += step / self.radius(),
        }
        moved.edges()
    }

    fn stepped(&self, step: &Gradient) -> Self {
        let r = self.radius();
        let mut ellipse = self.ellipse;
        ellipse.centre_px[0] += step[0];
        ellipse.centre_px[1] += step[1];
        ellipse.semi_axes_px[0] += step[2];
        ellipse.semi_axes_px[1] += step[3];
        ellipse.angle_rad += step[4] / r;
        Self {
            ellipse,
            band_fraction: self.band_fraction + step[5] / r,
            pole: self.pole,
        }
    }
}

/// A pixel's view of the model: its sector, the three levels' weights and
/// their derivatives along the parameters.
struct Modelled {
    /// Whether the pixel is on an edge's ramp (its Jacobian is not zero).
    on_ramp: bool,
    basis: Vector3<f64>,
    jacobian: SMatrix<f64, 3, PARAMETERS>,
}

fn ramp(d: f64, width: f64) -> (f64, f64) {
    let a = 0.5 - d / width;
    if a <= 0.0 {
        (0.0, 0.0)
    } else if a >= 1.0 {
        (1.0, 0.0)
    } else {
        (a, -1.0 / width)
    }
}

fn sector_of(phase_rad: f64) -> usize {
    let turn = (phase_rad + core::f64::consts::PI) / core::f64::consts::TAU;
    ((turn * RIM_SECTORS as f64) as usize).min(RIM_SECTORS - 1)
}

/// The basis `(floor, band, surface)` of a pixel at `p`: the shares of it
/// each covers, `(1 - a_o, a_o (1 - a_i), a_o a_i)`, and, given the
/// `nudged` edges, its derivatives by finite differences.
fn model(
    edges: &Edges,
    nudged: Option<&[Edges; PARAMETERS]>,
    p: [f64; 2],
    width: f64,
) -> Option<Modelled> {
    let d_outer = edges.outer.distance_px(p)?;
    let d_inner = edges.inner.distance_px(p)?;
    let (a_o, slope_o) = ramp(d_outer, width);
    let (a_i, slope_i) = ramp(d_inner, width);
    let basis = Vector3::new(1.0 - a_o, a_o * (1.0 - a_i), a_o * a_i);
    let mut jacobian = SMatrix::<f64, 3, PARAMETERS>::zeros();
    if let (Some(nudged), true) = (nudged, slope_o != 0.0 || slope_i != 0.0) {
        for (j, moved) in nudged.iter().enumerate() {
            let dd_o = (moved.outer.distance_px(p)? - d_outer) / STEP_PX;
            let dd_i = (moved.inner.distance_px(p)? - d_inner) / STEP_PX;
            let (da_o, da_i) = (slope_o * dd_o, slope_i * dd_i);
            jacobian.set_column(
                j,
                &Vector3::new(
                    -da_o,
                    da_o * (1.0 - a_i) - a_o * da_i,
                    da_o * a_i + a_o * da_i,
                ),
            );
        }
    }
    Some(Modelled {
        on_ramp: slope_o != 0.0 || slope_i != 0.0,
        basis,
        jacobian,
    })
}

/// Each sector's levels `(floor, band, surface)`, or `None` where the sector
/// does not show all three or the band lacks contrast.
fn sector_levels(
    pixels: &[RimPixel],
    geometry: &Geometry,
    width: f64,
    min_contrast: f64,
) -> [Option<Vector3<f64>>; RIM_SECTORS] {
    let mut normal = [Matrix3::<f64>::zeros(); RIM_SECTORS];
    let mut right = [Vector3::<f64>::zeros(); RIM_SECTORS];
    let Some(edges) = geometry.edges() else {
        return [None; RIM_SECTORS];
    };
    for pixel in pixels.iter().filter(|p| p.weight > 0.0) {
        let Some(m) = model(
            &edges,
            None,
            [f64::from(pixel.x), f64::from(pixel.y)],
            width,
        ) else {
            continue;
        };
        let w = f64::from(pixel.weight);
        let sector = sector_of(
            edges
                .outer
                .phase_rad([f64::from(pixel.x), f64::from(pixel.y)]),
        );
        if let (Some(n), Some(r)) = (normal.get_mut(sector), right.get_mut(sector)) {
            *n += m.basis * m.basis.transpose() * w;
            *r += m.basis * (w * f64::from(pixel.value));
        }
    }
    let mut levels = [None; RIM_SECTORS];
    for ((level, n), r) in levels.iter_mut().zip(&normal).zip(&right) {
        // Each level needs a pixel or so of its own.
        if n.diagonal().iter().any(|&d| d < 1.0) {
            continue;
        }
        *level = n
            .cholesky()
            .map(|c| c.solve(r))
            .filter(|l| l.iter().all(|v| v.is_finite()) && (l[0] - l[1]).abs() >= min_contrast);
    }
    levels
}

fn add_to_histogram(histogram: &mut [u32; HISTOGRAM_BINS], counted: &mut u32, residual: f64) {
    let bin = ((residual.abs() / 0.25) as usize).min(HISTOGRAM_BINS - 1);
    if let Some(slot) = histogram.get_mut(bin) {
        *slot += 1;
        *counted += 1;
    }
}

/// Robust scale of the residuals: the median absolute residual over 0.6745.
fn robust_scale(histogram: &[u32; HISTOGRAM_BINS], count: u32) -> f64 {
    let half = count / 2;
    let mut seen = 0;
    for (bin, &n) in histogram.iter().enumerate() {
        if seen + n > half && n > 0 {
            let within = f64::from(half - seen) / f64::from(n);
            return ((bin as f64 + within) * 0.25 / 0.6745).max(MIN_SCALE_GREY);
        }
        seen += n;
    }
    HISTOGRAM_BINS as f64 * 0.25
}

/// Finds the rim frame after frame, in fixed memory.
#[derive(Debug, Clone)]
pub struct RimFinder {
    settings: RimSettings,
    pixels: Vec<RimPixel, MAX_RIM_PIXELS>,
}

impl RimFinder {
    /// Bytes of working memory (the pixels near the band; the sectors' sums
    /// and the start's rays live on the stack while a frame is measured).
    pub const WORKING_MEMORY_BYTES: usize = core::mem::size_of::<Self>();

    /// A finder with the given settings.
    pub fn new(settings: RimSettings) -> Self {
        Self {
            settings,
            pixels: Vec::new(),
        }
    }

    /// The settings.
    pub fn settings(&self) -> &RimSettings {
        &self.settings
    }

    /// Measures the rim in `image`, starting from rays cast out of the disc
    /// centre's image `centre_px` (distorted, as the detector reports it).
    /// `marks` are the detector's blobs, whose pixels are not the band's.
    pub fn find_from_centre(
        &mut self,
        image: &GrayImage<'_>,
        lens: &LensModel,
        marks: &[Blob],
        centre_px: [f64; 2],
    ) -> Result<RimFit, RimError> {
        let seed = seed_ellipse(image, lens, marks, centre_px, self.settings.min_dip_depth)?;
        let pole = lens.undistort(centre_px).ok_or(RimError::CentreOffLens)?;
        // The dips are the band's middle; its outer edge lies about half a
        // band (a pixel or less) outside.
        let r = seed.mean_radius_px().max(1.0);
        let start = Geometry {
            ellipse: Ellipse {
                semi_axes_px: seed.semi_axes_px.map(|a| a + 0.8),
                ..seed
            },
            band_fraction: 1.6 / r,
            pole,
        };
        self.refine(image, lens, marks, start, &RAMP_SCHEDULE)
    }

    /// Measures the rim in `image` from an ellipse known within a pixel or
    /// two (the last frame's), with the disc centre's image `centre_px`
    /// (distorted) where the detector found it this frame.
    pub fn find_near(
        &mut self,
        image: &GrayImage<'_>,
        lens: &LensModel,
        marks: &[Blob],
        last: &RimFit,
        centre_px: Option<[f64; 2]>,
    ) -> Result<RimFit, RimError> {
        let pole = centre_px
            .and_then(|c| lens.undistort(c))
            .unwrap_or(last.pole_px);
        let start = Geometry {
            ellipse: last.ellipse,
            band_fraction: last.band_fraction,
            pole,
        };
        // Within a fraction of a pixel: the pixel's own ramp at once but
        // for one step.
        self.refine(image, lens, marks, start, &NEAR_SCHEDULE)
    }

    /// Takes the pixels within reach of the start's band.
    fn gather(
        &mut self,
        image: &GrayImage<'_>,
        lens: &LensModel,
        marks: &[Blob],
        start: &Geometry,
    ) -> Result<(), RimError> {
        self.pixels.clear();
        let s = &self.settings;
        let r = start.radius();
        let reach_out = 1.0 + s.outer_reach_px / r;
        // The box the outer reach's distorted image spans.
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        let outer = Ellipse {
            semi_axes_px: start.ellipse.semi_axes_px.map(|a| a * reach_out),
            ..start.ellipse
        };
        for k in 0..64 {
            let p = lens.distort(outer.point_at(core::f64::consts::TAU * k as f64 / 64.0));
            for axis in 0..2 {
                if let (Some(l), Some(h), Some(&v)) =
                    (lo.get_mut(axis), hi.get_mut(axis), p.get(axis))
                {
                    *l = l.min(v);
                    *h = h.max(v);
                }
            }
        }
        let clamp = |v: f64, size: usize| (v.max(0.0) as usize).min(size.saturating_sub(1));
        let (x0, x1) = (
            clamp(lo[0] - 2.0, image.width()),
            clamp(hi[0] + 2.0, image.width()),
        );
        let (y0, y1) = (
            clamp(lo[1] - 2.0, image.height()),
            clamp(hi[1] + 2.0, image.height()),
        );
        let locator = start.ellipse.locator();
        let band_px = r * start.band_fraction;
        let (inner_reach, outer_reach) = (s.inner_reach_px, s.outer_reach_px);
        let _ = band_px;
        // The lens moves the rim's pixels by at most this: a pixel farther
        // than the reaches and this from the start (taken at its distorted
        // place) is not looked at closer.
        let lens_shift = (0..32).fold(0.0f64, |m, k| {
            let p = start
                .ellipse
                .point_at(core::f64::consts::TAU * f64::from(k) / 32.0);
            let d = lens.distort(p);
            m.max(libm::hypot(d[0] - p[0], d[1] - p[1]))
        }) + 1.0;
        // The marks near the ring: the only ones a pixel must be checked against.
        let mut near: Vec<Blob, MAX_BLOBS> = Vec::new();
        for mark in marks {
            let reach = f64::from(mark.semi_major_px) + s.mark_margin_px + lens_shift;
            let at = [f64::from(mark.x_px), f64::from(mark.y_px)];
            if locator
                .distance_px(at)
                .is_some_and(|d| d <= outer_reach + reach && d >= -(inner_reach + reach))
            {
                // More marks than the detector gives cannot come.
                let _ = near.push(*mark);
            }
        }
        let (width, height) = (image.width(), image.height());
        let mut stride = 1usize;
        loop {
            self.pixels.clear();
            let mut index = 0usize;
            let mut overflow = false;
            'rows: for v in y0.max(1)..=y1.min(height.saturating_sub(2)) {
                let row = image.row(v);
                // The image's border row and column are not trusted.
                for u in x0.max(1)..=x1.min(width.saturating_sub(2)) {
                    let Some(&value) = row.get(u) else { continue };
                    let (uf, vf) = (u as f64, v as f64);
                    let rough = locator.distance_px([uf, vf]);
                    if !rough.is_some_and(|d| {
                        d <= outer_reach + lens_shift && d >= -(inner_reach + lens_shift)
                    }) {
                        continue;
                    }
                    if near_a_mark(&near, uf, vf, s.mark_margin_px) {
                        continue;
                    }
                    let Some(p) = lens.undistort([uf, vf]) else {
                        continue;
                    };
                    if !locator
                        .distance_px(p)
                        .is_some_and(|d| d <= outer_reach && d >= -inner_reach)
                    {
                        continue;
                    }
                    index += 1;
                    if !(index - 1).is_multiple_of(stride) {
                        continue;
                    }
                    let pixel = RimPixel {
                        x: p[0] as f32,
                        y: p[1] as f32,
                        value: f32::from(value),
                        weight: 1.0,
                    };
                    if self.pixels.push(pixel).is_err() {
                        overflow = true;
                        break 'rows;
                    }
                }
            }
            if !overflow {
                break;
            }
            stride *= 2;
        }
        if self.pixels.len() < s.min_pixels {
            return Err(RimError::TooFewPixels {
                found: self.pixels.len(),
                needed: s.min_pixels,
            });
        }
        Ok(())
    }

    fn refine(
        &mut self,
        image: &GrayImage<'_>,
        lens: &LensModel,
        marks: &[Blob],
        start: Geometry,
        schedule: &[f64],
    ) -> Result<RimFit, RimError> {
        self.gather(image, lens, marks, &start)?;
        let settings = self.settings;
        let mut geometry = start;
        let mut last: Option<(Normal, f64, usize, usize, f64)> = None;
        let mut iterations = 0;
        let mut scale: Option<f64> = None;
        let mut last_step_px = f64::INFINITY;
        for iteration in 0..settings.max_iterations {
            iterations = iteration + 1;
            let width = schedule.get(iteration).copied().unwrap_or(1.0);
            let levels = sector_levels(&self.pixels, &geometry, width, settings.min_contrast);
            let sectors = levels.iter().filter(|l| l.is_some()).count();
            if sectors < settings.min_sectors {
                return Err(RimError::TooFewSectors {
                    used: sectors,
                    needed: settings.min_sectors,
                });
            }
            let edges = geometry.edges().ok_or(RimError::Degenerate)?;
            let mut nudged = [edges; PARAMETERS];
            for (j, slot) in nudged.iter_mut().enumerate() {
                *slot = geometry.nudged(j, STEP_PX).ok_or(RimError::Degenerate)?;
            }
            let at = |pixel: &RimPixel, nudged: Option<&[Edges; PARAMETERS]>| {
                let m = model(
                    &edges,
                    nudged,
                    [f64::from(pixel.x), f64::from(pixel.y)],
                    width,
                )?;
                let sector = sector_of(
                    edges
                        .outer
                        .phase_rad([f64::from(pixel.x), f64::from(pixel.y)]),
                );
                let level = levels.get(sector).copied().flatten()?;
                Some((
                    f64::from(pixel.value) - level.dot(&m.basis),
                    level,
                    m,
                    sector,
                ))
            };
            // The residuals' scale: the last pass's, or a pass of its own
            // the first time.
            let sigma = match scale {
                Some(sigma) => sigma,
                None => {
                    let mut histogram = [0u32; HISTOGRAM_BINS];
                    let mut counted = 0u32;
                    for (residual, _, _, _) in self.pixels.iter().filter_map(|p| at(p, None)) {
                        add_to_histogram(&mut histogram, &mut counted, residual);
                    }
                    robust_scale(&histogram, counted)
                }
            };
            let cutoff = TUKEY * sigma;
            let mut normal = Normal::zeros();
            let mut gradient = Gradient::zeros();
            // The levels' blocks, per sector: the step below eliminates them
            // (variable projection: a step that ignored how the levels
            // follow the edges crept to the optimum a little each iteration).
            let mut level_normal = [Matrix3::<f64>::zeros(); RIM_SECTORS];
            let mut cross = [SMatrix::<f64, PARAMETERS, 3>::zeros(); RIM_SECTORS];
            let mut level_gradient = [Vector3::<f64>::zeros(); RIM_SECTORS];
            let mut used = 0usize;
            let mut histogram = [0u32; HISTOGRAM_BINS];
            let mut counted = 0u32;
            for pixel in self.pixels.iter_mut() {
                let Some((residual, level, m, sector)) = at(pixel, Some(&nudged)) else {
                    // A sector without levels this time: its pixels are
                    // looked at again when its levels are next solved.
                    pixel.weight = 1.0;
                    continue;
                };
                add_to_histogram(&mut histogram, &mut counted, residual);
                let u = residual / cutoff;
                if u.abs() >= 1.0 {
                    pixel.weight = 0.0;
                    continue;
                }
                let w = (1.0 - u * u) * (1.0 - u * u);
                pixel.weight = w as f32;
                used += 1;
                if let (Some(v), Some(g)) =
                    (level_normal.get_mut(sector), level_gradient.get_mut(sector))
                {
                    *v += m.basis * m.basis.transpose() * w;
                    *g += m.basis * (w * residual);
                }
                // Off both ramps a pixel's row is zero: it adds nothing to
                // the edges' blocks (most pixels; the sums are the same).
                if m.on_ramp {
                    let row = level.transpose() * m.jacobian;
                    normal += row.transpose() * row * w;
                    gradient += row.transpose() * (w * residual);
                    if let Some(c) = cross.get_mut(sector) {
                        *c += row.transpose() * m.basis.transpose() * w;
                    }
                }
            }
            for ((v, c), g) in level_normal.iter().zip(&cross).zip(&level_gradient) {
                if let Some(f) = v.cholesky() {
                    normal -= c * f.solve(&c.transpose());
                    gradient -= c * f.solve(g);
                }
            }
            scale = Some(robust_scale(&histogram, counted));
            let contrast = median_contrast(&levels);
            // A light damping keeps a step across a flat ramp finite.
            let mut damped = normal;
            for k in 0..PARAMETERS {
                if let Some(d) = damped.get_mut((k, k)) {
                    *d += 1e-6 * (*d).max(1.0);
                }
            }
            let step = damped
                .cholesky()
                .map(|c| c.solve(&gradient))
                .filter(|s| s.iter().all(|v| v.is_finite()))
                .ok_or(RimError::Degenerate)?;
            last = Some((normal, scale.unwrap_or(sigma), used, sectors, contrast));
            let before = geometry;
            geometry = geometry.stepped(&step);

            let moved = (geometry.ellipse.centre_px[0] - start.ellipse.centre_px[0]).abs()
                + (geometry.ellipse.centre_px[1] - start.ellipse.centre_px[1]).abs()
                + (geometry.radius() - start.radius()).abs();
            if !geometry.ellipse.is_valid()
                || moved > settings.max_shift_px
                || !(0.0..0.5).contains(&geometry.band_fraction)
            {
                return Err(RimError::Diverged);
            }
            // How far the edges moved (an angle step of a near-circle moves
            // nothing), and the band's width.
            let locator = geometry.ellipse.locator();
            let moved_edge = (0..16).fold(0.0f64, |m, k| {
                let p = before
                    .ellipse
                    .point_at(core::f64::consts::TAU * f64::from(k) / 16.0);
                m.max(locator.distance_px(p).map_or(f64::INFINITY, f64::abs))
            });
            let largest = moved_edge.max(step.get(5).map_or(0.0, |s| s.abs()));
            last_step_px = largest;
            if width <= 1.0 && largest < CONVERGED_PX {
                break;
            }
        }
        let (normal, sigma, pixels, sectors, contrast) = last.ok_or(RimError::Degenerate)?;
        let inverse = normal.try_inverse().ok_or(RimError::Degenerate)?;
        let r = geometry.radius();
        // From (.., angle * r, ..) to (.., angle).
        let mut to_angle = SMatrix::<f64, 5, PARAMETERS>::zeros();
        for k in 0..4 {
            if let Some(v) = to_angle.get_mut((k, k)) {
                *v = 1.0;
            }
        }
        if let Some(v) = to_angle.get_mut((4, 4)) {
            *v = 1.0 / r;
        }
        let covariance = to_angle * inverse * to_angle.transpose() * (sigma * sigma);
        let [a, b] = geometry.ellipse.semi_axes_px;
        let radius_row = SMatrix::<f64, 1, 5>::new(0.0, 0.0, 0.5 * b / r, 0.5 * a / r, 0.0);
        let radius_variance = (radius_row * covariance * radius_row.transpose()).x;
        Ok(RimFit {
            ellipse: geometry.ellipse,
            band_fraction: geometry.band_fraction,
            pole_px: geometry.pole,
            covariance,
            sigma_mean_radius_px: libm::sqrt(radius_variance.max(0.0)),
            pixels,
            sectors,
            noise_grey: sigma,
            contrast_grey: contrast,
            iterations,
            last_step_px,
        })
    }
}

/// Median of the sectors' `|floor - band|`.
fn median_contrast(levels: &[Option<Vector3<f64>>; RIM_SECTORS]) -> f64 {
    let mut contrasts = [0.0f64; RIM_SECTORS];
    let mut count = 0;
    for (slot, level) in contrasts.iter_mut().zip(levels.iter().flatten()) {
        *slot = (level[0] - level[1]).abs();
        count += 1;
    }
    let used = contrasts.get_mut(..count).unwrap_or(&mut []);
    used.sort_unstable_by(f64::total_cmp);
    used.get(count / 2).copied().unwrap_or(0.0)
}
