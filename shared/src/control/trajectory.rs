//! Desired flange motion for the pick task: a horizontal circle at constant rate.
//!
//! A part on the rotating disc moves on a circle in a plane parallel to the
//! base XY-plane (spec: the disc plane and the base XY-plane are parallel), so
//! this is the reference the arm must follow to stay above a part while it is
//! grasped. Pose, twist and classical acceleration are analytic, so Eq 23's
//! feed-forward `a_d` is exact.

use nalgebra::{Isometry3, RealField, Translation3, UnitQuaternion, Vector3, Vector6};

use super::computed_torque::TaskReference;

/// Flange origin on `centre + radius [cos(w t), sin(w t), 0]` (base frame), constant orientation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CircleTrajectory<T: RealField + Copy> {
    /// Centre of the circle in the base frame (m).
    pub centre: Vector3<T>,
    /// Radius (m).
    pub radius: T,
    /// Angular rate `w` about base +Z (rad/s).
    pub angular_rate: T,
    /// Fixed `base_from_flange` rotation (e.g. flange pointing down).
    pub orientation: UnitQuaternion<T>,
}

impl<T: RealField + Copy> CircleTrajectory<T> {
    /// Pose, twist and acceleration at time `t` (s).
    pub fn reference(&self, t: T) -> TaskReference<T> {
        let (sin, cos) = (self.angular_rate * t).sin_cos();
        let (r, w) = (self.radius, self.angular_rate);
        let position = self.centre + Vector3::new(r * cos, r * sin, T::zero());
        let zero = T::zero();
        TaskReference {
            base_from_flange: Isometry3::from_parts(Translation3::from(position), self.orientation),
            twist: Vector6::new(-r * w * sin, r * w * cos, zero, zero, zero, zero),
            acceleration: Vector6::new(-r * w * w * cos, -r * w * w * sin, zero, zero, zero, zero),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Twist and acceleration are the time derivatives of the position (central differences).
    #[test]
    fn derivatives_are_consistent() {
        let circle = CircleTrajectory {
            centre: Vector3::new(0.45, -0.15, 0.4),
            radius: 0.3,
            angular_rate: 1.3,
            orientation: UnitQuaternion::identity(),
        };
        let h = 1e-5;
        for k in 0..50 {
            let t = 0.37 * f64::from(k);
            let p = |t| circle.reference(t).base_from_flange.translation.vector;
            let v = (p(t + h) - p(t - h)) / (2.0 * h);
            let a = (p(t + h) - 2.0 * p(t) + p(t - h)) / (h * h);
            let r = circle.reference(t);
            assert!((v - r.twist.fixed_rows::<3>(0)).norm() < 1e-8);
            assert!((a - r.acceleration.fixed_rows::<3>(0)).norm() < 1e-4);
            assert!(((p(t) - circle.centre).norm() - 0.3).abs() < 1e-12);
        }
    }
}
