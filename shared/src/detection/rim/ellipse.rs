//! The rim's image: an ellipse in undistorted (pinhole) pixels, and the
//! signed distance of a pixel from it.
//!
//! The image of a circle is a conic (the paper's Section 2 rests on the same
//! fact for the reference point's path); a ring of the disc concentric with
//! the rim is, to the fraction of a pixel that matters across the rim band,
//! the same ellipse scaled about its centre.

use nalgebra::{Matrix2, Matrix3, SymmetricEigen, Vector2, Vector3};

use crate::calibration::conic::Conic;

/// An ellipse in undistorted pixel coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ellipse {
    /// Centre, px.
    pub centre_px: [f64; 2],
    /// Semi-axes along the ellipse's own x and y axes, px.
    pub semi_axes_px: [f64; 2],
    /// Angle of its own x axis from the image's, rad.
    pub angle_rad: f64,
}

/// A pixel seen from an ellipse: its normalised radius `s` (1 on the
/// ellipse) and the length of `s`'s gradient, 1/px.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EllipsePoint {
    /// `sqrt((x/a)^2 + (y/b)^2)` in the ellipse's own axes.
    pub s: f64,
    /// `|grad s|`.
    pub gradient: f64,
    /// Angle of the point about the centre in the ellipse's own axes,
    /// scaled to a circle (`atan2(y/b, x/a)`), rad.
    pub phase_rad: f64,
}

impl EllipsePoint {
    /// Signed distance in px from the ellipse scaled by `scale` about its
    /// centre (positive outside): `(s - scale) / |grad s|`, exact for a
    /// circle and, for an ellipse, off by the curvature's change across the
    /// distance (under 0.01 px within half a pixel of an ellipse of 40 by
    /// 28 px, tested).
    pub fn distance_px(&self, scale: f64) -> f64 {
        (self.s - scale) / self.gradient
    }
}

/// An ellipse made ready to place many pixels: its rotation and inverse
/// axes computed once (a pass over the rim's pixels places each against
/// up to fourteen ellipses).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Locator {
    centre_px: [f64; 2],
    cos: f64,
    sin: f64,
    inverse_axes: [f64; 2],
}

impl Locator {
    /// `(x / a, y / b)` in the ellipse's own axes.
    fn scaled(&self, point: [f64; 2]) -> (f64, f64) {
        let dx = point[0] - self.centre_px[0];
        let dy = point[1] - self.centre_px[1];
        let [ia, ib] = self.inverse_axes;
        (
            (self.cos * dx + self.sin * dy) * ia,
            (-self.sin * dx + self.cos * dy) * ib,
        )
    }

    /// [`EllipsePoint::distance_px`] from the ellipse itself (scale 1), or
    /// `None` at its centre.
    pub fn distance_px(&self, point: [f64; 2]) -> Option<f64> {
        let (xa, yb) = self.scaled(point);
        let s2 = xa * xa + yb * yb;
        let [ia, ib] = self.inverse_axes;
        let g2 = (xa * ia) * (xa * ia) + (yb * ib) * (yb * ib);
        if !(s2 > 1e-18 && g2 > 0.0) {
            return None;
        }
        let s = libm::sqrt(s2);
        // (s - 1) / (|grad s^2| / (2 s)) with |grad s^2| / 2 = sqrt(g2).
        Some((s - 1.0) * s / libm::sqrt(g2))
    }

    /// Where `point` lies ([`Ellipse::locate`]), or `None` at the centre.
    pub fn locate(&self, point: [f64; 2]) -> Option<EllipsePoint> {
        let (xa, yb) = self.scaled(point);
        let s = libm::sqrt(xa * xa + yb * yb);
        if s <= 1e-9 || !s.is_finite() {
            return None;
        }
        let [ia, ib] = self.inverse_axes;
        let gradient = libm::sqrt((xa * ia) * (xa * ia) + (yb * ib) * (yb * ib)) / s;
        Some(EllipsePoint {
            s,
            gradient,
            phase_rad: libm::atan2(yb, xa),
        })
    }

    /// [`EllipsePoint::phase_rad`].
    pub fn phase_rad(&self, point: [f64; 2]) -> f64 {
        let (xa, yb) = self.scaled(point);
        libm::atan2(yb, xa)
    }
}

impl Ellipse {
    /// The ellipse made ready to place many pixels.
    pub fn locator(&self) -> Locator {
        let [a, b] = self.semi_axes_px;
        let (sin, cos) = libm::sincos(self.angle_rad);
        Locator {
            centre_px: self.centre_px,
            cos,
            sin,
            inverse_axes: [1.0 / a, 1.0 / b],
        }
    }

    /// Mean radius `sqrt(a b)`, px.
    pub fn mean_radius_px(&self) -> f64 {
        let [a, b] = self.semi_axes_px;
        libm::sqrt((a * b).abs())
    }

    /// Whether every number is finite and the axes positive.
    pub fn is_valid(&self) -> bool {
        let [a, b] = self.semi_axes_px;
        self.centre_px.iter().all(|c| c.is_finite())
            && a.is_finite()
            && b.is_finite()
            && a > 0.0
            && b > 0.0
            && self.angle_rad.is_finite()
    }

    /// Where `point` lies with respect to the ellipse, or `None` at its centre.
    pub fn locate(&self, point: [f64; 2]) -> Option<EllipsePoint> {
        self.locator().locate(point)
    }

    /// The point of the ellipse at `phase_rad` (as [`EllipsePoint::phase_rad`]).
    pub fn point_at(&self, phase_rad: f64) -> [f64; 2] {
        let [a, b] = self.semi_axes_px;
        let (sp, cp) = libm::sincos(phase_rad);
        let (sin, cos) = libm::sincos(self.angle_rad);
        let (x, y) = (a * cp, b * sp);
        [
            self.centre_px[0] + cos * x - sin * y,
            self.centre_px[1] + sin * x + cos * y,
        ]
    }

    /// Its matrix `C` in px (`p^T C p = 0` for `p = (u, v, 1)` on it,
    /// negative inside).
    pub fn matrix(&self) -> Matrix3<f64> {
        let [a, b] = self.semi_axes_px;
        let (sin, cos) = libm::sincos(self.angle_rad);
        // x' = cos dx + sin dy, y' = -sin dx + cos dy; x'^2/a^2 + y'^2/b^2 - 1.
        let (ia, ib) = (1.0 / (a * a), 1.0 / (b * b));
        let qxx = cos * cos * ia + sin * sin * ib;
        let qyy = sin * sin * ia + cos * cos * ib;
        let qxy = cos * sin * (ia - ib);
        let [cx, cy] = self.centre_px;
        let lx = -(qxx * cx + qxy * cy);
        let ly = -(qxy * cx + qyy * cy);
        let g = qxx * cx * cx + 2.0 * qxy * cx * cy + qyy * cy * cy - 1.0;
        Matrix3::new(qxx, qxy, lx, qxy, qyy, ly, lx, ly, g)
    }

    /// The ellipse of a matrix in px, or `None` when it is not a real ellipse.
    pub fn from_matrix(c: &Matrix3<f64>) -> Option<Self> {
        let conic = Conic {
            coefficients: [
                c.m11,
                c.m12 + c.m21,
                c.m22,
                c.m13 + c.m31,
                c.m23 + c.m32,
                c.m33,
            ],
        };
        Self::from_ray_conic(&conic, 1.0, [0.0, 0.0])
    }

    /// The image of the circle concentric with this one (the image of a
    /// circle of radius `R`) of radius `(1 - fraction) R`, given the image of
    /// their common centre `pole` (undistorted px): concentric circles'
    /// images form the pencil `C_R - (1 - rho^2 / R^2) m m^T / (c^T C_R c)`,
    /// `m = C_R c`, since the centre is the pole of the plane's vanishing
    /// line with respect to each. Exact under perspective, where scaling
    /// the ellipse about its own centre is not (the centre's image is not
    /// the ellipse's centre).
    pub fn concentric(&self, pole: [f64; 2], fraction: f64) -> Option<Self> {
        let c = self.matrix();
        let p = Vector3::new(pole[0], pole[1], 1.0);
        let m = c * p;
        let inside = p.dot(&m);
        // Negative inside; NaN fails too.
        if inside.is_nan() || inside >= 0.0 {
            return None;
        }
        let keep = 1.0 - fraction;
        let inner = c - m * m.transpose() * ((1.0 - keep * keep) / inside);
        Self::from_matrix(&inner)
    }

    /// The ellipse of a conic fitted in ray coordinates (`(u - cx) / f`),
    /// or `None` when it is not a real ellipse.
    pub fn from_ray_conic(conic: &Conic, f_px: f64, principal_px: [f64; 2]) -> Option<Self> {
        let [a, b, c, d, e, g] = conic.coefficients;
        let quadratic = Matrix2::new(a, b / 2.0, b / 2.0, c);
        let linear = Vector2::new(d, e);
        let centre = quadratic.try_inverse()? * linear * -0.5;
        // Value of the conic at its centre: the form is `(x-c)^T Q (x-c) = -value`.
        let value = g + 0.5 * linear.dot(&centre);
        let eigen = SymmetricEigen::new(quadratic);
        let (l0, l1) = (eigen.eigenvalues.x, eigen.eigenvalues.y);
        let (r0, r1) = (-value / l0, -value / l1);
        if !(r0 > 0.0 && r1 > 0.0) {
            return None;
        }
        let axis = eigen.eigenvectors.column(0);
        let ellipse = Self {
            centre_px: [
                centre.x * f_px + principal_px[0],
                centre.y * f_px + principal_px[1],
            ],
            semi_axes_px: [libm::sqrt(r0) * f_px, libm::sqrt(r1) * f_px],
            angle_rad: libm::atan2(axis.y, axis.x),
        };
        ellipse.is_valid().then_some(ellipse)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::conic::ConicFit;

    #[test]
    fn a_conic_fitted_to_an_ellipse_gives_it_back() {
        let truth = Ellipse {
            centre_px: [131.0, 118.0],
            semi_axes_px: [52.0, 41.0],
            angle_rad: 0.4,
        };
        let mut fit = ConicFit::new();
        for k in 0..40 {
            let p = truth.point_at(k as f64 * 0.157);
            fit.add(
                Vector2::new((p[0] - 127.5) / 290.0, (p[1] - 127.5) / 290.0),
                1.0,
            );
        }
        let back = Ellipse::from_ray_conic(&fit.solve().unwrap(), 290.0, [127.5, 127.5]).unwrap();
        for k in 0..12 {
            let p = truth.point_at(k as f64 * 0.5);
            let here = back.locate(p).unwrap();
            assert!(here.distance_px(1.0).abs() < 1e-6, "{here:?}");
        }
        assert!((back.mean_radius_px() - truth.mean_radius_px()).abs() < 1e-6);
    }

    #[test]
    fn the_matrix_gives_the_ellipse_back_and_scales_about_its_centre() {
        let e = Ellipse {
            centre_px: [120.0, 140.0],
            semi_axes_px: [50.0, 38.0],
            angle_rad: 0.7,
        };
        for k in 0..8 {
            let p = e.point_at(k as f64);
            let h = Vector3::new(p[0], p[1], 1.0);
            assert!((h.dot(&(e.matrix() * h))).abs() < 1e-9);
        }
        let back = Ellipse::from_matrix(&e.matrix()).unwrap();
        for k in 0..8 {
            let d = back.locate(e.point_at(k as f64)).unwrap().distance_px(1.0);
            assert!(d.abs() < 1e-9);
        }
        // With the pole at the centre, the concentric image is the scaled one.
        let inner = e.concentric(e.centre_px, 0.1).unwrap();
        for k in 0..8 {
            let d = inner
                .locate(e.point_at(k as f64))
                .unwrap()
                .distance_px(1.0 / 0.9);
            assert!(d.abs() < 1e-7, "{d}");
        }
    }

    #[test]
    fn the_locator_places_a_point_as_the_ellipse_does() {
        let e = Ellipse {
            centre_px: [120.0, 140.0],
            semi_axes_px: [50.0, 38.0],
            angle_rad: 0.7,
        };
        let locator = e.locator();
        for p in [
            [171.0, 150.0],
            [120.0, 181.0],
            [80.0, 100.0],
            [125.0, 139.0],
        ] {
            let here = e.locate(p).unwrap();
            assert!((locator.distance_px(p).unwrap() - here.distance_px(1.0)).abs() < 1e-9);
            assert!((locator.phase_rad(p) - here.phase_rad).abs() < 1e-12);
        }
        assert!(locator.distance_px(e.centre_px).is_none());
    }

    #[test]
    fn the_distance_is_exact_for_a_circle_and_close_for_an_ellipse() {
        let circle = Ellipse {
            centre_px: [100.0, 100.0],
            semi_axes_px: [40.0, 40.0],
            angle_rad: 0.3,
        };
        let here = circle.locate([143.0, 100.0]).unwrap();
        assert!((here.distance_px(1.0) - 3.0).abs() < 1e-12);
        assert!((here.distance_px(0.95) - 5.0).abs() < 1e-12);
        let ellipse = Ellipse {
            semi_axes_px: [40.0, 28.0],
            ..circle
        };
        // Points a known distance along the normal from the ellipse.
        for k in 0..24 {
            let phase = k as f64 * 0.26;
            let on = ellipse.point_at(phase);
            let next = ellipse.point_at(phase + 1e-6);
            let (tx, ty) = (next[0] - on[0], next[1] - on[1]);
            let norm = (tx * tx + ty * ty).sqrt();
            for d in [-2.0, -0.5, 0.5, 2.0] {
                let p = [on[0] + d * ty / norm, on[1] - d * tx / norm];
                let got = ellipse.locate(p).unwrap().distance_px(1.0);
                // The outward normal's sign depends on the phase's sense.
                let tolerance = if d.abs() <= 0.5 { 0.01 } else { 0.06 };
                assert!((got.abs() - d.abs()).abs() < tolerance, "{phase} {d} {got}");
            }
        }
    }
}
