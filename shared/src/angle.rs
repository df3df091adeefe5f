//! Angles wrapped to (-pi, pi]: the range the contract gives every yaw
//! (`docs/reference/frames-and-log.md`) and the one Eq 2's sine and cosine are
//! taken in. One helper, [`wrap_pi`], for the control loop's `f32` and for the
//! calibration's and the simulator's `f64`.

use nalgebra::{convert, RealField};

/// A floating-point angle [`wrap_pi`] wraps: `f32` and `f64`.
///
/// Each precision has the reduction its users need. `f32` is the control
/// loop's: whole turns are subtracted with a two-part `2 pi` (Cody-Waite),
/// because `atan2(sin, cos)` through libm runs its kernels in `f64`, which the
/// M4F emulates in software (about 2,200 instructions a call against about
/// 30); `k * TWO_PI_HIGH` is exact in `f32` for `|k| < 2^15` turns, so the
/// result is as accurate as the input. `f64` is the calibration's and the
/// simulator's: the reduction is IEEE `remainder` by `2 pi`, which is exact,
/// so a reported yaw is the estimated angle itself less whole turns.
pub trait WrapPi: Copy + sealed::Sealed {
    /// `self` wrapped to (-pi, pi]; NaN for a non-finite angle.
    fn wrap_pi(self) -> Self;
}

mod sealed {
    /// Only the two float types: [`super::WrapPi`]'s reductions are theirs.
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for f64 {}
}

/// `angle` wrapped to (-pi, pi] (see [`WrapPi`] for how, per precision); a
/// non-finite angle gives NaN.
pub fn wrap_pi<T: WrapPi>(angle: T) -> T {
    angle.wrap_pi()
}

impl WrapPi for f32 {
    fn wrap_pi(self) -> Self {
        cody_waite(self)
    }
}

impl WrapPi for f64 {
    fn wrap_pi(self) -> Self {
        const PI: f64 = core::f64::consts::PI;
        let wrapped = libm::remainder(self, 2.0 * PI);
        // `remainder` lands in [-pi, pi]; -pi is the same angle as pi.
        if wrapped <= -PI {
            wrapped + 2.0 * PI
        } else {
            wrapped
        }
    }
}

/// Subtraction of whole turns with a two-part `2 pi` (see [`WrapPi`]).
fn cody_waite<T: RealField + Copy>(angle: T) -> T {
    /// `2 pi = TWO_PI_HIGH + TWO_PI_LOW`, the first with 9 significant bits.
    const TWO_PI_HIGH: f64 = 6.281_25;
    const TWO_PI_LOW: f64 = core::f64::consts::TAU - TWO_PI_HIGH;
    let high: T = convert(TWO_PI_HIGH);
    let low: T = convert(TWO_PI_LOW);
    let turns = (angle / T::two_pi()).round();
    let mut wrapped = (angle - turns * high) - turns * low;
    // Rounding to the nearest turn leaves [-pi, pi] up to an ulp either way.
    if wrapped <= -T::pi() {
        wrapped += T::two_pi();
    } else if wrapped > T::pi() {
        wrapped -= T::two_pi();
    }
    if angle.is_finite() {
        wrapped
    } else {
        angle * T::zero()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::{PI, TAU};

    #[test]
    fn wrap_pi_agrees_with_atan2_of_sine_and_cosine() {
        for k in -200_000..=200_000 {
            let angle = f64::from(k) * 7.3e-4; // +-146 rad, every branch
            let expected = angle.sin().atan2(angle.cos());
            let wrapped = wrap_pi(angle);
            assert!(wrapped > -PI && wrapped <= PI);
            let difference = (wrapped - expected).abs();
            // +-pi are the same angle
            let difference = difference.min((difference - TAU).abs());
            assert!(difference < 1e-13, "{angle}: {wrapped} vs {expected}");
            let single = wrap_pi(angle as f32);
            let difference = (f64::from(single) - expected).abs();
            let difference = difference.min((difference - TAU).abs());
            assert!(difference < 2e-5, "f32 {angle}: {single} vs {expected}");
        }
        assert_eq!(wrap_pi(-PI), PI);
        assert_eq!(wrap_pi(PI), PI);
        assert_eq!(wrap_pi(0.0_f32), 0.0);
        assert!(wrap_pi(f32::NAN).is_nan());
        assert!(wrap_pi(f32::INFINITY).is_nan());
        assert!(wrap_pi(f64::NAN).is_nan());
        assert!(wrap_pi(f64::INFINITY).is_nan());
    }

    #[test]
    fn wrap_pi_lands_in_the_half_open_interval() {
        assert!((wrap_pi(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_pi(0.5 + 4.0 * TAU) - 0.5).abs() < 1e-9);
        assert!((wrap_pi(-0.5 - TAU) + 0.5).abs() < 1e-9);
    }

    /// In `f64` the reduction is exact: whole turns of the `f64` `2 pi` away.
    #[test]
    fn f64_reduction_is_exact() {
        for angle in [0.3, 2.0, -3.0, 7.0, -19.5, 123.456, 1e6 + 0.25] {
            assert_eq!(wrap_pi(angle), libm::remainder(angle, TAU));
        }
    }
}
