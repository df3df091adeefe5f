//! The gripper's orientation over a part: pointing straight down at the disc
//! (the disc plane is parallel to the base XY-plane, paper assumption A2), turned
//! about the vertical to the part's yaw.

use nalgebra::{convert, RealField, Rotation3, UnitQuaternion, Vector3};

use crate::robot::JointVector;

/// `base_from_flange` rotation with the flange's z axis pointing down (-Z of the
/// base) and its x axis at `yaw` in the base XY-plane: `Rz(yaw) Rx(pi)`.
///
/// Written out, `[[c, s, 0], [s, -c, 0], [0, 0, -1]]`, with the control loop's
/// sine and cosine ([`crate::control::trig`]): it runs every control period,
/// and libm's single-precision pair costs about 2,100 instructions on the M4F.
pub fn gripper_down_rotation<T: RealField + Copy>(yaw: T) -> Rotation3<T> {
    let (s, c) = crate::control::trig::sin_cos(yaw);
    let zero = T::zero();
    Rotation3::from_matrix_unchecked(nalgebra::Matrix3::new(
        c,
        s,
        zero, //
        s,
        -c,
        zero, //
        zero,
        zero,
        -T::one(),
    ))
}

/// The gripper's yaw in `base_from_flange`: the angle of the flange's x axis
/// in the base XY-plane (the inverse of [`gripper_down_rotation`] for a
/// gripper pointing down).
pub fn gripper_yaw(base_from_flange: &UnitQuaternion<f32>) -> f32 {
    let x_axis = base_from_flange * Vector3::x();
    libm::atan2f(x_axis.y, x_axis.x)
}

/// A gripper-down posture of the PUMA 560, the toolbox's nominal `qn` with the
/// wrist bent the other way: the flange at about (0.60, -0.15, 0.66) m pointing
/// straight down, elbow up, away from the wrist singularity (q5 = -45 degrees).
/// The planner seeds its inverse kinematics here.
pub fn ready_posture<T: RealField + Copy>() -> JointVector<T> {
    let quarter: T = convert(core::f64::consts::FRAC_PI_4);
    JointVector::new(T::zero(), quarter, -T::pi(), T::zero(), -quarter, T::zero())
}

/// The yaw equivalent to `target` (modulo `symmetry`, e.g. pi for a two-finger
/// gripper, 2 pi for none) that is closest to `current`, so the wrist never turns
/// further than it must.
pub fn nearest_equivalent_yaw<T: RealField + Copy>(current: T, target: T, symmetry: T) -> T {
    if !(symmetry.is_finite() && symmetry > T::zero()) {
        return target;
    }
    let turns = ((current - target) / symmetry).round();
    target + turns * symmetry
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::PI;
    use nalgebra::Vector3;

    #[test]
    fn is_rz_of_yaw_times_rx_of_pi() {
        for yaw in [-3.0_f64, -0.7, 0.0, 0.3, 1.6, 3.1] {
            let expected = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), yaw)
                * nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), PI);
            let r = gripper_down_rotation(yaw);
            assert!((r.matrix() - expected.matrix()).norm() < 1e-14, "yaw {yaw}");
        }
    }

    #[test]
    fn points_down_with_the_requested_yaw() {
        let r = gripper_down_rotation(0.7_f64);
        let z = r * Vector3::z();
        assert!((z - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
        let x = r * Vector3::x();
        assert!((x.y.atan2(x.x) - 0.7).abs() < 1e-12);
    }

    #[test]
    fn the_ready_posture_points_down() {
        let robot = crate::robot::Puma560::<f64>::new();
        let pose = robot.forward_kinematics(&ready_posture());
        assert!((pose.rotation * Vector3::z() + Vector3::z()).norm() < 1e-12);
    }

    #[test]
    fn picks_the_nearest_equivalent_yaw() {
        assert!((nearest_equivalent_yaw(0.1, 0.1 + 2.0 * PI, 2.0 * PI) - 0.1).abs() < 1e-12);
        assert!((nearest_equivalent_yaw(0.0, 3.0, PI) - (3.0 - PI)).abs() < 1e-12);
        assert!((nearest_equivalent_yaw(6.0, -0.2, 2.0 * PI) - (-0.2 + 2.0 * PI)).abs() < 1e-12);
        assert_eq!(nearest_equivalent_yaw(0.0, 1.0, 0.0), 1.0);
    }
}
