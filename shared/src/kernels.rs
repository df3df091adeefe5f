//! Straight-line kernels for the small vectors and matrices of the control
//! period (frame chain, Newton-Euler recursion, conveyor filter, Eq 23).
//!
//! Written out, their cost does not hang on the optimiser: where LLVM
//! neither unrolls nalgebra's generic element loops nor folds its iterator
//! adaptors (as at opt-level "s"), a `Matrix3 * Vector3` costs about 90
//! instructions on the M4F and a `Vector3 + Vector3` about 50, against 15
//! and 3 written out (bench-m4's profile). They are the same products
//! written component by component, so the results are bit for bit those of
//! nalgebra's expressions whenever the summation order is the same (it is,
//! for everything here: nalgebra sums a product's terms left to right).

use nalgebra::{Matrix3, Matrix6, RealField, Vector3, Vector6};

/// `a + b`.
#[inline(always)]
pub fn add3<T: RealField + Copy>(a: &Vector3<T>, b: &Vector3<T>) -> Vector3<T> {
    Vector3::new(a.x + b.x, a.y + b.y, a.z + b.z)
}

/// `a - b`.
#[inline(always)]
pub fn sub3<T: RealField + Copy>(a: &Vector3<T>, b: &Vector3<T>) -> Vector3<T> {
    Vector3::new(a.x - b.x, a.y - b.y, a.z - b.z)
}

/// `a * s`.
#[inline(always)]
pub fn scale3<T: RealField + Copy>(a: &Vector3<T>, s: T) -> Vector3<T> {
    Vector3::new(a.x * s, a.y * s, a.z * s)
}

/// `a * s + b * t`.
#[inline(always)]
pub fn combine3<T: RealField + Copy>(a: &Vector3<T>, s: T, b: &Vector3<T>, t: T) -> Vector3<T> {
    Vector3::new(a.x * s + b.x * t, a.y * s + b.y * t, a.z * s + b.z * t)
}

/// `a x b`.
#[inline(always)]
pub fn cross3<T: RealField + Copy>(a: &Vector3<T>, b: &Vector3<T>) -> Vector3<T> {
    Vector3::new(
        a.y * b.z - a.z * b.y,
        a.z * b.x - a.x * b.z,
        a.x * b.y - a.y * b.x,
    )
}

/// `m v`.
#[inline(always)]
pub fn mul3<T: RealField + Copy>(m: &Matrix3<T>, v: &Vector3<T>) -> Vector3<T> {
    Vector3::new(
        m.m11 * v.x + m.m12 * v.y + m.m13 * v.z,
        m.m21 * v.x + m.m22 * v.y + m.m23 * v.z,
        m.m31 * v.x + m.m32 * v.y + m.m33 * v.z,
    )
}

/// The rows of a 6x6 (nalgebra stores columns).
#[inline(always)]
pub fn rows6<T: RealField + Copy>(m: &Matrix6<T>) -> [[T; 6]; 6] {
    let [[a00, a10, a20, a30, a40, a50], [a01, a11, a21, a31, a41, a51], [a02, a12, a22, a32, a42, a52], [a03, a13, a23, a33, a43, a53], [a04, a14, a24, a34, a44, a54], [a05, a15, a25, a35, a45, a55]]: [[T; 6]; 6] =
        (*m).into();
    [
        [a00, a01, a02, a03, a04, a05],
        [a10, a11, a12, a13, a14, a15],
        [a20, a21, a22, a23, a24, a25],
        [a30, a31, a32, a33, a34, a35],
        [a40, a41, a42, a43, a44, a45],
        [a50, a51, a52, a53, a54, a55],
    ]
}

/// `a . b` for six-vectors, summed left to right (as nalgebra's products do).
#[inline(always)]
pub fn dot6<T: RealField + Copy>(a: &[T; 6], b: &[T; 6]) -> T {
    let [a0, a1, a2, a3, a4, a5] = *a;
    let [b0, b1, b2, b3, b4, b5] = *b;
    a0 * b0 + a1 * b1 + a2 * b2 + a3 * b3 + a4 * b4 + a5 * b5
}

/// `m v` for 6x6 (the Jacobian times the joint rates).
#[inline]
pub fn mul6<T: RealField + Copy>(m: &Matrix6<T>, v: &Vector6<T>) -> Vector6<T> {
    let [r0, r1, r2, r3, r4, r5] = rows6(m);
    let v: [T; 6] = (*v).into();
    Vector6::new(
        dot6(&r0, &v),
        dot6(&r1, &v),
        dot6(&r2, &v),
        dot6(&r3, &v),
        dot6(&r4, &v),
        dot6(&r5, &v),
    )
}

/// `x.max(-limit).min(limit)` by comparisons (in the firmware's build
/// `f32::max` and `min` are calls into compiler-builtins, about 10
/// instructions each). The same result for every `x`, NaN included (it gives
/// `-limit`), when `limit` is a number `>= 0`.
#[inline(always)]
pub fn clamp_symmetric<T: RealField + Copy>(x: T, limit: T) -> T {
    if x >= -limit {
        if x > limit {
            limit
        } else {
            x
        }
    } else {
        // below the range, or NaN
        -limit
    }
}

/// Microseconds to seconds in `f32`: through `u32` when the value fits, a
/// hardware conversion on the M4F, where `u64 as f32` is a software routine.
/// The same rounding either way.
#[inline(always)]
pub fn micros_to_seconds(us: u64) -> f32 {
    let seconds = match u32::try_from(us) {
        Ok(small) => small as f32,
        Err(_) => us as f32,
    };
    seconds * 1e-6
}

/// True if no entry is NaN or infinite. Branch-free: `0 x` is 0 for a
/// finite `x` and NaN otherwise, so one sum over the contiguous storage
/// tells; an early-exit `all(is_finite)` through nalgebra's iterator costs
/// about 20 instructions an entry at opt-level "s", this about 3.
#[inline]
pub fn all_finite<T: RealField + Copy, const R: usize, const C: usize>(
    m: &nalgebra::SMatrix<T, R, C>,
) -> bool {
    let mut sum = T::zero();
    for &x in m.as_slice() {
        sum += x * T::zero();
    }
    sum == T::zero()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::splitmix;

    #[test]
    fn kernels_equal_nalgebra_bit_for_bit() {
        let mut seed = 5_u64;
        let mut random = || splitmix(&mut seed) * 4.0 - 2.0;
        for _ in 0..1000 {
            let a = Vector3::new(random(), random(), random());
            let b = Vector3::new(random(), random(), random());
            let m = Matrix3::from_fn(|_, _| random());
            let (s, t) = (random(), random());
            assert_eq!(add3(&a, &b), a + b);
            assert_eq!(sub3(&a, &b), a - b);
            assert_eq!(scale3(&a, s), a * s);
            assert_eq!(combine3(&a, s, &b, t), a * s + b * t);
            assert_eq!(cross3(&a, &b), a.cross(&b));
            assert_eq!(mul3(&m, &a), m * a);
            let big = Matrix6::from_fn(|_, _| random());
            let v6 = Vector6::from_fn(|_, _| random());
            assert_eq!(mul6(&big, &v6), big * v6);
            let rows: [[f64; 6]; 6] = big.transpose().into();
            assert_eq!(rows6(&big), rows);
        }
    }

    #[test]
    fn clamp_and_time_conversion_match_the_library_forms() {
        let mut seed = 9_u64;
        for _ in 0..10_000 {
            let x = (splitmix(&mut seed) * 8.0 - 4.0) as f32;
            let limit = (splitmix(&mut seed) * 3.0) as f32;
            assert_eq!(clamp_symmetric(x, limit), x.max(-limit).min(limit));
        }
        for limit in [0.0_f32, 1.5] {
            for x in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -0.0, 0.0] {
                let (ours, library) = (clamp_symmetric(x, limit), x.max(-limit).min(limit));
                assert!(
                    ours.to_bits() == library.to_bits() || ours == library,
                    "{x} {limit}"
                );
            }
        }
        for us in [
            0_u64,
            1,
            999,
            1_000_000,
            63_300_000,
            u64::from(u32::MAX),
            u64::from(u32::MAX) + 7,
            u64::MAX,
        ] {
            assert_eq!(micros_to_seconds(us), us as f32 * 1e-6);
        }
    }

    #[test]
    fn all_finite_finds_nan_and_infinities_anywhere() {
        let mut m = nalgebra::Matrix6::<f32>::from_fn(|i, j| (i * 6 + j) as f32 - 17.5);
        assert!(all_finite(&m));
        assert!(all_finite(&nalgebra::Vector6::<f64>::repeat(f64::MAX)));
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            for index in 0..36 {
                let saved = m[index];
                m[index] = bad;
                assert!(!all_finite(&m), "{bad} at {index}");
                m[index] = saved;
            }
        }
    }
}
