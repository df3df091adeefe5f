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

use nalgebra::{Matrix6, RealField, Vector6};

use super::error::ControlError;
use crate::kernels::{dot6, rows6};

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

/// `J J^T + lambda^2 I` factorised once, for as many right-hand sides as the
/// caller has: Eq 23 solves for the joint accelerations and, on the same
/// factor, for the joint speeds its reference asks for (the speed guard).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DampedFactor<T> {
    lower: [[T; 6]; 6],
    diagonal: [T; 6],
    /// The columns of `J` (`x = J^T y`).
    columns: [[T; 6]; 6],
    /// Manipulability `|det J| = sqrt(det(J J^T))`.
    pub manipulability: T,
    /// The damping `lambda^2` that was applied (0 away from singularities).
    pub damping_squared: T,
}

impl<T: RealField + Copy> DampedFactor<T> {
    /// Factorises `J J^T`, damped inside the manipulability band.
    ///
    /// One LDL^T factorisation of `J J^T` gives the manipulability as the
    /// product of its diagonal (no SVD needed on the M4F); a second one, of
    /// the damped matrix, is done only inside the damping band. Returns
    /// [`ControlError::SolveFailed`] if the damped matrix is not positive
    /// definite (only possible with non-finite input or `max_damping = 0` at
    /// a singularity).
    pub fn new(jacobian: &Matrix6<T>, config: &DampingConfig<T>) -> Result<Self, ControlError> {
        // Plain arrays and a square-root-free LDL^T: the firmware is built for
        // size, and there nalgebra's generic product and `Cholesky` cost 5,300
        // instructions on the M4F (bench-m4).
        let rows = rows6(jacobian);
        let jjt = gram(&rows);
        // Factorised in place: returning a factor by value costs copies on the
        // M4F that are as dear as the arithmetic.
        let mut lower = jjt;
        let mut diagonal = [T::zero(); 6];
        let undamped = factor_in_place(&mut lower, &mut diagonal);
        let manipulability = if undamped {
            let [d0, d1, d2, d3, d4, d5] = diagonal;
            (d0 * d1 * d2 * d3 * d4 * d5).sqrt()
        } else {
            T::zero()
        };
        let damping_squared = config.damping_squared(manipulability);
        if !undamped || damping_squared != T::zero() {
            lower = jjt;
            for (i, row) in lower.iter_mut().enumerate() {
                if let Some(d) = row.get_mut(i) {
                    *d += damping_squared;
                }
            }
            if !factor_in_place(&mut lower, &mut diagonal) {
                return Err(ControlError::SolveFailed);
            }
        }
        Ok(Self {
            lower,
            diagonal,
            columns: (*jacobian).into(),
            manipulability,
            damping_squared,
        })
    }

    /// `x = J^T (J J^T + lambda^2 I)^-1 b`.
    pub fn solve(&self, b: &Vector6<T>) -> Vector6<T> {
        let y = solve_factored(&self.lower, &self.diagonal, &(*b).into());
        // x = J^T y: element c is column c of J dotted with y.
        let [c0, c1, c2, c3, c4, c5] = &self.columns;
        Vector6::new(
            dot6(c0, &y),
            dot6(c1, &y),
            dot6(c2, &y),
            dot6(c3, &y),
            dot6(c4, &y),
            dot6(c5, &y),
        )
    }
}

/// Solves `J x = b` in the damped least-squares sense (see [`DampedFactor`]).
pub fn solve_damped<T: RealField + Copy>(
    jacobian: &Matrix6<T>,
    b: &Vector6<T>,
    config: &DampingConfig<T>,
) -> Result<DampedSolution<T>, ControlError> {
    let factor = DampedFactor::new(jacobian, config)?;
    Ok(DampedSolution {
        x: factor.solve(b),
        manipulability: factor.manipulability,
        damping_squared: factor.damping_squared,
    })
}

/// The lower triangle of `J J^T` (all the factorisation reads), from the rows of `J`.
fn gram<T: RealField + Copy>(rows: &[[T; 6]; 6]) -> [[T; 6]; 6] {
    let [r0, r1, r2, r3, r4, r5] = rows;
    let z = T::zero();
    let d = dot6::<T>;
    [
        [d(r0, r0), z, z, z, z, z],
        [d(r1, r0), d(r1, r1), z, z, z, z],
        [d(r2, r0), d(r2, r1), d(r2, r2), z, z, z],
        [d(r3, r0), d(r3, r1), d(r3, r2), d(r3, r3), z, z],
        [d(r4, r0), d(r4, r1), d(r4, r2), d(r4, r3), d(r4, r4), z],
        [
            d(r5, r0),
            d(r5, r1),
            d(r5, r2),
            d(r5, r3),
            d(r5, r4),
            d(r5, r5),
        ],
    ]
}

/// `sum_k a_k d_k b_k`.
#[inline(always)]
fn weighted_dot6<T: RealField + Copy>(a: &[T; 6], d: &[T; 6], b: &[T; 6]) -> T {
    let [a0, a1, a2, a3, a4, a5] = *a;
    let [d0, d1, d2, d3, d4, d5] = *d;
    let [b0, b1, b2, b3, b4, b5] = *b;
    a0 * d0 * b0 + a1 * d1 * b1 + a2 * d2 * b2 + a3 * d3 * b3 + a4 * d4 * b4 + a5 * d5 * b5
}

/// `A = L D L^T` of a symmetric positive-definite 6x6, in place: `a`'s lower
/// triangle in, `L`'s strictly lower part out (zeros on and above the
/// diagonal), `D` into `diagonal`. No square roots: `det A = prod D_i`.
/// False (with `a` spoilt) unless every pivot is finite and positive.
///
/// Row `i` of `L` is built in a zeroed row, left to right, and `D_k` is zero
/// for `k >= i`, so full six-term weighted dot products sum exactly the
/// recursion's terms `sum_{k<j} L_ik D_k L_jk`.
fn factor_in_place<T: RealField + Copy>(a: &mut [[T; 6]; 6], diagonal: &mut [T; 6]) -> bool {
    *diagonal = [T::zero(); 6];
    for i in 0..6 {
        let Some(&a_row) = a.get(i) else {
            return false;
        };
        let mut l_row = [T::zero(); 6];
        for (j, (&a_ij, l_j)) in a_row.iter().zip(a.iter()).enumerate().take(i) {
            let d_j = diagonal.get(j).copied().unwrap_or_else(T::one);
            let value = (a_ij - weighted_dot6(&l_row, diagonal, l_j)) / d_j;
            if let Some(slot) = l_row.get_mut(j) {
                *slot = value;
            }
        }
        let pivot =
            a_row.get(i).copied().unwrap_or_else(T::zero) - weighted_dot6(&l_row, diagonal, &l_row);
        if !(pivot.is_finite() && pivot > T::zero()) {
            return false;
        }
        if let (Some(d), Some(row)) = (diagonal.get_mut(i), a.get_mut(i)) {
            *d = pivot;
            *row = l_row;
        }
    }
    true
}

/// `A^-1 b` from [`factor_in_place`]'s `L` and `D`: `L z = b`, `y = D^-1 z`,
/// `L^T x = y`. `L z = b` solves into a vector whose unsolved entries are
/// still zero, so a full dot product with the zero-padded row sums only the
/// solved ones; `L^T x = y` runs up the rows of `L`, subtracting each solved
/// `x_i` from the entries before it.
fn solve_factored<T: RealField + Copy>(
    lower: &[[T; 6]; 6],
    diagonal: &[T; 6],
    b: &[T; 6],
) -> [T; 6] {
    let mut x = [T::zero(); 6];
    for (i, l_row) in lower.iter().enumerate() {
        let value = b.get(i).copied().unwrap_or_else(T::zero) - dot6(l_row, &x);
        if let Some(slot) = x.get_mut(i) {
            *slot = value;
        }
    }
    for (x_i, d) in x.iter_mut().zip(diagonal.iter()) {
        *x_i /= *d;
    }
    for (i, l_row) in lower.iter().enumerate().rev() {
        let x_i = x.get(i).copied().unwrap_or_else(T::zero);
        for (x_k, &l_ik) in x.iter_mut().zip(l_row.iter()).take(i) {
            *x_k -= l_ik * x_i;
        }
    }
    x
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
