//! The reference point's track and the disc centre's image, Steps 2 and 3 on
//! the stored frames: the checks a track must pass before any estimate (enough
//! points, enough turn, an ellipse the pixel noise cannot fake), the robust
//! conic and centre, and the image angle of the disc's X axis. Both the
//! paper's estimate and the initial estimate start here.

use nalgebra::Vector2;

use super::SelfCalibrator;
use crate::calibration::conic::{Conic, ConicFit};
use crate::calibration::error::CalibrationError;
use crate::calibration::exceeds;
use crate::calibration::records::{to_vector, PixelF32};
use crate::calibration::virtual_rotation::VirtualRotation;

/// Smallest spread of the reference track across its principal direction, in
/// pixel sigmas: pure noise about a line gives one sigma; 2 needs an ellipse whose
/// minor semi-axis is at least 2.4 sigmas (1.2 px at the paper's 0.5 px).
const MIN_TRACK_SPREAD_IN_SIGMAS: f64 = 2.0;

impl<const FRAMES: usize, const EFFECTOR_FRAMES: usize, const PIXELS_PER_FRAME: usize>
    SelfCalibrator<FRAMES, EFFECTOR_FRAMES, PIXELS_PER_FRAME>
{
    /// `pixel` (an image of `field`) in the virtual camera looking straight down the
    /// disc's axis (Step 3). A ray that does not point down towards the disc plane has
    /// no such image: the point is level with or above the camera.
    pub(super) fn virtual_point(
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
    pub(super) fn mean_centre_ray(
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
    pub(super) fn robust_centre_ray(&self) -> Result<Vector2<f64>, CalibrationError> {
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
    pub(super) fn robust_conic(&self) -> Result<Conic, CalibrationError> {
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
    pub(super) fn check_reference_count(&self) -> Result<(), CalibrationError> {
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
    pub(super) fn check_reference_spread(&self) -> Result<(), CalibrationError> {
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

    pub(super) fn check_rotation_span(&self) -> Result<(), CalibrationError> {
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
    pub(super) fn disc_axis_angle(
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
}
