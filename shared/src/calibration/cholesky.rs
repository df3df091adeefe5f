//! In-place Cholesky factorisation and solve of a small symmetric positive-definite
//! matrix, for the Levenberg-Marquardt step of the bundle adjustment ([`super::refine`]).
//!
//! In place and generic over the size, so that the Schur complement of
//! [`super::normal_blocks`] factorises its 10x10 camera-and-base system and each 3x3
//! feature block without a second copy of either on a firmware stack.

use nalgebra::SMatrix;

/// Factorises `a = L L^T` in place: `a`'s lower triangle becomes L (the strict upper
/// triangle is left as it was). False, with `a` spoilt, when `a` is not positive
/// definite (a pivot not above zero, or not finite).
pub fn factor_in_place<const N: usize>(a: &mut SMatrix<f64, N, N>) -> bool {
    let at = |a: &SMatrix<f64, N, N>, i: usize, j: usize| a.get((i, j)).copied().unwrap_or(0.0);
    for j in 0..N {
        let mut pivot = at(a, j, j);
        for k in 0..j {
            let l = at(a, j, k);
            pivot -= l * l;
        }
        if !(pivot.is_finite() && pivot > 0.0) {
            return false;
        }
        let diagonal = libm::sqrt(pivot);
        if let Some(e) = a.get_mut((j, j)) {
            *e = diagonal;
        }
        for i in (j + 1)..N {
            let mut value = at(a, i, j);
            for k in 0..j {
                value -= at(a, i, k) * at(a, j, k);
            }
            if let Some(e) = a.get_mut((i, j)) {
                *e = value / diagonal;
            }
        }
    }
    true
}

/// Overwrites every column of `b` with the solution x of `L L^T x = b`, `factor`'s
/// lower triangle being L from [`factor_in_place`].
pub fn solve_in_place<const N: usize, const M: usize>(
    factor: &SMatrix<f64, N, N>,
    b: &mut SMatrix<f64, N, M>,
) {
    let l = |i: usize, j: usize| factor.get((i, j)).copied().unwrap_or(0.0);
    for mut column in b.column_iter_mut() {
        // L y = b, then L^T x = y.
        for i in 0..N {
            let mut value = column.get(i).copied().unwrap_or(0.0);
            for k in 0..i {
                value -= l(i, k) * column.get(k).copied().unwrap_or(0.0);
            }
            if let Some(e) = column.get_mut(i) {
                *e = value / l(i, i);
            }
        }
        for i in (0..N).rev() {
            let mut value = column.get(i).copied().unwrap_or(0.0);
            for k in (i + 1)..N {
                value -= l(k, i) * column.get(k).copied().unwrap_or(0.0);
            }
            if let Some(e) = column.get_mut(i) {
                *e = value / l(i, i);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type Square = SMatrix<f64, 10, 10>;

    /// A symmetric positive-definite matrix of the camera-and-base system's size.
    fn spd(seed: u64) -> Square {
        let mut state = seed;
        let m = Square::from_fn(|_, _| crate::test_rng::splitmix(&mut state) - 0.5);
        m * m.transpose() + Square::identity() * 0.1
    }

    #[test]
    fn the_in_place_solve_agrees_with_nalgebras_cholesky() {
        for seed in 1..20 {
            let a = spd(seed);
            let b = SMatrix::<f64, 10, 3>::from_fn(|i, j| ((i + 7 * j) as f64 * 0.37).sin());
            let expected = nalgebra::Cholesky::new(a).unwrap().solve(&b);
            let (mut factor, mut x) = (a, b);
            assert!(factor_in_place(&mut factor));
            solve_in_place(&factor, &mut x);
            assert!(
                (x - expected).norm() <= 1e-9 * expected.norm(),
                "seed {seed}"
            );
            assert!((a * x - b).norm() <= 1e-9 * b.norm() * a.norm());
        }
    }

    #[test]
    fn a_matrix_that_is_not_positive_definite_is_refused() {
        let mut a = spd(3);
        if let Some(e) = a.get_mut((5, 5)) {
            *e = -1.0;
        }
        assert!(!factor_in_place(&mut a));
        let mut nan = spd(4);
        if let Some(e) = nan.get_mut((0, 0)) {
            *e = f64::NAN;
        }
        assert!(!factor_in_place(&mut nan));
    }
}
