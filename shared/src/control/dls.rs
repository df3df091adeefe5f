//! Damped least-squares inversion of the Jacobian for the joint accelerations.
//!
//! Eq 23 needs `J^-1`, which does not exist at the PUMA's wrist (`q5 = 0`),
//! elbow (arm stretched) and shoulder (wrist centre on the `z0` axis)
//! singularities; there the plain inverse makes `qdd`, and through RNEA the
//! torques, unbounded. The damped least-squares solution
//! `x = J^T (J J^T + lambda^2 I)^-1 b` equals `J^-1 b` when `lambda = 0` and is
//! bounded by `|b| / (2 lambda)` otherwise. The damping is switched on only
//! inside a manipulability band (Nakamura and Hanafusa's schedule), so tracking
//! away from singularities is exact.

use nalgebra::{Cholesky, Matrix6, RealField, Vector6};

use super::error::ControlError;

/// When and how hard the Jacobian solve is damped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DampingConfig<T> {
    /// Manipulability `w0 = |det J|` (m^3) below which damping starts.
    pub manipulability_threshold: T,
    /// Damping `lambda_max` reached at `|det J| = 0` (units of the rows of `J`).
    pub max_damping: T,
}

impl<T: RealField + Copy> DampingConfig<T> {
    /// Rejects NaN, infinite or negative parameters.
    pub fn validate(&self) -> Result<(), ControlError> {
        let ok = |x: T| x.is_finite() && x >= T::zero();
        if !ok(self.manipulability_threshold) || !ok(self.max_damping) {
            return Err(ControlError::InvalidConfiguration(
                "damping parameters must be finite and >= 0",
            ));
        }
        Ok(())
    }

    /// `lambda^2 = lambda_max^2 (1 - w / w0)^2` for `w < w0`, else 0: grows
    /// smoothly from zero as the arm approaches a singularity.
    pub fn damping_squared(&self, manipulability: T) -> T {
        if manipulability >= self.manipulability_threshold {
            return T::zero();
        }
        let closeness = T::one() - manipulability / self.manipulability_threshold;
        let lambda = self.max_damping * closeness;
        lambda * lambda
    }
}

/// Result of one damped solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DampedSolution<T> {
    /// `x = J^T (J J^T + lambda^2 I)^-1 b`.
    pub x: Vector6<T>,
    /// Manipulability `|det J| = sqrt(det(J J^T))`.
    pub manipulability: T,
    /// The damping `lambda^2` that was applied (0 away from singularities).
    pub damping_squared: T,
}

/// Solves `J x = b` in the damped least-squares sense.
///
/// One Cholesky factorisation of `J J^T` gives the manipulability as the
/// product of its diagonal (no SVD needed on the M4F); a second one, of the
/// damped matrix, is done only inside the damping band. Returns
/// [`ControlError::SolveFailed`] if the damped matrix is not positive definite
/// (only possible with non-finite input or `max_damping = 0` at a singularity).
pub fn solve_damped<T: RealField + Copy>(
    jacobian: &Matrix6<T>,
    b: &Vector6<T>,
    config: &DampingConfig<T>,
) -> Result<DampedSolution<T>, ControlError> {
    let jjt = jacobian * jacobian.transpose();
    let undamped = Cholesky::new(jjt);
    let manipulability = match &undamped {
        Some(chol) => chol
            .l_dirty()
            .diagonal()
            .iter()
            .fold(T::one(), |p, &d| p * d),
        None => T::zero(),
    };
    let damping_squared = config.damping_squared(manipulability);
    let factor = match undamped {
        Some(chol) if damping_squared == T::zero() => chol,
        _ => {
            let damped = jjt + Matrix6::from_diagonal_element(damping_squared);
            Cholesky::new(damped).ok_or(ControlError::SolveFailed)?
        }
    };
    let x = jacobian.transpose() * factor.solve(b);
    Ok(DampedSolution {
        x,
        manipulability,
        damping_squared,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::splitmix;

    const CONFIG: DampingConfig<f64> = DampingConfig {
        manipulability_threshold: 1e-3,
        max_damping: 0.05,
    };

    #[test]
    fn well_conditioned_solve_is_exact() {
        let mut seed = 7_u64;
        for _ in 0..200 {
            let j = Matrix6::from_fn(|_, _| splitmix(&mut seed) - 0.5) + Matrix6::identity();
            let b = Vector6::from_fn(|_, _| 4.0 * splitmix(&mut seed) - 2.0);
            let sol = solve_damped(&j, &b, &CONFIG).unwrap();
            if sol.manipulability < CONFIG.manipulability_threshold {
                continue;
            }
            assert_eq!(sol.damping_squared, 0.0);
            assert!((j * sol.x - b).norm() < 1e-9 * (1.0 + b.norm()));
            assert!((sol.manipulability - j.determinant().abs()).abs() < 1e-9);
        }
    }

    /// At an exact singularity the solution stays finite and within |b|/(2 lambda_max).
    #[test]
    fn singular_jacobian_stays_bounded() {
        let mut seed = 11_u64;
        for _ in 0..200 {
            let mut j = Matrix6::from_fn(|_, _| splitmix(&mut seed) - 0.5);
            let col = j.column(1).clone_owned();
            j.set_column(4, &(col * 2.0)); // rank 5
            let b = Vector6::from_fn(|_, _| 4.0 * splitmix(&mut seed) - 2.0);
            let sol = solve_damped(&j, &b, &CONFIG).unwrap();
            assert!(sol.x.iter().all(|v| v.is_finite()));
            assert!(sol.damping_squared > 0.9 * CONFIG.max_damping.powi(2));
            assert!(sol.x.norm() <= b.norm() / (2.0 * CONFIG.max_damping) * 1.0001);
        }
    }

    #[test]
    fn nan_jacobian_is_an_error() {
        let mut j = Matrix6::<f64>::identity();
        j[(2, 3)] = f64::NAN;
        assert_eq!(
            solve_damped(&j, &Vector6::repeat(1.0), &CONFIG),
            Err(ControlError::SolveFailed)
        );
    }
}
