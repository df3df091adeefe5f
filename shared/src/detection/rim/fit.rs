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

use nalgebra::{Matrix3, SMatrix, Vector3};

use super::ellipse::{Ellipse, Locator};
use super::model::{
    concentric_coefficients, ellipse_coefficients, EdgeConic, PixelModel, PARAMETERS,
};
use super::pixels::{Classified, PassPixel, RimPixels, ZONE_NEAR};
pub use super::pixels::{MAX_RIM_PIXELS, RIM_SECTORS};
use super::seed::seed_ellipse;
use super::sums::{Gradient, Levels, Normal, PassSums};
use super::RimError;
use crate::detection::identify::lens::LensModel;
use crate::detection::{Blob, GrayImage};

// A pass reads a zoned pixel's level as `levels[zone]`: the zones are the
// three levels' indices, and "near" is the first index past them.
const _: () = assert!(ZONE_NEAR == 3);

/// Ramp widths of the first iterations from the disc centre, px: a wide
/// ramp first so that a start a pixel or two off still sees the edges, then
/// the pixel's own (1 px).
const RAMP_SCHEDULE: [f64; 3] = [3.0, 2.0, 1.5];
/// From the last frame's fit, a hundredth of a pixel off: the pixel's own
/// ramp at once (a wider ramp's optimum lies tenths of a pixel away).
const NEAR_SCHEDULE: [f64; 0] = [];
/// The pixel's own ramp, px: the width after a schedule.
const PIXEL_RAMP_PX: f64 = 1.0;
/// A first step from the last frame's fit longer than this, px, means the
/// rim moved (the camera was knocked): the fit gives up, and the caller
/// starts again from the disc centre.
const NEAR_TRUST_PX: f64 = 0.25;
/// A step that moves no edge by more than this (px) ends the iterations:
/// a third of a frame's sigma of the mean radius. The ramps are piecewise
/// linear, so the steps do not shrink to nothing: pixels entering and
/// leaving a ramp keep them at about a thousandth of a pixel.
const CONVERGED_PX: f64 = 2e-3;
/// Finite-difference step of the edges' coefficients along the
/// parameters, px.
const STEP_PX: f64 = 1e-4;
/// A pixel's zone is worked out with the ramps this much wider, px, and
/// kept while the edges move less than half of it.
const ZONE_MARGIN_PX: f64 = 0.4;
/// Tukey's biweight constant.
const TUKEY: f64 = 4.685;

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

/// The ellipse and band being fitted, and the disc centre's image that
/// places the band's inner edge ([`Ellipse::concentric`]).
#[derive(Debug, Clone, Copy)]
struct Geometry {
    ellipse: Ellipse,
    band_fraction: f64,
    pole: [f64; 2],
}

impl Geometry {
    fn radius(&self) -> f64 {
        self.ellipse.mean_radius_px().max(1.0)
    }

    /// The two edges' coefficients relative to `origin`, given the sine
    /// and cosine of the ellipse's angle.
    fn coefficients(&self, turn: (f64, f64), origin: [f64; 2]) -> Option<[[f64; 6]; 2]> {
        let outer = ellipse_coefficients(&self.ellipse, turn, origin);
        let pole = [self.pole[0] - origin[0], self.pole[1] - origin[1]];
        let inner = concentric_coefficients(&outer, pole, self.band_fraction)?;
        Some([outer, inner])
    }

    /// The two edges relative to `origin`, with their coefficients'
    /// derivatives along the parameters (forward differences in `f64`, once
    /// an iteration: the pencil that places the inner edge has no
    /// closed-form derivative worth its code).
    fn edges(&self, turn: (f64, f64), origin: [f64; 2]) -> Option<(EdgeConic, EdgeConic)> {
        let r = self.radius();
        let [outer, inner] = self.coefficients(turn, origin)?;
        let mut chains = [SMatrix::<f64, 6, PARAMETERS>::zeros(); 2];
        for j in 0..PARAMETERS {
            let mut moved = *self;
            let mut moved_turn = turn;
            match j {
                0 => moved.ellipse.centre_px[0] += STEP_PX,
                1 => moved.ellipse.centre_px[1] += STEP_PX,
                2 => moved.ellipse.semi_axes_px[0] += STEP_PX,
                3 => moved.ellipse.semi_axes_px[1] += STEP_PX,
                4 => {
                    moved.ellipse.angle_rad += STEP_PX / r;
                    moved_turn = libm::sincos(moved.ellipse.angle_rad);
                }
                _ => moved.band_fraction += STEP_PX / r,
            }
            let now = moved.coefficients(moved_turn, origin)?;
            for ((chain, after), before) in chains.iter_mut().zip(&now).zip([&outer, &inner]) {
                for (k, (a, b)) in after.iter().zip(before).enumerate() {
                    if let Some(slot) = chain.get_mut((k, j)) {
                        *slot = (a - b) / STEP_PX;
                    }
                }
            }
        }
        let [outer_chain, inner_chain] = chains;
        Some((
            EdgeConic::new(outer, outer_chain)?,
            EdgeConic::new(inner, inner_chain)?,
        ))
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

/// The pixel's model: from its zone where the zones hold, else placed
/// against the edges.
#[inline]
fn model_of(
    pixel: &PassPixel,
    outer: &EdgeConic,
    inner: &EdgeConic,
    width: f32,
) -> Option<PixelModel> {
    if pixel.zone < ZONE_NEAR {
        Some(PixelModel::in_zone(pixel.zone))
    } else {
        PixelModel::at(outer, inner, pixel.x, pixel.y, width)
    }
}

/// Works out the pixels' zones again unless the edges moved less than half
/// of [`ZONE_MARGIN_PX`] from where they were last worked out (the 16
/// points [`largest_move`] looks at, the band's width and the pole), for
/// ramps no wider.
fn keep_zones(
    pixels: &mut RimPixels,
    geometry: &Geometry,
    turn: (f64, f64),
    edges: &(EdgeConic, EdgeConic),
    width: f64,
) {
    let band_px = geometry.band_fraction * geometry.radius();
    if let Some(c) = pixels.classified() {
        // The inner edge follows the pole by about the band's fraction.
        let pole_moved = libm::hypot(
            c.pole_px[0] - geometry.pole[0],
            c.pole_px[1] - geometry.pole[1],
        );
        let moved = largest_move(&c.ellipse, c.turn, &geometry.ellipse.locator())
            + (c.band_px - band_px).abs()
            + pole_moved * geometry.band_fraction;
        if width <= c.width_px && moved < 0.5 * ZONE_MARGIN_PX {
            return;
        }
    }
    let (outer, inner) = edges;
    let half = (0.5 * width + ZONE_MARGIN_PX) as f32;
    pixels.classify(
        Classified {
            ellipse: geometry.ellipse,
            turn,
            band_px,
            pole_px: geometry.pole,
            width_px: width,
        },
        |x, y| PixelModel::zone_at(outer, inner, x, y, half, ZONE_NEAR),
    );
}

/// Solves the levels `(floor, band, surface)` of each sector that has none
/// in `levels`; a sector that does not show all three, or whose band lacks
/// contrast, stays `None`.
fn fill_levels(
    pixels: &RimPixels,
    (outer, inner): &(EdgeConic, EdgeConic),
    width: f32,
    min_contrast: f64,
    levels: &mut Levels,
) {
    let mut wanted = [false; RIM_SECTORS];
    for (want, level) in wanted.iter_mut().zip(levels.iter()) {
        *want = level.is_none();
    }
    if !wanted.contains(&true) {
        return;
    }
    let mut normal = [Matrix3::<f32>::zeros(); RIM_SECTORS];
    let mut right = [Vector3::<f32>::zeros(); RIM_SECTORS];
    for pixel in pixels.pass() {
        if !wanted.get(pixel.sector).copied().unwrap_or(false) {
            continue;
        }
        let Some(m) = model_of(&pixel, outer, inner, width) else {
            continue;
        };
        if let (Some(n), Some(r)) = (normal.get_mut(pixel.sector), right.get_mut(pixel.sector)) {
            *n += m.basis * m.basis.transpose();
            *r += m.basis * pixel.value;
        }
    }
    for (((level, n), r), want) in levels.iter_mut().zip(&normal).zip(&right).zip(wanted) {
        // Each level needs a pixel or so of its own.
        if !want || n.diagonal().iter().any(|&d| d < 1.0) {
            continue;
        }
        *level = n.cholesky().map(|c| c.solve(r)).filter(|l| {
            l.iter().all(|v| v.is_finite()) && f64::from((l[0] - l[1]).abs()) >= min_contrast
        });
    }
}

/// What the last fit leaves the next frame's: its band, each sector's
/// levels and the residuals' scale. The light changes little from one
/// frame to the next, and the first joint step corrects the levels
/// exactly (the model is linear in them) for the pixels the robust weight
/// keeps, so the next frame needs no pass of its own to find them. Where
/// the light jumps and the fit fails, it is tried again without them.
#[derive(Debug, Clone, Copy)]
struct Carried {
    ellipse: Ellipse,
    band_fraction: f64,
    levels: Levels,
    scale: f64,
}

/// Finds the rim frame after frame, in fixed memory.
#[derive(Debug, Clone)]
pub struct RimFinder {
    settings: RimSettings,
    pixels: RimPixels,
    carried: Option<Carried>,
}

impl RimFinder {
    /// Bytes of working memory (the pixels near the band and the last
    /// fit's levels; a pass's sums and the start's rays live on the stack
    /// while a frame is measured).
    pub const WORKING_MEMORY_BYTES: usize = core::mem::size_of::<Self>();

    /// A finder with the given settings.
    pub fn new(settings: RimSettings) -> Self {
        Self {
            settings,
            pixels: RimPixels::default(),
            carried: None,
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
        self.pixels.forget();
        self.carried = None;
        self.refine(image, lens, marks, start, (&RAMP_SCHEDULE, f64::INFINITY))
    }

    /// Measures the rim in `image` from an ellipse known within a fraction
    /// of a pixel (the last frame's), with the disc centre's image
    /// `centre_px` (distorted) where the detector found it this frame. A
    /// rim that moved farther gives [`RimError::Diverged`]: start again
    /// with [`Self::find_from_centre`].
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
        // The levels and scale carry over only from this very fit.
        self.carried = self
            .carried
            .filter(|c| c.ellipse == last.ellipse && c.band_fraction == last.band_fraction);
        self.refine(image, lens, marks, start, (&NEAR_SCHEDULE, NEAR_TRUST_PX))
    }

    /// One pass over the pixels at the edges: the residuals' histogram,
    /// and with `cutoff` (Tukey's) the sums.
    fn pass(
        &self,
        edges: &(EdgeConic, EdgeConic),
        levels: &Levels,
        width: f32,
        cutoff: Option<f32>,
    ) -> PassSums {
        let (outer, inner) = edges;
        let mut sums = PassSums::default();
        let weight = |residual: f32| {
            let u = residual / cutoff?;
            (u.abs() < 1.0).then_some((1.0 - u * u) * (1.0 - u * u))
        };
        for pixel in self.pixels.pass() {
            // A sector without levels this frame is left out.
            let Some(level) = levels.get(pixel.sector).copied().flatten() else {
                continue;
            };
            // A pixel off both ramps (most) is its zone's level and no
            // more: no model to build.
            if let Some(zone_level) = level.get(usize::from(pixel.zone)) {
                let residual = pixel.value - zone_level;
                sums.count_residual(residual);
                if let Some(w) = weight(residual) {
                    sums.add_level_only(pixel.sector, usize::from(pixel.zone), w, residual);
                }
                continue;
            }
            let Some(m) = PixelModel::at(outer, inner, pixel.x, pixel.y, width) else {
                continue;
            };
            let residual = pixel.value - level.dot(&m.basis);
            sums.count_residual(residual);
            let Some(w) = weight(residual) else { continue };
            match m.zone() {
                // Off both ramps a pixel's row is zero: it only tells its
                // zone's level (most pixels).
                Some(zone) => sums.add_level_only(pixel.sector, zone, w, residual),
                None => {
                    let row = m.row(outer, inner, &level, pixel.x, pixel.y);
                    sums.add(pixel.sector, &m.basis, &row, w, residual);
                }
            }
        }
        sums
    }

    fn refine(
        &mut self,
        image: &GrayImage<'_>,
        lens: &LensModel,
        marks: &[Blob],
        start: Geometry,
        schedule: (&[f64], f64),
    ) -> Result<RimFit, RimError> {
        let carried = self.carried.take();
        let (fit, levels) = match self.iterate(image, lens, marks, start, schedule, carried) {
            // The light jumped (the last levels' cutoff refused whole
            // zones): once more with levels and scale of this frame's own.
            Err(_) if carried.is_some() => self.iterate(image, lens, marks, start, schedule, None),
            result => result,
        }?;
        self.carried = Some(Carried {
            ellipse: fit.ellipse,
            band_fraction: fit.band_fraction,
            levels,
            scale: fit.noise_grey,
        });
        Ok(fit)
    }

    /// Gauss-Newton from `start`, with the levels and scale `carried` from
    /// the last frame where there are; the fit and its final levels.
    fn iterate(
        &mut self,
        image: &GrayImage<'_>,
        lens: &LensModel,
        marks: &[Blob],
        start: Geometry,
        (schedule, trust_px): (&[f64], f64),
        carried: Option<Carried>,
    ) -> Result<(RimFit, Levels), RimError> {
        let settings = self.settings;
        self.pixels.gather(
            image,
            lens,
            &start.ellipse,
            (settings.inner_reach_px, settings.outer_reach_px),
        );
        let found = self.pixels.load(image, marks, settings.mark_margin_px);
        if found < settings.min_pixels {
            return Err(RimError::TooFewPixels {
                found,
                needed: settings.min_pixels,
            });
        }
        let origin = self.pixels.origin_px();
        let mut geometry = start;
        let mut last: Option<(Normal, f64, usize, usize, f64)> = None;
        let mut iterations = 0;
        let mut scale: Option<f64> = carried.map(|c| c.scale);
        let mut last_step_px = f64::INFINITY;
        // The levels at the start (the last frame's where they are, a pass
        // of their own for the sectors without); each step below moves
        // them with the edges (the joint Gauss-Newton step, with the
        // levels eliminated).
        let mut levels = carried.map_or([None; RIM_SECTORS], |c| c.levels);
        // The start's edges serve the first iteration too.
        let mut start_edges = {
            let width = schedule.first().copied().unwrap_or(PIXEL_RAMP_PX);
            let turn = libm::sincos(geometry.ellipse.angle_rad);
            let edges = geometry.edges(turn, origin).ok_or(RimError::Degenerate)?;
            keep_zones(&mut self.pixels, &geometry, turn, &edges, width);
            fill_levels(
                &self.pixels,
                &edges,
                width as f32,
                settings.min_contrast,
                &mut levels,
            );
            Some((turn, edges))
        };
        for iteration in 0..settings.max_iterations {
            iterations = iteration + 1;
            let width = schedule.get(iteration).copied().unwrap_or(PIXEL_RAMP_PX);
            let sectors = levels.iter().filter(|l| l.is_some()).count();
            if sectors < settings.min_sectors {
                return Err(RimError::TooFewSectors {
                    used: sectors,
                    needed: settings.min_sectors,
                });
            }
            // (The start's zones were kept with its edges.)
            let (turn, edges) = match start_edges.take() {
                Some(ready) => ready,
                None => {
                    let turn = libm::sincos(geometry.ellipse.angle_rad);
                    let edges = geometry.edges(turn, origin).ok_or(RimError::Degenerate)?;
                    keep_zones(&mut self.pixels, &geometry, turn, &edges, width);
                    (turn, edges)
                }
            };
            // The residuals' scale: the last pass's, or a pass of its own
            // the first time.
            let sigma = match scale {
                Some(sigma) => sigma,
                None => {
                    let sums = self.pass(&edges, &levels, width as f32, None);
                    sums.robust_scale()
                }
            };
            let sums = self.pass(&edges, &levels, width as f32, Some((TUKEY * sigma) as f32));
            let (normal, gradient) = sums.reduced();
            scale = Some(sums.robust_scale());
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
            last = Some((
                normal,
                scale.unwrap_or(sigma),
                sums.used(),
                sectors,
                contrast,
            ));
            sums.step_levels(&mut levels, &step, settings.min_contrast);
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
            let moved_edge = largest_move(&before.ellipse, turn, &geometry.ellipse.locator());
            let largest = moved_edge.max(step.get(5).map_or(0.0, |s| s.abs()));
            last_step_px = largest;
            if iteration == 0 && largest > trust_px {
                return Err(RimError::Diverged);
            }
            if width <= PIXEL_RAMP_PX && largest < CONVERGED_PX {
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
        let fit = RimFit {
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
        };
        Ok((fit, levels))
    }
}

/// `cos` and `sin` of `k pi / 8`, the phases [`largest_move`] looks at.
const OUTLINE: [(f64, f64); 16] = {
    const C1: f64 = 0.923_879_532_511_286_7;
    const C2: f64 = core::f64::consts::FRAC_1_SQRT_2;
    const C3: f64 = 0.382_683_432_365_089_8;
    [
        (1.0, 0.0),
        (C1, C3),
        (C2, C2),
        (C3, C1),
        (0.0, 1.0),
        (-C3, C1),
        (-C2, C2),
        (-C1, C3),
        (-1.0, 0.0),
        (-C1, -C3),
        (-C2, -C2),
        (-C3, -C1),
        (0.0, -1.0),
        (C3, -C1),
        (C2, -C2),
        (C1, -C3),
    ]
};

/// The farthest a point of `before` (whose angle's sine and cosine are
/// `turn`) lies from the ellipse `after` places, over 16 points round it,
/// px.
fn largest_move(before: &Ellipse, (sin, cos): (f64, f64), after: &Locator) -> f64 {
    let [a, b] = before.semi_axes_px;
    let [cx, cy] = before.centre_px;
    OUTLINE.iter().fold(0.0f64, |m, &(cp, sp)| {
        let (x, y) = (a * cp, b * sp);
        let p = [cx + cos * x - sin * y, cy + sin * x + cos * y];
        m.max(after.distance_px(p).map_or(f64::INFINITY, f64::abs))
    })
}

/// Median of the sectors' `|floor - band|`.
fn median_contrast(levels: &Levels) -> f64 {
    let mut contrasts = [0.0f64; RIM_SECTORS];
    let mut count = 0;
    for (slot, level) in contrasts.iter_mut().zip(levels.iter().flatten()) {
        *slot = f64::from((level[0] - level[1]).abs());
        count += 1;
    }
    let used = contrasts.get_mut(..count).unwrap_or(&mut []);
    used.sort_unstable_by(f64::total_cmp);
    used.get(count / 2).copied().unwrap_or(0.0)
}
