//! A simple gripper: closing succeeds only when the jaws are over the grasp point
//! within a stated tolerance, turned to the part within a stated angle, and
//! moving with it (small relative speed); otherwise it closes on nothing (or
//! knocks the part, which the simulator reports as a failed grasp).

use nalgebra::Vector3;

use crate::scenario::pick::GripperSettings;

/// The tolerances a grasp must meet. Horizontal and vertical are separate: the
/// jaws' clearance limits the horizontal error, their depth the vertical one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GraspTolerance {
    pub horizontal_m: f64,
    pub vertical_m: f64,
    pub yaw_rad: f64,
    pub relative_speed_m_s: f64,
}

impl GraspTolerance {
    /// The scenario's gripper settings in the world's units.
    pub fn from_settings(gripper: &GripperSettings) -> Self {
        Self {
            horizontal_m: gripper.horizontal_m,
            vertical_m: gripper.vertical_m,
            yaw_rad: gripper.yaw_deg.to_radians(),
            relative_speed_m_s: gripper.relative_speed_m_s,
        }
    }
}

impl Default for GraspTolerance {
    /// 5 mm across, 10 mm deep, 3 degrees, 2 cm/s: a parallel gripper with about
    /// 1 cm of jaw clearance and 2 cm of finger length below the grasp point.
    fn default() -> Self {
        Self {
            horizontal_m: 0.005,
            vertical_m: 0.010,
            yaw_rad: 3f64.to_radians(),
            relative_speed_m_s: 0.02,
        }
    }
}

/// What closing the gripper did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GraspOutcome {
    Grasped(GraspErrors),
    Missed(GraspErrors),
}

/// The jaws against the part at the instant they closed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GraspErrors {
    /// Horizontal distance of the jaws' grasp point from the part's, m.
    pub horizontal_error_m: f64,
    /// Vertical distance (absolute), m.
    pub vertical_error_m: f64,
    /// Yaw difference modulo pi, in [0, pi/2].
    pub yaw_error_rad: f64,
    pub relative_speed_m_s: f64,
}

impl GraspOutcome {
    pub fn succeeded(&self) -> bool {
        matches!(self, Self::Grasped { .. })
    }

    pub fn errors(&self) -> GraspErrors {
        match *self {
            Self::Grasped(errors) | Self::Missed(errors) => errors,
        }
    }
}

/// Judges a grasp. Yaw is compared modulo pi (two symmetric fingers).
pub fn try_grasp(
    tolerance: &GraspTolerance,
    jaw_position: &Vector3<f64>,
    jaw_velocity: &Vector3<f64>,
    jaw_yaw: f64,
    grasp_point: &Vector3<f64>,
    part_velocity: &Vector3<f64>,
    part_yaw: f64,
) -> GraspOutcome {
    let offset = jaw_position - grasp_point;
    let errors = GraspErrors {
        horizontal_error_m: offset.x.hypot(offset.y),
        vertical_error_m: offset.z.abs(),
        yaw_error_rad: {
            let d = (jaw_yaw - part_yaw).rem_euclid(core::f64::consts::PI);
            d.min(core::f64::consts::PI - d)
        },
        relative_speed_m_s: (jaw_velocity - part_velocity).norm(),
    };
    // Written so that a NaN anywhere fails every comparison: a miss.
    let ok = errors.horizontal_error_m <= tolerance.horizontal_m
        && errors.vertical_error_m <= tolerance.vertical_m
        && errors.yaw_error_rad <= tolerance.yaw_rad
        && errors.relative_speed_m_s <= tolerance.relative_speed_m_s;
    if ok {
        GraspOutcome::Grasped(errors)
    } else {
        GraspOutcome::Missed(errors)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grasps_only_within_every_tolerance() {
        let tol = GraspTolerance::default();
        let p = Vector3::new(0.6, 0.1, 0.3);
        let v = Vector3::new(0.1, 0.2, 0.0);
        let near = p + Vector3::new(0.003, 0.0, 0.0);
        assert!(try_grasp(&tol, &near, &v, 0.1 + core::f64::consts::PI, &p, &v, 0.1).succeeded());
        let far = p + Vector3::new(0.004, 0.004, 0.0);
        assert!(!try_grasp(&tol, &far, &v, 0.1, &p, &v, 0.1).succeeded());
        // 8 mm too high is within the vertical tolerance, 12 mm is not.
        let high = p + Vector3::new(0.0, 0.0, 0.008);
        let outcome = try_grasp(&tol, &high, &v, 0.1, &p, &v, 0.1);
        assert!(outcome.succeeded());
        assert!((outcome.errors().vertical_error_m - 0.008).abs() < 1e-12);
        let too_high = p + Vector3::new(0.0, 0.0, -0.012);
        assert!(!try_grasp(&tol, &too_high, &v, 0.1, &p, &v, 0.1).succeeded());
        assert!(!try_grasp(&tol, &p, &v, 0.2, &p, &v, 0.1).succeeded());
        let fast = v + Vector3::new(0.03, 0.0, 0.0);
        assert!(!try_grasp(&tol, &p, &fast, 0.1, &p, &v, 0.1).succeeded());
        assert!(!try_grasp(&tol, &Vector3::repeat(f64::NAN), &v, 0.1, &p, &v, 0.1).succeeded());
    }
}
