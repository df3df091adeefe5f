//! Orientation error on SO(3): the log map of `R_d R^T`.
//!
//! Eq 23 needs an orientation error that is a 3-vector in the same frame as the
//! angular velocity rows of the base-frame Jacobian, and that is zero only at
//! `R = R_d`. Euler-angle differences wrap and are singular; the rotation vector
//! of `R_d R^T` (axis times angle, in the base frame) is neither, and for small
//! errors its derivative is `omega_d - omega`, which is what the `Kd` term damps.

use nalgebra::{RealField, UnitQuaternion, Vector3};

/// Rotation vector `log(R_d R^T)` in the base frame, with angle in `[0, pi]`.
///
/// Works on unit quaternions: `q_e = q_d q^*` is flipped to the `w >= 0`
/// hemisphere so that the shorter of the two equivalent rotations is returned,
/// and the angle is `2 atan2(|v|, w)`, which stays accurate both near 0 (where
/// `acos` loses half the digits) and near `pi`. Non-finite inputs give
/// non-finite outputs; the caller checks.
pub fn orientation_error<T: RealField + Copy>(
    base_from_flange_desired: &UnitQuaternion<T>,
    base_from_flange: &UnitQuaternion<T>,
) -> Vector3<T> {
    let error = base_from_flange_desired.quaternion() * base_from_flange.quaternion().conjugate();
    let (mut w, mut v) = (error.scalar(), error.imag());
    if w < T::zero() {
        w = -w;
        v = -v;
    }
    let sin_half = v.norm();
    if sin_half <= T::default_epsilon() {
        // atan2(s, w) / s -> 1 / w as s -> 0; w is ~1 here.
        return v * ((T::one() + T::one()) / w.max(T::default_epsilon()));
    }
    let angle = (T::one() + T::one()) * sin_half.atan2(w);
    v * (angle / sin_half)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::splitmix;
    use core::f64::consts::PI;

    fn random_rotation(state: &mut u64, max_angle: f64) -> UnitQuaternion<f64> {
        let axis = Vector3::new(
            splitmix(state) - 0.5,
            splitmix(state) - 0.5,
            splitmix(state) - 0.5,
        )
        .normalize();
        UnitQuaternion::from_scaled_axis(axis * (max_angle * splitmix(state)))
    }

    /// exp(e) R = R_d, |e| <= pi, for random pairs including errors near pi.
    #[test]
    fn log_map_recovers_the_relative_rotation() {
        let mut seed = 0x5eed_0001_u64;
        for _ in 0..2000 {
            let actual = random_rotation(&mut seed, PI);
            let delta = random_rotation(&mut seed, PI);
            let desired = delta * actual;
            let e = orientation_error(&desired, &actual);
            assert!(e.norm() <= PI + 1e-12);
            let rebuilt = UnitQuaternion::from_scaled_axis(e) * actual;
            assert!(rebuilt.angle_to(&desired) < 1e-9, "{e:?}");
            // away from pi the log is unique: compare with the generating vector
            if delta.angle() < PI - 1e-3 {
                assert!((e - delta.scaled_axis()).norm() < 1e-9);
            }
        }
    }

    /// Tiny errors keep full relative precision, in f32 as well.
    #[test]
    fn small_errors_are_linear() {
        let actual = UnitQuaternion::from_euler_angles(0.3_f32, -1.1, 2.0);
        for mag in [1e-7_f32, 1e-5, 1e-3] {
            let e_true = Vector3::new(0.6_f32, -0.8, 0.0) * mag;
            let desired = UnitQuaternion::from_scaled_axis(e_true) * actual;
            let e = orientation_error(&desired, &actual);
            assert!((e - e_true).norm() <= 5e-7 + 1e-3 * mag, "{mag}: {e:?}");
        }
        assert!(orientation_error(&actual, &actual).norm() < 2e-7);
    }

    #[test]
    fn nan_input_gives_nan_output() {
        let bad = UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(f64::NAN, 0.0, 0.0, 0.0));
        let e = orientation_error(&bad, &UnitQuaternion::identity());
        assert!(!e.iter().all(|x| x.is_finite()));
    }
}
