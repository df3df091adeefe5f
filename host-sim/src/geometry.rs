//! Small geometric helpers with the contract's conventions (`spec/frames-and-log.md`).

use nalgebra::{Matrix3, Vector3};

/// Rotation about +Z by `angle` (the paper's Eq 2 for `disc_from_rotating`, Eq 14 for `base_from_disc`).
///
/// Written here rather than taken from `shared`: the ground truth builds its
/// geometry independently of the estimator, so a sign error in one cannot hide
/// in the other.
pub fn rotation_z(angle_rad: f64) -> Matrix3<f64> {
    let (sin, cos) = angle_rad.sin_cos();
    Matrix3::new(cos, -sin, 0.0, sin, cos, 0.0, 0.0, 0.0, 1.0)
}

/// `angle` wrapped to (-pi, pi], the contract's range for yaw angles (the same
/// function the estimator uses: wrapping carries no convention to get wrong).
pub use shared::angle::wrap_pi as wrap_angle;

/// Absolute difference of two angles, taking the short way round (in [0, pi]).
pub fn angle_distance(a_rad: f64, b_rad: f64) -> f64 {
    wrap_angle(a_rad - b_rad).abs()
}

pub fn to_array(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

pub fn from_array(p: [f64; 3]) -> Vector3<f64> {
    Vector3::new(p[0], p[1], p[2])
}

/// Rows of a 3x3 matrix, as the contract writes rotations.
pub fn rows(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    [
        [m.m11, m.m12, m.m13],
        [m.m21, m.m22, m.m23],
        [m.m31, m.m32, m.m33],
    ]
}

pub fn from_rows(r: &[[f64; 3]; 3]) -> Matrix3<f64> {
    let [[a, b, c], [d, e, f], [g, h, i]] = *r;
    Matrix3::new(a, b, c, d, e, f, g, h, i)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{PI, TAU};

    #[test]
    fn wrap_angle_lands_in_half_open_interval() {
        assert_eq!(wrap_angle(PI), PI);
        assert_eq!(wrap_angle(-PI), PI);
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(0.5 + 4.0 * TAU) - 0.5).abs() < 1e-9);
        assert!((wrap_angle(-0.5 - TAU) + 0.5).abs() < 1e-9);
        assert!((angle_distance(PI - 0.01, -PI + 0.01) - 0.02).abs() < 1e-12);
    }

    #[test]
    fn rotation_z_turns_x_towards_y() {
        let turned = rotation_z(PI / 2.0) * Vector3::x();
        assert!((turned - Vector3::y()).norm() < 1e-15);
    }
}
