//! Eq 1 and its time derivatives: where a point fixed on the part is in the base
//! frame, how fast it moves and how it accelerates, at control rate.
//!
//! `p_base(t) = Rz(yaw) Rz(theta(t)) p_rotating + translation` (Eq 1 with Eq 2 for
//! `Rz(theta)`). Differentiating with `S = [z]x` (the cross product with the disc's
//! +Z) gives `v = Rz(yaw) omega S Rz(theta) p_rotating` and
//! `a = Rz(yaw) (alpha S + omega^2 S^2) Rz(theta) p_rotating`: the tangential and the
//! centripetal terms. Vision gives `p_rotating` slowly; the encoder gives theta,
//! omega and alpha fast: the complementary fusion of the paper.

use nalgebra::{RealField, Vector3};

use crate::angle::{wrap_pi, WrapPi};

/// The part's motion in the base frame at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PartMotion<T: RealField + Copy> {
    /// Position, base frame.
    pub position_base: Vector3<T>,
    /// Velocity, base frame.
    pub velocity_base: Vector3<T>,
    /// Acceleration, base frame.
    pub acceleration_base: Vector3<T>,
    /// The part's yaw in the base frame (its rotating-frame yaw carried round by
    /// theta and the disc's yaw), wrapped to (-pi, pi].
    pub yaw_base: T,
    /// Its angular velocity and acceleration about the base +Z (the disc's).
    pub yaw_rate: T,
    /// Its angular acceleration (see `yaw_rate`).
    pub yaw_acceleration: T,
}

/// Eq 1 for a point `p_rotating` of a part whose rotating-frame yaw is
/// `yaw_rotating`, with `base_from_disc = (disc_yaw, disc_translation)` and the
/// conveyor at `(theta, omega, alpha)`.
pub fn part_motion_in_base<T: RealField + Copy + WrapPi>(
    disc_yaw: T,
    disc_translation_base: &Vector3<T>,
    p_rotating: &Vector3<T>,
    yaw_rotating: T,
    theta: T,
    omega: T,
    alpha: T,
) -> PartMotion<T> {
    // Rz(yaw) Rz(theta) = Rz(yaw + theta): one rotation of the plane.
    let angle = disc_yaw + theta;
    // The control loop's sine and cosine: libm's cost ~2,100 instructions on the M4F.
    let (s, c) = crate::control::trig::sin_cos(angle);
    let rotated = Vector3::new(
        c * p_rotating.x - s * p_rotating.y,
        s * p_rotating.x + c * p_rotating.y,
        p_rotating.z,
    );
    // S r = (-r_y, r_x, 0); S^2 r = (-r_x, -r_y, 0).
    let s_r = Vector3::new(-rotated.y, rotated.x, T::zero());
    let s2_r = Vector3::new(-rotated.x, -rotated.y, T::zero());
    PartMotion {
        position_base: rotated + disc_translation_base,
        velocity_base: s_r * omega,
        acceleration_base: s_r * alpha + s2_r * (omega * omega),
        yaw_base: wrap_pi(angle + yaw_rotating),
        yaw_rate: omega,
        yaw_acceleration: alpha,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Finite differences of Eq 1 along a trajectory theta(t) = 0.3 + 0.7 t + 0.2 t^2.
    #[test]
    fn velocity_and_acceleration_are_the_derivatives_of_eq_1() {
        let translation = Vector3::new(0.9, -0.3, -0.12);
        let p = Vector3::new(0.21, 0.05, 0.04);
        let theta = |t: f64| 0.3 + 0.7 * t + 0.2 * t * t;
        let at =
            |t: f64| part_motion_in_base(0.52, &translation, &p, 0.1, theta(t), 0.7 + 0.4 * t, 0.4);
        let h = 1e-4;
        for &t in &[0.0, 0.5, 2.0, 7.0] {
            let m = at(t);
            let v_fd = (at(t + h).position_base - at(t - h).position_base) / (2.0 * h);
            let a_fd = (at(t + h).position_base - 2.0 * m.position_base + at(t - h).position_base)
                / (h * h);
            assert!(
                (m.velocity_base - v_fd).norm() < 1e-6,
                "velocity at t = {t}"
            );
            assert!(
                (m.acceleration_base - a_fd).norm() < 1e-5,
                "acceleration at t = {t}"
            );
            assert_eq!(m.yaw_rate, 0.7 + 0.4 * t);
        }
    }

    #[test]
    fn matches_the_spec_composition_of_rotations() {
        // p_base = Rz(yaw) * Rz(theta) * p_rotating + translation, with explicit matrices.
        let rz = |a: f64| nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), a);
        let translation = Vector3::new(0.95, -0.30, -0.12);
        let p = Vector3::new(0.26, 0.05, 0.04);
        let m = part_motion_in_base(0.52, &translation, &p, 0.0, 2.0, 0.0, 0.0);
        let expected = rz(0.52) * rz(2.0) * p + translation;
        assert!((m.position_base - expected).norm() < 1e-12);
        assert!((m.yaw_base - wrap_pi(2.52)).abs() < 1e-12);
        // The height does not move with the disc.
        assert!((m.position_base.z - (0.04 - 0.12)).abs() < 1e-12);
    }
}
