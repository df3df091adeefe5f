//! A first ellipse for the rim from rays cast outwards from the disc centre's
//! image: on each ray, the deepest narrow dip (the dark rim band between the
//! disc's surface and the floor), then a robust conic through the dips.
//!
//! Only a start for [`super::fit`]: it must land within a pixel or two of
//! the band, which the band's depth (tens of grey levels against the
//! texture's few) gives on most rays; rays that cross the arm or a mark give
//! a wrong dip or none, and the conic drops them.

use nalgebra::Vector2;

use super::ellipse::Ellipse;
use super::RimError;
use crate::calibration::conic::ConicFit;
use crate::detection::identify::lens::LensModel;
use crate::detection::{Blob, GrayImage};

/// Rays cast from the centre.
pub const SEED_RAYS: usize = 64;
/// Step along a ray, px.
const STEP_PX: f64 = 0.5;
/// Rise on each side of a dip, px from its bottom: the band is 1 to 3 px wide.
const SIDE_NEAR_PX: f64 = 1.5;
const SIDE_FAR_PX: f64 = 4.0;
/// Samples a ray may hold (a 512 px image's diagonal at [`STEP_PX`]).
const MAX_RAY_SAMPLES: usize = 1500;
/// Least distance from the centre a dip may lie at, px: inside it the
/// centre mark and the part's marks crowd.
const MIN_RADIUS_PX: f64 = 12.0;
/// A dip farther than this from the conic through the others is dropped, px.
const OUTLIER_PX: f64 = 2.0;
/// Least rays whose dips make the conic.
pub const MIN_SEED_DIPS: usize = 16;

/// Image value at a real position by bilinear interpolation, or `None` off
/// the image.
pub fn bilinear(image: &GrayImage<'_>, x: f64, y: f64) -> Option<f64> {
    if !(x >= 0.0 && y >= 0.0) {
        return None;
    }
    let (x0, y0) = (x as usize, y as usize);
    if x0 + 1 >= image.width() || y0 + 1 >= image.height() {
        return None;
    }
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let top = image.row(y0);
    let bottom = image.row(y0 + 1);
    let at = |row: &[u8], i: usize| row.get(i).map(|&v| f64::from(v));
    let (a, b) = (at(top, x0)?, at(top, x0 + 1)?);
    let (c, d) = (at(bottom, x0)?, at(bottom, x0 + 1)?);
    Some((a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy)
}

/// Whether `(x, y)` lies on or near a mark the detector found.
pub fn near_a_mark(marks: &[Blob], x: f64, y: f64, margin_px: f64) -> bool {
    marks.iter().any(|mark| {
        let reach = f64::from(mark.semi_major_px) + margin_px;
        let (dx, dy) = (x - f64::from(mark.x_px), y - f64::from(mark.y_px));
        dx * dx + dy * dy <= reach * reach
    })
}

/// The deepest dip along one ray from `centre` in direction `(cos, sin)`:
/// its distance in px, or `None`.
fn deepest_dip(
    image: &GrayImage<'_>,
    marks: &[Blob],
    centre: [f64; 2],
    (cos, sin): (f64, f64),
    min_depth: f64,
    samples: &mut [f64; MAX_RAY_SAMPLES],
) -> Option<f64> {
    let mut count = 0;
    for (k, slot) in samples.iter_mut().enumerate() {
        let t = k as f64 * STEP_PX;
        let (x, y) = (centre[0] + t * cos, centre[1] + t * sin);
        match bilinear(image, x, y) {
            // A mark's light is no band: read it as a wall the dip cannot cross.
            Some(_) if near_a_mark(marks, x, y, 1.5) => *slot = f64::INFINITY,
            Some(value) => *slot = value,
            None => break,
        }
        count = k + 1;
    }
    let near = (SIDE_NEAR_PX / STEP_PX) as usize;
    let far = (SIDE_FAR_PX / STEP_PX) as usize;
    let first = (MIN_RADIUS_PX / STEP_PX) as usize;
    let mut best: Option<(f64, f64)> = None;
    for k in first.max(far)..count.saturating_sub(far) {
        let bottom = *samples.get(k)?;
        if !bottom.is_finite() {
            continue;
        }
        let window = samples.get(k - near..=k + near)?;
        if window.iter().any(|&v| v < bottom) {
            continue;
        }
        let inner = samples.get(k - far..=k - near)?;
        let outer = samples.get(k + near..=k + far)?;
        if inner.iter().chain(outer).any(|v| !v.is_finite()) {
            continue;
        }
        let rise = |side: &[f64]| side.iter().fold(f64::NEG_INFINITY, |m, &v| m.max(v)) - bottom;
        let depth = rise(inner).min(rise(outer));
        if depth >= min_depth && best.is_none_or(|(_, d)| depth >= d) {
            best = Some((k as f64 * STEP_PX, depth));
        }
    }
    best.map(|(t, _)| t)
}

/// A first ellipse of the rim (undistorted px) from the disc centre's image
/// `centre_px` (distorted, as the detector reports it).
pub fn seed_ellipse(
    image: &GrayImage<'_>,
    lens: &LensModel,
    marks: &[Blob],
    centre_px: [f64; 2],
    min_depth: f64,
) -> Result<Ellipse, RimError> {
    let centre_undistorted = lens.undistort(centre_px).ok_or(RimError::CentreOffLens)?;
    let mut samples = [0.0; MAX_RAY_SAMPLES];
    let mut dips = [[0.0f64; 2]; SEED_RAYS];
    let mut found = 0;
    for k in 0..SEED_RAYS {
        let angle = core::f64::consts::TAU * k as f64 / SEED_RAYS as f64;
        let (sin, cos) = libm::sincos(angle);
        let Some(t) = deepest_dip(image, marks, centre_px, (cos, sin), min_depth, &mut samples)
        else {
            continue;
        };
        let distorted = [centre_px[0] + t * cos, centre_px[1] + t * sin];
        if let (Some(point), Some(slot)) = (lens.undistort(distorted), dips.get_mut(found)) {
            *slot = point;
            found += 1;
        }
    }
    let dips = dips.get(..found).unwrap_or(&[]);
    // A dip far from the others' typical radius is the arm's or a mark's.
    let mut radii = [0.0f64; SEED_RAYS];
    for (slot, point) in radii.iter_mut().zip(dips) {
        *slot = libm::hypot(
            point[0] - centre_undistorted[0],
            point[1] - centre_undistorted[1],
        );
    }
    let radii = radii.get_mut(..found).unwrap_or(&mut []);
    radii.sort_unstable_by(f64::total_cmp);
    let typical = radii.get(found / 2).copied().unwrap_or(0.0);
    let mut kept = [true; SEED_RAYS];
    for (point, keep) in dips.iter().zip(kept.iter_mut()) {
        let radius = libm::hypot(
            point[0] - centre_undistorted[0],
            point[1] - centre_undistorted[1],
        );
        *keep = (radius - typical).abs() <= 0.25 * typical;
    }
    let mut ellipse = None;
    // Fit, drop what lies far from the fit, fit again.
    for _ in 0..4 {
        let mut fit = ConicFit::new();
        let mut used = 0;
        for (point, _) in dips.iter().zip(kept.iter()).filter(|(_, &k)| k) {
            let ray = Vector2::new(
                (point[0] - lens.cx) / lens.f_px,
                (point[1] - lens.cy) / lens.f_px,
            );
            fit.add(ray, 1.0);
            used += 1;
        }
        if used < MIN_SEED_DIPS {
            return Err(RimError::TooFewDips {
                found: used,
                needed: MIN_SEED_DIPS,
            });
        }
        let conic = fit.solve().map_err(|_| RimError::NotAnEllipse)?;
        let fitted = Ellipse::from_ray_conic(&conic, lens.f_px, [lens.cx, lens.cy])
            .ok_or(RimError::NotAnEllipse)?;
        let mut changed = false;
        for (point, keep) in dips.iter().zip(kept.iter_mut()) {
            let close = fitted
                .locate(*point)
                .is_some_and(|p| p.distance_px(1.0).abs() <= OUTLIER_PX);
            changed |= close != *keep;
            *keep = close;
        }
        ellipse = Some(fitted);
        if !changed {
            break;
        }
    }
    ellipse.ok_or(RimError::NotAnEllipse)
}
