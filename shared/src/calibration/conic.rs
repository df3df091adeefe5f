//! Step 2 of the virtual rotation: least-squares fit of the conic traced by the
//! reference point's image, absorbed one observation at a time.
//!
//! The fit is recursive least squares in information form: each point adds the outer
//! product of its monomial vector `[x^2, xy, y^2, x, y, 1]` to a 6x6 scatter matrix, so
//! the memory is fixed and the order of arrival does not matter. Points enter in ray
//! coordinates `((u - cx) / f, (v - cy) / f)` (a fixed centring and scaling); before the
//! eigen-solve the scatter is re-expressed exactly in coordinates centred on the points'
//! centroid and scaled to unit RMS radius (Hartley-style normalisation), which keeps the
//! smallest eigenvector well conditioned wherever the ellipse lies in the image.

use super::exceeds;
use nalgebra::{Matrix3, SMatrix, SVector, SymmetricEigen, Vector2};

use super::error::{CalibrationError, ConicKind};

type Matrix6 = SMatrix<f64, 6, 6>;
type Vector6 = SVector<f64, 6>;

/// A conic `a x^2 + b xy + c y^2 + d x + e y + g = 0` in ray coordinates, scaled to unit norm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Conic {
    /// `[a, b, c, d, e, g]`.
    pub coefficients: [f64; 6],
}

impl Conic {
    /// The symmetric 3x3 matrix `Q` with `[x y 1] Q [x y 1]^T = 0`.
    pub fn matrix(&self) -> Matrix3<f64> {
        let [a, b, c, d, e, g] = self.coefficients;
        Matrix3::new(
            a,
            b / 2.0,
            d / 2.0,
            b / 2.0,
            c,
            e / 2.0,
            d / 2.0,
            e / 2.0,
            g,
        )
    }

    /// Sampson (first-order geometric) distance of a ray-coordinate point to the conic,
    /// in the same units as the point.
    pub fn sampson_distance(&self, point: Vector2<f64>) -> f64 {
        let [a, b, c, d, e, g] = self.coefficients;
        let (x, y) = (point.x, point.y);
        let algebraic = a * x * x + b * x * y + c * y * y + d * x + e * y + g;
        let gx = 2.0 * a * x + b * y + d;
        let gy = b * x + 2.0 * c * y + e;
        let gradient = libm::sqrt(gx * gx + gy * gy);
        if gradient > 0.0 {
            libm::fabs(algebraic) / gradient
        } else {
            f64::INFINITY
        }
    }

    /// Checks that the conic is a real, non-degenerate ellipse.
    fn check_ellipse(&self) -> Result<(), CalibrationError> {
        let [a, b, c, ..] = self.coefficients;
        let discriminant = b * b - 4.0 * a * c;
        let tolerance = 1e-7 * (a * a + b * b + c * c);
        if discriminant > tolerance {
            return Err(CalibrationError::NotAnEllipse {
                kind: ConicKind::Hyperbola,
            });
        }
        if discriminant >= -tolerance {
            return Err(CalibrationError::NotAnEllipse {
                kind: ConicKind::Parabola,
            });
        }
        // A real ellipse has det(Q) of sign opposite to a (its value at the centre is -a*...).
        let determinant = self.matrix().determinant();
        if determinant * a >= 0.0 {
            return Err(CalibrationError::NotAnEllipse {
                kind: ConicKind::Imaginary,
            });
        }
        Ok(())
    }
}

/// Monomials of a point, in the order of [`Conic::coefficients`].
fn monomials(point: Vector2<f64>) -> Vector6 {
    let (x, y) = (point.x, point.y);
    Vector6::new(x * x, x * y, y * y, x, y, 1.0)
}

/// `T` with `monomials(p) = T * monomials((p - mean) / scale)`, written for the inverse map
/// when called with `(-mean / scale, 1 / scale)`.
fn monomial_transform(mean: Vector2<f64>, scale: f64) -> Matrix6 {
    let (mx, my, k) = (mean.x, mean.y, scale);
    let k2 = k * k;
    #[rustfmt::skip]
    let t = Matrix6::new(
        k2,  0.0, 0.0, 2.0 * k * mx,        0.0,          mx * mx,
        0.0, k2,  0.0, k * my,              k * mx,       mx * my,
        0.0, 0.0, k2,  0.0,                 2.0 * k * my, my * my,
        0.0, 0.0, 0.0, k,                   0.0,          mx,
        0.0, 0.0, 0.0, 0.0,                 k,            my,
        0.0, 0.0, 0.0, 0.0,                 0.0,          1.0,
    );
    t
}

/// Recursive (information-form) least-squares conic fit; 6x6 f64 state, any number of points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConicFit {
    scatter: Matrix6,
    points: u32,
}

impl Default for ConicFit {
    fn default() -> Self {
        Self::new()
    }
}

impl ConicFit {
    /// No point yet.
    pub fn new() -> Self {
        Self {
            scatter: Matrix6::zeros(),
            points: 0,
        }
    }

    /// Absorbs one point (ray coordinates) with weight `weight` (1 for plain least squares).
    pub fn add(&mut self, point: Vector2<f64>, weight: f64) {
        let m = monomials(point);
        self.scatter += m * m.transpose() * weight;
        self.points = self.points.saturating_add(1);
    }

    /// Points absorbed.
    pub fn points(&self) -> u32 {
        self.points
    }

    /// The algebraic least-squares conic (smallest eigenvector of the normalised scatter),
    /// or a typed error when the points do not determine an ellipse.
    pub fn solve(&self) -> Result<Conic, CalibrationError> {
        if self.points < 5 {
            return Err(CalibrationError::TooFewObservations {
                what: "reference point images (conic fit)",
                needed: 5,
                found: self.points,
            });
        }
        let s = &self.scatter;
        let weight_sum = s.m66;
        if !exceeds(weight_sum, 0.0) || !s.iter().all(|v| v.is_finite()) {
            return Err(CalibrationError::NumericalFailure { stage: "conic fit" });
        }
        // Centroid and RMS radius from the scatter's own moments (column of x, y, 1).
        let mean = Vector2::new(s.m46 / weight_sum, s.m56 / weight_sum);
        let second_moment = (s.m16 + s.m36) / weight_sum;
        let variance = second_moment - mean.norm_squared();
        if !exceeds(variance, 1e-18) {
            return Err(CalibrationError::DegenerateConic {
                points: self.points,
            });
        }
        let scale = libm::sqrt(variance / 2.0);
        // Normalised coordinates p' = (p - mean) / scale: S' = Tinv S Tinv^T.
        let to_normalised = monomial_transform(-mean / scale, 1.0 / scale);
        let normalised = to_normalised * s * to_normalised.transpose();
        let eigen = SymmetricEigen::try_new(normalised, 1e-15, 500).ok_or(
            CalibrationError::NumericalFailure {
                stage: "conic eigen-solve",
            },
        )?;
        let values: [f64; 6] = eigen.eigenvalues.into();
        let mut order = [0usize, 1, 2, 3, 4, 5];
        order.sort_unstable_by(|&i, &j| {
            let value = |k: usize| values.get(k).copied().unwrap_or(f64::INFINITY);
            value(i).total_cmp(&value(j))
        });
        let [smallest, second, .., largest] = order;
        let eigenvalue = |k: usize| values.get(k).copied().unwrap_or(0.0);
        if eigenvalue(second) <= 1e-12 * eigenvalue(largest).max(f64::MIN_POSITIVE) {
            return Err(CalibrationError::DegenerateConic {
                points: self.points,
            });
        }
        let normalised_conic: Vector6 = eigen.eigenvectors.column(smallest).into_owned();
        // Back to ray coordinates: m' = Tinv m, so p = Tinv^T p'.
        let mut coefficients_vector = to_normalised.transpose() * normalised_conic;
        let norm = coefficients_vector.norm();
        if !exceeds(norm, 0.0) || !norm.is_finite() {
            return Err(CalibrationError::NumericalFailure { stage: "conic fit" });
        }
        coefficients_vector /= norm;
        let mut coefficients = [0.0; 6];
        for (slot, value) in coefficients.iter_mut().zip(coefficients_vector.iter()) {
            *slot = *value;
        }
        let conic = Conic { coefficients };
        conic.check_ellipse()?;
        Ok(conic)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ellipse_point(t: f64) -> Vector2<f64> {
        // Centre (0.1, -0.05), semi-axes 0.2 and 0.12, rotated by 0.4 rad.
        let (s, c) = libm::sincos(0.4);
        let (x, y) = (0.2 * libm::cos(t), 0.12 * libm::sin(t));
        Vector2::new(0.1 + c * x - s * y, -0.05 + s * x + c * y)
    }

    #[test]
    fn recovers_an_exact_ellipse() {
        let mut fit = ConicFit::new();
        for i in 0..50 {
            fit.add(ellipse_point(f64::from(i) * 0.13), 1.0);
        }
        let conic = fit.solve().unwrap();
        for i in 0..20 {
            let p = ellipse_point(f64::from(i) * 0.31 + 0.05);
            assert!(conic.sampson_distance(p) < 1e-10);
        }
    }

    #[test]
    fn collinear_points_are_degenerate() {
        let mut fit = ConicFit::new();
        for i in 0..20 {
            let t = f64::from(i) * 0.01;
            fit.add(Vector2::new(t, 2.0 * t + 0.1), 1.0);
        }
        assert!(matches!(
            fit.solve(),
            Err(CalibrationError::DegenerateConic { .. })
        ));
    }

    #[test]
    fn hyperbola_and_parabola_are_refused() {
        let mut hyperbola = ConicFit::new();
        let mut parabola = ConicFit::new();
        for i in 0..30 {
            let t = f64::from(i) * 0.05 - 0.7;
            hyperbola.add(Vector2::new(libm::cosh(t) * 0.1, libm::sinh(t) * 0.1), 1.0);
            parabola.add(Vector2::new(t * 0.2, t * t * 0.3), 1.0);
        }
        assert_eq!(
            hyperbola.solve(),
            Err(CalibrationError::NotAnEllipse {
                kind: ConicKind::Hyperbola
            })
        );
        assert_eq!(
            parabola.solve(),
            Err(CalibrationError::NotAnEllipse {
                kind: ConicKind::Parabola
            })
        );
    }
}
