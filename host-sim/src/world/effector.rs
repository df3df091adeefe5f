//! End-effector poses shown to the camera for the robot-to-disc calibration
//! (paper Section 3.2): two marks on the tool 0.1 m apart, 0.05 to 0.5 m above
//! the disc, inside the PUMA 560's reach and in view.
//!
//! The segment between the marks is kept within 30 degrees of horizontal: Eq 15
//! recovers the base yaw from the segment's horizontal part and has no solution
//! when the segment is vertical (the paper requires it not be parallel to Z).

use std::f64::consts::{PI, TAU};

use nalgebra::Vector3;
use rand::{Rng, RngExt};

use super::dimensions::{DISC_RADIUS_M, SHOULDER_HEIGHT_M};
use super::workcell::Workcell;

pub const EFFECTOR_MARK_SPACING_M: f64 = 0.1;
pub const EFFECTOR_HEIGHT_RANGE_M: (f64, f64) = (0.05, 0.5);
pub const EFFECTOR_MAX_ELEVATION_RAD: f64 = 30.0 * PI / 180.0;
/// Distance of a mark from the shoulder (0, 0, d1) the arm can reach: a2 + d4 of
/// the PUMA 560 is 0.8636 m; the lower bound keeps the tool clear of its own base.
pub const REACH_FROM_SHOULDER_RANGE_M: (f64, f64) = (0.30, 0.85);
pub const MIN_DISTANCE_FROM_BASE_AXIS_M: f64 = 0.25;
/// Pixels an effector mark keeps from the image border before noise is added.
pub const EFFECTOR_MARGIN_PX: f64 = 3.0;
const MAX_ATTEMPTS: usize = 2000;

/// One tool pose: the two marks in the disc frame (truth) and in the base frame
/// (what the robot's kinematics report, taken as exact by the contract).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EffectorPose {
    pub marks_disc: [Vector3<f64>; 2],
    pub marks_base: [Vector3<f64>; 2],
}

pub struct EffectorSampler<'a> {
    workcell: &'a Workcell,
}

fn reachable(p_base: &Vector3<f64>) -> bool {
    let (near, far) = REACH_FROM_SHOULDER_RANGE_M;
    let from_shoulder = (p_base - Vector3::new(0.0, 0.0, SHOULDER_HEIGHT_M)).norm();
    let from_axis = p_base.x.hypot(p_base.y);
    (near..=far).contains(&from_shoulder) && from_axis >= MIN_DISTANCE_FROM_BASE_AXIS_M
}

impl<'a> EffectorSampler<'a> {
    pub fn new(workcell: &'a Workcell) -> Self {
        Self { workcell }
    }

    fn valid_mark(&self, p_disc: &Vector3<f64>) -> Option<Vector3<f64>> {
        let (low, high) = EFFECTOR_HEIGHT_RANGE_M;
        let p_base = self.workcell.base_from_disc(p_disc);
        let in_view = self
            .workcell
            .camera
            .project_in_view(p_disc, EFFECTOR_MARGIN_PX)
            .is_some();
        ((low..=high).contains(&p_disc.z) && reachable(&p_base) && in_view).then_some(p_base)
    }

    /// A random valid pose over the disc, or `None` if none was found in a bounded
    /// number of draws (the workcell generator then draws another workcell).
    pub fn sample(&self, rng: &mut impl Rng) -> Option<EffectorPose> {
        let (low, high) = EFFECTOR_HEIGHT_RANGE_M;
        (0..MAX_ATTEMPTS).find_map(|_| {
            let radius = DISC_RADIUS_M * rng.random::<f64>().sqrt();
            let angle = TAU * rng.random::<f64>();
            let first = Vector3::new(
                radius * angle.cos(),
                radius * angle.sin(),
                low + (high - low) * rng.random::<f64>(),
            );
            let azimuth = TAU * rng.random::<f64>();
            let elevation = EFFECTOR_MAX_ELEVATION_RAD * (2.0 * rng.random::<f64>() - 1.0);
            let direction = Vector3::new(
                elevation.cos() * azimuth.cos(),
                elevation.cos() * azimuth.sin(),
                elevation.sin(),
            );
            let second = first + direction * EFFECTOR_MARK_SPACING_M;
            let first_base = self.valid_mark(&first)?;
            let second_base = self.valid_mark(&second)?;
            Some(EffectorPose {
                marks_disc: [first, second],
                marks_base: [first_base, second_base],
            })
        })
    }
}
