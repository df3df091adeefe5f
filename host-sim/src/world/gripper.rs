//! A simple gripper: closing succeeds only when the jaws are over the grasp point
//! within a stated tolerance, turned to the part within a stated angle, and
//! moving with it (small relative speed); otherwise it closes on nothing (or
//! knocks the part, which the simulator reports as a failed grasp).

use nalgebra::Vector3;

/// The tolerances a grasp must meet.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GraspTolerance {
    pub position_m: f64,
    pub yaw_rad: f64,
    pub relative_speed_m_s: f64,
}

impl Default for GraspTolerance {
    /// 5 mm, 3 degrees, 2 cm/s: a parallel gripper with about 1 cm of jaw clearance.
    fn default() -> Self {
        Self {
            position_m: 0.005,
            yaw_rad: 3f64.to_radians(),
            relative_speed_m_s: 0.02,
        }
    }
}

/// What closing the gripper did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GraspOutcome {
    Grasped {
        position_error_m: f64,
        yaw_error_rad: f64,
        relative_speed_m_s: f64,
    },
    Missed {
        position_error_m: f64,
        yaw_error_rad: f64,
        relative_speed_m_s: f64,
    },
}

impl GraspOutcome {
    pub fn succeeded(&self) -> bool {
        matches!(self, Self::Grasped { .. })
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
    let position_error_m = (jaw_position - grasp_point).norm();
    let relative_speed_m_s = (jaw_velocity - part_velocity).norm();
    let d = (jaw_yaw - part_yaw).rem_euclid(core::f64::consts::PI);
    let yaw_error_rad = d.min(core::f64::consts::PI - d);
    let ok = position_error_m <= tolerance.position_m
        && yaw_error_rad <= tolerance.yaw_rad
        && relative_speed_m_s <= tolerance.relative_speed_m_s;
    if ok {
        GraspOutcome::Grasped {
            position_error_m,
            yaw_error_rad,
            relative_speed_m_s,
        }
    } else {
        GraspOutcome::Missed {
            position_error_m,
            yaw_error_rad,
            relative_speed_m_s,
        }
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
        let far = p + Vector3::new(0.006, 0.0, 0.0);
        assert!(!try_grasp(&tol, &far, &v, 0.1, &p, &v, 0.1).succeeded());
        assert!(!try_grasp(&tol, &p, &v, 0.2, &p, &v, 0.1).succeeded());
        let fast = v + Vector3::new(0.03, 0.0, 0.0);
        assert!(!try_grasp(&tol, &p, &fast, 0.1, &p, &v, 0.1).succeeded());
        assert!(!try_grasp(&tol, &Vector3::repeat(f64::NAN), &v, 0.1, &p, &v, 0.1).succeeded());
    }
}
