//! The drop-off the user states, checked when the configuration arrives: the
//! gripper must reach it, lowered and at its hover height, and it must stand
//! clear of the robot's own column. The disc's place is unknown then; the
//! user keeps the bin clear of the conveyor, as in any cell.

use nalgebra::Vector3;

use super::cell::ConfigError;
use super::settings::PickSettings;
use crate::app::tool::TOOL_LENGTH_M;
use crate::planning::within_reach;
use crate::robot::Puma560;

/// Nearest the drop-off may be to the base axis, m: the robot's column (0.2
/// m) and the wrist over the shoulder (a singularity) are inside it.
pub const MIN_DROP_OFF_RADIUS_M: f32 = 0.35;

const FIELD: &str = "drop_off_base_m";

/// Checks the drop-off `drop_off_base` (the part's grasp point when placed,
/// base frame) against the arm's reach and joint 1's range.
pub fn check_drop_off(
    model: &Puma560<f32>,
    drop_off_base: &Vector3<f32>,
    settings: &PickSettings,
) -> Result<(), ConfigError> {
    if !drop_off_base.iter().all(|x| x.is_finite()) {
        return Err(ConfigError::new(FIELD, "is not finite"));
    }
    let radius = drop_off_base.xy().norm();
    if radius < MIN_DROP_OFF_RADIUS_M {
        return Err(ConfigError::new(
            FIELD,
            "is within 0.35 m of the base axis (the robot's column)",
        ));
    }
    // Lowered onto the drop-off, and at the hover height of the carry.
    let place = drop_off_base + Vector3::new(0.0, 0.0, TOOL_LENGTH_M as f32);
    let hover = place + Vector3::new(0.0, 0.0, settings.drop_hover_m);
    if !(within_reach(model, &place) && within_reach(model, &hover)) {
        return Err(ConfigError::new(FIELD, "is out of the arm's reach"));
    }
    // The arm's plane is offset d2 + d3 from the base axis, so joint 1 turns
    // up to asin(offset / radius) beyond the drop-off's azimuth.
    let [_, l2, l3, ..] = model.dh_table();
    let offset = libm::fabsf(l2.d + l3.d);
    let swing = libm::asinf((offset / radius).min(1.0));
    let azimuth = libm::atan2f(drop_off_base.y, drop_off_base.x);
    let limits = model.joint_limits();
    let (low, high) = (limits.position_min.x, limits.position_max.x);
    if azimuth - swing < low || azimuth + swing > high {
        return Err(ConfigError::new(FIELD, "is beyond joint 1's range"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(x: f32, y: f32, z: f32) -> Result<(), ConfigError> {
        let model = Puma560::<f64>::new().cast::<f32>();
        check_drop_off(&model, &Vector3::new(x, y, z), &PickSettings::default())
    }

    #[test]
    fn a_bin_beside_the_robot_is_accepted() {
        assert_eq!(check(-0.275, 0.476, 0.3), Ok(()));
        assert_eq!(check(0.0, 0.55, 0.3), Ok(()));
        assert_eq!(check(0.0, -0.55, 0.2), Ok(()));
    }

    #[test]
    fn a_bad_drop_off_is_refused_by_name_and_why() {
        let near = check(0.1, 0.1, 0.3).unwrap_err();
        assert_eq!(near.field, FIELD);
        assert!(near.reason.contains("column"), "{near}");
        let far = check(1.2, 0.6, 0.3).unwrap_err();
        assert!(far.reason.contains("reach"), "{far}");
        let high = check(0.4, 0.3, 1.5).unwrap_err();
        assert!(high.reason.contains("reach"), "{high}");
        let behind = check(-0.55, -0.02, 0.3).unwrap_err();
        assert!(behind.reason.contains("joint 1"), "{behind}");
        let nan = check(f32::NAN, 0.5, 0.3).unwrap_err();
        assert!(nan.reason.contains("finite"), "{nan}");
    }
}
