//! Robot-to-disc calibration (paper Eqs 10 to 15): the depth of two end-effector points
//! in the virtual camera from their image, their distance `s` and their height difference
//! `d` (both from the robot's kinematics), then `base_from_disc` from point pairs known in
//! both frames with the rotation constrained to the form of Eq 14.

use super::exceeds;
use nalgebra::{Vector2, Vector3};

use super::error::CalibrationError;
use super::model::rotation_z;

/// Roots of Eq 10 that put both points in front of the camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DepthRoots {
    /// Exactly one physically valid root: depths `(z0, z1)` of points 0 and 1.
    Unique(f64, f64),
    /// Two valid roots (possible only when G >= 0, a steep segment): the image cannot decide.
    Ambiguous([(f64, f64); 2]),
    /// No real root, or none with both points in front of the camera.
    None,
}

/// Eq 10 in the virtual camera with `f = 1`: with `m0`, `m1` the points' virtual image
/// points, `d = z0 - z1` (the base-frame height difference `zb1 - zb0`, since virtual depth
/// is `H - h`) and `s` their distance,
/// `E z1^2 + 2 F z1 + G = 0`, `E = |m0 - m1|^2`, `F = d m0.(m0 - m1)`, `G = (|m0|^2 + 1) d^2 - s^2`.
pub fn depth_roots(m0: Vector2<f64>, m1: Vector2<f64>, d: f64, s: f64) -> DepthRoots {
    let difference = m0 - m1;
    let e = difference.norm_squared();
    let f = d * m0.dot(&difference);
    let g = (m0.norm_squared() + 1.0) * d * d - s * s;
    let valid = |z1: f64| z1.is_finite() && z1 > 0.0 && z1 + d > 0.0;
    if !exceeds(e, 1e-18) {
        // Both points on one ray: Eq 10 degenerates to 2 F z1 + G = 0.
        if f != 0.0 {
            let z1 = -g / (2.0 * f);
            if valid(z1) {
                return DepthRoots::Unique(z1 + d, z1);
            }
        }
        return DepthRoots::None;
    }
    let discriminant = f * f - e * g;
    if discriminant < 0.0 {
        return DepthRoots::None;
    }
    let root = libm::sqrt(discriminant);
    // Numerically stable pair: q = -(F + sign(F) sqrt), roots q / E and G / q.
    let q = -(f + if f >= 0.0 { root } else { -root });
    let first = q / e;
    let second = if q != 0.0 { g / q } else { first };
    match (valid(first), valid(second)) {
        (true, true) if libm::fabs(first - second) > 1e-12 * first.abs().max(1.0) => {
            DepthRoots::Ambiguous([(first + d, first), (second + d, second)])
        }
        (true, _) => DepthRoots::Unique(first + d, first),
        (false, true) => DepthRoots::Unique(second + d, second),
        (false, false) => DepthRoots::None,
    }
}

/// Least-squares `base_from_disc` from point pairs, rotation of the form of Eq 14.
///
/// The paper's constrained closed form for one difference vector generalises to many
/// pairs as the 2-D Procrustes solution about the centroids:
/// `yaw = atan2(sum(b_y d_x - b_x d_y), sum(b_x d_x + b_y d_y))` (the paper's `r11`, `-r12`
/// up to a common positive factor), then the translation from the centroids (Eq 13).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BaseFromDiscFit {
    sum_disc: Vector3<f64>,
    sum_base: Vector3<f64>,
    sum_dot: f64,
    sum_cross: f64,
    sum_disc_outer_xy: [f64; 3],
    sum_base_disc: [f64; 4],
    count: u32,
}

impl BaseFromDiscFit {
    /// One correspondence: `p_disc` in the disc frame is `p_base` in the base frame.
    pub fn add(&mut self, p_disc: Vector3<f64>, p_base: Vector3<f64>) {
        self.sum_disc += p_disc;
        self.sum_base += p_base;
        let [bxdx, bxdy, bydx, bydy] = &mut self.sum_base_disc;
        *bxdx += p_base.x * p_disc.x;
        *bxdy += p_base.x * p_disc.y;
        *bydx += p_base.y * p_disc.x;
        *bydy += p_base.y * p_disc.y;
        let [xx, xy, yy] = &mut self.sum_disc_outer_xy;
        *xx += p_disc.x * p_disc.x;
        *xy += p_disc.x * p_disc.y;
        *yy += p_disc.y * p_disc.y;
        self.count = self.count.saturating_add(1);
    }

    /// Correspondences absorbed.
    pub fn count(&self) -> u32 {
        self.count
    }

    /// `(yaw, translation)`; `known_height` fixes the translation's z (experiment 2).
    pub fn solve(
        &self,
        known_height: Option<f64>,
    ) -> Result<(f64, Vector3<f64>), CalibrationError> {
        if self.count < 2 {
            return Err(CalibrationError::TooFewObservations {
                what: "end-effector points with a valid depth",
                needed: 2,
                found: self.count,
            });
        }
        let n = f64::from(self.count);
        let mean_disc = self.sum_disc / n;
        let mean_base = self.sum_base / n;
        let [bxdx, bxdy, bydx, bydy] = self.sum_base_disc;
        // Centred sums: sum (b - mb)(d - md) = sum b d - n mb md.
        let cxx = bxdx - n * mean_base.x * mean_disc.x;
        let cxy = bxdy - n * mean_base.x * mean_disc.y;
        let cyx = bydx - n * mean_base.y * mean_disc.x;
        let cyy = bydy - n * mean_base.y * mean_disc.y;
        let [xx, _, yy] = self.sum_disc_outer_xy;
        let spread = xx + yy - n * (mean_disc.x * mean_disc.x + mean_disc.y * mean_disc.y);
        if !exceeds(spread, 1e-12) {
            return Err(CalibrationError::NumericalFailure {
                stage: "base_from_disc (points coincide in the disc plane; Eq 15 needs a horizontal offset)",
            });
        }
        let yaw = libm::atan2(cyx - cxy, cxx + cyy);
        let mut translation = mean_base - rotation_z(yaw) * mean_disc;
        if let Some(height) = known_height {
            translation.z = height;
        }
        if !(yaw.is_finite() && translation.iter().all(|v| v.is_finite())) {
            return Err(CalibrationError::NumericalFailure {
                stage: "base_from_disc",
            });
        }
        Ok((yaw, translation))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::angle::wrap_pi;

    /// Virtual image points of two disc-frame points seen from a virtual camera at height `h`
    /// straight above the origin (depth = h - z).
    fn image(p: Vector3<f64>, h: f64) -> (Vector2<f64>, f64) {
        let depth = h - p.z;
        (Vector2::new(p.x / depth, p.y / depth), depth)
    }

    #[test]
    fn a_level_segment_has_a_unique_root_equal_to_the_true_depth() {
        let (p0, p1) = (Vector3::new(0.1, 0.05, 0.2), Vector3::new(0.2, 0.05, 0.2));
        let ((m0, z0), (m1, z1)) = (image(p0, 2.5), image(p1, 2.5));
        match depth_roots(m0, m1, p1.z - p0.z, (p1 - p0).norm()) {
            DepthRoots::Unique(a, b) => assert!((a - z0).abs() < 1e-12 && (b - z1).abs() < 1e-12),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_steep_segment_can_be_ambiguous_and_one_root_is_the_truth() {
        // G = (|m0|^2 + 1) d^2 - s^2 > 0 for a steep segment: two roots of one sign.
        let (p0, p1) = (
            Vector3::new(0.30, 0.0, 0.10),
            Vector3::new(0.31, 0.0, 0.1995),
        );
        let ((m0, z0), (m1, _)) = (image(p0, 2.5), image(p1, 2.5));
        match depth_roots(m0, m1, p1.z - p0.z, (p1 - p0).norm()) {
            DepthRoots::Ambiguous(roots) => {
                assert!(
                    roots.iter().any(|(a, _)| (a - z0).abs() < 1e-9),
                    "{roots:?}"
                );
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_vertical_segment_off_the_radial_line_has_no_root() {
        let m0 = Vector2::new(0.1, 0.05);
        let m1 = Vector2::new(0.2, -0.1);
        assert_eq!(depth_roots(m0, m1, -0.1, 0.1), DepthRoots::None);
    }

    #[test]
    fn yaw_and_translation_from_exact_pairs() {
        let yaw = 2.5;
        let translation = Vector3::new(0.9, -0.4, -0.2);
        let mut fit = BaseFromDiscFit::default();
        for p in [
            Vector3::new(0.1, 0.2, 0.3),
            Vector3::new(-0.2, 0.1, 0.1),
            Vector3::new(0.3, -0.3, 0.4),
        ] {
            fit.add(p, rotation_z(yaw) * p + translation);
        }
        let (found_yaw, found_translation) = fit.solve(None).unwrap();
        assert!((wrap_pi(found_yaw - yaw)).abs() < 1e-12);
        assert!((found_translation - translation).norm() < 1e-12);
        let (_, pinned) = fit.solve(Some(-0.25)).unwrap();
        assert_eq!(pinned.z, -0.25);
    }
}
