//! Joint-angle sine and cosine at full precision without f64 arithmetic.
//!
//! Measured on the emulated Cortex-M4F (bench-m4), libm's `sincosf` costs about
//! 2,100 instructions per call because its argument reduction and kernels run in
//! f64, which the M4F emulates in software: the six joints' `sin`/`cos` were 60 %
//! of a control step. micromath's approximations are cheap but off by ~1e-3,
//! which puts the kinematics 1.2 mm off (tests/control_micromath.rs). This module
//! keeps full precision in the working type: Cody-Waite reduction by `pi/2` with
//! a three-part constant (exact products for the small quadrant counts of joint
//! angles), then Taylor polynomials on `[-pi/4, pi/4]` whose length follows the
//! type's epsilon (f32: through `r^9`/`r^10`, truncation < 2e-9; f64: through
//! `r^17`/`r^18`, truncation < 1e-19). Arguments beyond `|x| > 64` (no joint
//! reaches them) go to the library routine.

use nalgebra::RealField;

/// `pi/2 = PIO2_1 + PIO2_2 + PIO2_3`; the first two have few significant bits
/// so that `k * PIO2_1` and `k * PIO2_2` are exact in f32 for small `k`.
const PIO2_1: f64 = 1.570_312_5;
const PIO2_2: f64 = 4.837_512_969_970_703e-4;
const PIO2_3: f64 = 7.549_789_954_891_882e-8;
/// Above this the three-part reduction loses digits in f32.
const MAX_REDUCED_ARGUMENT: f64 = 64.0;

/// `(sin x, cos x)`, accurate to a few ulp of `T` for `|x| <= 64`.
pub fn sin_cos<T: RealField + Copy>(x: T) -> (T, T) {
    let c = |v: f64| -> T { nalgebra::convert(v) };
    if !x.is_finite() || x.abs() > c(MAX_REDUCED_ARGUMENT) {
        // large or NaN argument: the library handles (and propagates) it
        return x.sin_cos();
    }
    // Round to nearest by adding and taking away 1.5 * 2^(mantissa bits):
    // libm's `round`/`floor` are calls of about 50 instructions on the M4F.
    // Exact for |v| < 2^22 (f32), far beyond |x| <= 64.
    let magic = if T::default_epsilon() > c(1e-10) {
        c(12_582_912.0)
    } else {
        c(6_755_399_441_055_744.0)
    };
    let round = |v: T| (v + magic) - magic;
    let quadrant = round(x * c(core::f64::consts::FRAC_2_PI));
    let r = ((x - quadrant * c(PIO2_1)) - quadrant * c(PIO2_2)) - quadrant * c(PIO2_3);
    let r2 = r * r;
    let (s, co) = if T::default_epsilon() > c(1e-10) {
        // single precision: truncation < 2e-9 on |r| <= pi/4
        let s = r
            * (c(1.0)
                + r2 * (c(-1.0 / 6.0)
                    + r2 * (c(1.0 / 120.0) + r2 * (c(-1.0 / 5040.0) + r2 * c(1.0 / 362_880.0)))));
        let co = c(1.0)
            + r2 * (c(-0.5)
                + r2 * (c(1.0 / 24.0)
                    + r2 * (c(-1.0 / 720.0)
                        + r2 * (c(1.0 / 40_320.0) + r2 * c(-1.0 / 3_628_800.0)))));
        (s, co)
    } else {
        (sin_poly_f64(r, r2), cos_poly_f64(r2))
    };
    // quadrant mod 4 in {0, 1, 2, 3}
    // floor(k / 4) = round((k - 1.5) / 4) for an integer k (no ties).
    let four = c(4.0);
    let n = quadrant - four * round((quadrant - c(1.5)) / four);
    if n == T::zero() {
        (s, co)
    } else if n == T::one() {
        (co, -s)
    } else if n == c(2.0) {
        (-s, -co)
    } else {
        (-co, s)
    }
}

/// `sin r` by Taylor series through `r^17`, Horner form.
fn sin_poly_f64<T: RealField + Copy>(r: T, r2: T) -> T {
    let mut acc = T::zero();
    // coefficients (-1)^k / (2k+1)!, k = 8 down to 1
    let mut factorial = 1.0_f64;
    let mut coefficients = [0.0_f64; 9];
    for (k, coefficient) in coefficients.iter_mut().enumerate() {
        if k > 0 {
            factorial *= ((2 * k) * (2 * k + 1)) as f64;
        }
        *coefficient = if k % 2 == 0 {
            1.0 / factorial
        } else {
            -1.0 / factorial
        };
    }
    for coefficient in coefficients.iter().rev() {
        acc = acc * r2 + nalgebra::convert::<f64, T>(*coefficient);
    }
    r * acc
}

/// `cos r` by Taylor series through `r^18`, Horner form.
fn cos_poly_f64<T: RealField + Copy>(r2: T) -> T {
    let mut acc = T::zero();
    let mut factorial = 1.0_f64;
    let mut coefficients = [0.0_f64; 10];
    for (k, coefficient) in coefficients.iter_mut().enumerate() {
        if k > 0 {
            factorial *= ((2 * k - 1) * (2 * k)) as f64;
        }
        *coefficient = if k % 2 == 0 {
            1.0 / factorial
        } else {
            -1.0 / factorial
        };
    }
    for coefficient in coefficients.iter().rev() {
        acc = acc * r2 + nalgebra::convert::<f64, T>(*coefficient);
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f32_matches_the_f64_library_to_f32_rounding() {
        let mut worst = 0.0_f64;
        for k in -200_000..=200_000 {
            let x = k as f32 * 3.3e-5; // covers +-6.6 rad, every quadrant
            let (s, c) = sin_cos(x);
            let (s_ref, c_ref) = f64::from(x).sin_cos();
            worst = worst
                .max((f64::from(s) - s_ref).abs())
                .max((f64::from(c) - c_ref).abs());
        }
        assert!(worst < 2.5e-7, "worst abs error {worst:e}");
    }

    #[test]
    fn f64_matches_the_library() {
        let mut worst = 0.0_f64;
        for k in -100_000..=100_000 {
            let x = k as f64 * 6.1e-4; // +-61 rad
            let (s, c) = sin_cos(x);
            let (s_ref, c_ref) = x.sin_cos();
            worst = worst.max((s - s_ref).abs()).max((c - c_ref).abs());
        }
        assert!(worst < 5e-15, "worst abs error {worst:e}");
    }

    #[test]
    fn quadrant_boundaries_and_special_values() {
        for k in -8..=8 {
            let x = f64::from(k) * core::f64::consts::FRAC_PI_2;
            let (s, c) = sin_cos(x);
            assert!((s - x.sin()).abs() < 1e-15 && (c - x.cos()).abs() < 1e-15);
        }
        let (s, c) = sin_cos(f32::NAN);
        assert!(s.is_nan() && c.is_nan());
        let (s, c) = sin_cos(1000.0_f32);
        assert_eq!((s, c), 1000.0_f32.sin_cos());
    }
}
