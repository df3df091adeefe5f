//! The search for the gripper's marks, before anything is known of where the
//! disc or the camera stand. It is derived from what the controller knows of
//! itself, never from where a cell is expected to be laid out: joint 1's
//! range, the arm's reach at the travel height, and its start.
//!
//! The search sweeps the whole waist range (joint 1 from one limit to the
//! other, a margin inside each) at the travel height, one radius from the base
//! axis at a time: the start's radius first, then the others of the band the
//! arm reaches at that height, nearest first, `search_radius_step_m` apart.
//! The camera frames the disc (the paper's A4), so its view at travel height
//! is wider than that step and a disc the arm can serve is crossed by some
//! sweep. The first sweep in which the camera has seen the marks often enough
//! ends the search. When the last one ends with none seen, the sweeps run
//! again with the wrist turned ([`SEARCH_WRIST_TURNS_RAD`]); after the last
//! round the pick stops (`EffectorNotSeen`).

use nalgebra::Vector3;

use super::jobs::MIN_RADIUS_FROM_BASE_AXIS_M;
use super::settings::PickSettings;
use crate::angle::wrap_pi;
use crate::robot::{JointVector, Puma560};

/// Most sweeps of one search (radii of the band the arm reaches).
pub const MAX_SEARCH_LEGS: usize = 4;

/// How far the wrist turns about the vertical in each round of the search,
/// from its start's yaw, rad. The marks lie across the wrist, and seen from
/// the side the wrist hides one of them: through images the vision stage
/// learns the marks only from frames that show both at once, so a camera that
/// sees the gripper from its hidden side sees it in vain (images, seed 13: 12
/// cells of 1,000 found no mark that ideal points showed; with the turns
/// all 12 pick). A quarter turn, then a half turn, the same way (away from
/// joint 6's nearer stop: `Route::start_from`): each shows the camera
/// another side of the wrist.
pub const SEARCH_WRIST_TURNS_RAD: [f32; 3] =
    [0.0, core::f32::consts::FRAC_PI_2, core::f32::consts::PI];

/// The search keeps this much further from the base axis than a grasp may
/// come (the shoulder singularity, the robot's column), m.
const SEARCH_AXIS_MARGIN_M: f32 = 0.05;

/// One sweep of the waist range at one radius from the base axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SearchLeg {
    /// The flange's distance from the base axis, m.
    pub radius_m: f32,
    /// The flange's azimuth with joint 1 at its lower end of the sweep, rad
    /// (not wrapped: joint 1's angle plus the arm's offset at this radius).
    pub low_azimuth_rad: f32,
    /// The same at the sweep's upper end, rad.
    pub high_azimuth_rad: f32,
}

impl SearchLeg {
    /// The azimuth equivalent to `azimuth` (modulo a turn) within the sweep,
    /// or the sweep's nearer end when none is.
    pub fn within(&self, azimuth: f32) -> f32 {
        let middle = 0.5 * (self.low_azimuth_rad + self.high_azimuth_rad);
        let near_middle = middle + wrap_pi(azimuth - middle);
        near_middle.clamp(self.low_azimuth_rad, self.high_azimuth_rad)
    }
}

/// Why no search could be planned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SearchError {
    /// The travel height (`search_tool_height_m`) is beyond the arm's reach
    /// at every radius.
    TravelHeightOutOfReach,
    /// The start's joint angles or flange position are not finite, or the
    /// step or margin settings are not positive.
    InvalidInput,
}

/// The sweeps of the search, in the order they run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SearchPlan {
    legs: [SearchLeg; MAX_SEARCH_LEGS],
    count: u8,
    /// The flange's height during the search, m.
    flange_z_m: f32,
}

impl SearchPlan {
    /// No sweep (before the arm's start is known).
    pub const fn empty() -> Self {
        Self {
            legs: [SearchLeg {
                radius_m: 0.0,
                low_azimuth_rad: 0.0,
                high_azimuth_rad: 0.0,
            }; MAX_SEARCH_LEGS],
            count: 0,
            flange_z_m: 0.0,
        }
    }

    /// The search of an arm with joint angles `q_start` and its flange at
    /// `flange_start` (base frame), its flange at `flange_z_m` while it sweeps.
    ///
    /// The arm's plane is offset from the base axis (the PUMA's d2 + d3), so
    /// the flange's azimuth is joint 1's angle plus `atan2(lateral, along)`,
    /// where `lateral` is that offset and `along` the flange's distance along
    /// the arm's plane: both are read from the start (the flange turned back
    /// by joint 1), so the same configuration (shoulder, elbow) is kept.
    pub fn new(
        robot: &Puma560<f32>,
        q_start: &JointVector<f32>,
        flange_start: &Vector3<f32>,
        flange_z_m: f32,
        settings: &PickSettings,
    ) -> Result<Self, SearchError> {
        let q1 = q_start.x;
        let finite = q1.is_finite() && flange_start.iter().all(|x| x.is_finite());
        let settings_ok = settings.search_radius_step_m > 0.0
            && settings.search_joint1_margin_rad >= 0.0
            && settings.search_max_stretch > 0.0
            && flange_z_m.is_finite();
        if !(finite && settings_ok) {
            return Err(SearchError::InvalidInput);
        }
        // The flange in the arm's plane: along it and across it (the offset).
        // The control loop's sine and cosine: libm's sinf and cosf go
        // through soft f64 for any joint angle but a tiny one (1,900
        // instructions more in the first period from a posture off the
        // ready one, on the M4F).
        let (s, c) = crate::control::trig::sin_cos(q1);
        let along = c * flange_start.x + s * flange_start.y;
        let lateral = -s * flange_start.x + c * flange_start.y;
        let along_sign = if along < 0.0 { -1.0 } else { 1.0 };

        // The band of radii the arm reaches at the travel height.
        let [l1, l2, l3, l4, _, l6] = robot.dh_table();
        let stretch = l2.a + libm::sqrtf(l3.a * l3.a + l4.d * l4.d);
        let limit = stretch * settings.search_max_stretch;
        let vertical = flange_z_m + l6.d - l1.d;
        let across_sq = limit * limit - vertical * vertical;
        let near = (MIN_RADIUS_FROM_BASE_AXIS_M + SEARCH_AXIS_MARGIN_M).max(lateral.abs() + 1e-3);
        let far = libm::sqrtf(across_sq.max(0.0) + lateral * lateral);
        if !(across_sq > 0.0 && far > near) {
            return Err(SearchError::TravelHeightOutOfReach);
        }

        let limits = robot.joint_limits();
        let margin = settings.search_joint1_margin_rad;
        let (q1_low, q1_high) = (
            limits.position_min.x + margin,
            limits.position_max.x - margin,
        );
        let leg_at = |radius: f32| {
            let along = along_sign * libm::sqrtf((radius * radius - lateral * lateral).max(0.0));
            let offset = libm::atan2f(lateral, along);
            SearchLeg {
                radius_m: radius,
                low_azimuth_rad: q1_low + offset,
                high_azimuth_rad: q1_high + offset,
            }
        };

        // The start's radius first, then the band's others nearest first.
        let step = settings.search_radius_step_m;
        let first = flange_start.xy().norm().clamp(near, far);
        let mut plan = Self {
            flange_z_m,
            ..Self::empty()
        };
        plan.push(leg_at(first));
        let mut k = 1.0_f32;
        while usize::from(plan.count) < MAX_SEARCH_LEGS {
            let (outward, inward) = (first + k * step, first - k * step);
            if outward >= far + step && inward <= near - step {
                break;
            }
            // The nearer of the two first (they are equally far: outward).
            for radius in [outward.min(far), inward.max(near)] {
                let clear = plan
                    .legs()
                    .iter()
                    .all(|leg| (leg.radius_m - radius).abs() >= 0.5 * step);
                if clear {
                    plan.push(leg_at(radius));
                }
            }
            k += 1.0;
        }
        Ok(plan)
    }

    fn push(&mut self, leg: SearchLeg) {
        if let Some(slot) = self.legs.get_mut(usize::from(self.count)) {
            *slot = leg;
            self.count = self.count.saturating_add(1);
        }
    }

    /// The sweeps, in order.
    pub fn legs(&self) -> &[SearchLeg] {
        self.legs.get(..usize::from(self.count)).unwrap_or(&[])
    }

    /// Sweep `index`, if the plan has it.
    pub fn leg(&self, index: u8) -> Option<SearchLeg> {
        self.legs().get(usize::from(index)).copied()
    }

    /// The flange's height during the search, m.
    pub fn flange_z_m(&self) -> f32 {
        self.flange_z_m
    }

    /// Where sweep `index` starts and ends: even sweeps turn joint 1 up from
    /// its lower end, odd ones back down, so that each starts where the one
    /// before ended (a step out or in at that end).
    pub fn ends(&self, index: u8) -> Option<(f32, f32, f32)> {
        let leg = self.leg(index)?;
        let (from, to) = if index.is_multiple_of(2) {
            (leg.low_azimuth_rad, leg.high_azimuth_rad)
        } else {
            (leg.high_azimuth_rad, leg.low_azimuth_rad)
        };
        Some((leg.radius_m, from, to))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::tool::TOOL_LENGTH_M;
    use crate::planning::{ready_posture, within_stretch};

    fn robot() -> Puma560<f32> {
        Puma560::<f64>::new().cast::<f32>()
    }

    fn start(q: &JointVector<f32>) -> Vector3<f32> {
        robot().forward_kinematics(q).translation.vector
    }

    fn plan_from(q: &JointVector<f32>) -> SearchPlan {
        let settings = PickSettings::default();
        let z = settings.search_tool_height_m + TOOL_LENGTH_M as f32;
        SearchPlan::new(&robot(), q, &start(q), z, &settings).unwrap()
    }

    /// Joint 1's angle with the flange at (radius, azimuth), the rest as `q`.
    fn q1_at(q: &JointVector<f32>, radius: f32, azimuth: f32) -> f32 {
        let flange = start(q);
        let (s, c) = (libm::sinf(q.x), libm::cosf(q.x));
        let lateral = -s * flange.x + c * flange.y;
        let along = libm::sqrtf(radius * radius - lateral * lateral);
        azimuth - libm::atan2f(lateral, along)
    }

    #[test]
    fn every_sweep_covers_joint_1_range_within_its_margin() {
        let robot = robot();
        let limits = robot.joint_limits();
        let settings = PickSettings::default();
        let q = ready_posture::<f32>();
        let plan = plan_from(&q);
        assert!(plan.legs().len() >= 3, "{:?}", plan.legs());
        for leg in plan.legs() {
            let low = q1_at(&q, leg.radius_m, leg.low_azimuth_rad);
            let high = q1_at(&q, leg.radius_m, leg.high_azimuth_rad);
            let margin = settings.search_joint1_margin_rad;
            assert!(
                (low - (limits.position_min.x + margin)).abs() < 1e-4,
                "{low}"
            );
            assert!(
                (high - (limits.position_max.x - margin)).abs() < 1e-4,
                "{high}"
            );
            // More than 300 degrees of azimuth in every sweep.
            assert!(leg.high_azimuth_rad - leg.low_azimuth_rad > 5.3);
        }
    }

    #[test]
    fn the_start_radius_comes_first_then_the_band_nearest_first() {
        let settings = PickSettings::default();
        let q = ready_posture::<f32>();
        let plan = plan_from(&q);
        let radii: std::vec::Vec<f32> = plan.legs().iter().map(|l| l.radius_m).collect();
        let start_radius = start(&q).xy().norm();
        assert!((radii[0] - start_radius).abs() < 1e-5, "{radii:?}");
        let distances: std::vec::Vec<f32> =
            radii.iter().map(|r| (r - start_radius).abs()).collect();
        assert!(
            distances.windows(2).all(|d| d[0] <= d[1] + 1e-6),
            "{radii:?}"
        );
        // The band: from clear of the base axis to the arm's reach at travel height.
        let z = plan.flange_z_m();
        let robot = robot();
        for r in &radii {
            assert!(*r >= MIN_RADIUS_FROM_BASE_AXIS_M);
            assert!(within_stretch(
                &robot,
                &Vector3::new(*r, 0.0, z),
                settings.search_max_stretch + 1e-4
            ));
        }
        let widest = radii.iter().fold(0.0_f32, |a, r| a.max(*r));
        let narrowest = radii.iter().fold(f32::INFINITY, |a, r| a.min(*r));
        assert!(widest > 0.75 && narrowest < 0.45, "{radii:?}");
        // Neighbouring radii no further apart than the step.
        let mut sorted = radii.clone();
        sorted.sort_by(|a, b| a.total_cmp(b));
        assert!(sorted
            .windows(2)
            .all(|w| w[1] - w[0] <= settings.search_radius_step_m + 1e-5));
    }

    #[test]
    fn sweeps_alternate_so_each_starts_where_the_last_ended() {
        let plan = plan_from(&ready_posture::<f32>());
        for i in 1..plan.legs().len() as u8 {
            let (_, _, previous_end) = plan.ends(i - 1).unwrap();
            let (_, from, _) = plan.ends(i).unwrap();
            // The same joint-1 end (azimuths differ by the offset change only).
            assert!(
                (from - previous_end).abs() < 0.3,
                "{i}: {from} {previous_end}"
            );
        }
        assert!(plan.ends(plan.legs().len() as u8).is_none());
    }

    #[test]
    fn the_sweep_follows_joint_1_wherever_the_arm_starts() {
        // Started turned round by 120 degrees: the sweeps still span joint 1's range.
        let mut q = ready_posture::<f32>();
        q.x = 2.1;
        let plan = plan_from(&q);
        let robot = robot();
        for leg in plan.legs() {
            let low = q1_at(&q, leg.radius_m, leg.low_azimuth_rad);
            let high = q1_at(&q, leg.radius_m, leg.high_azimuth_rad);
            assert!(low >= robot.joint_limits().position_min.x);
            assert!(high <= robot.joint_limits().position_max.x);
            assert!(high - low > 5.3);
        }
    }

    #[test]
    fn a_direction_maps_into_the_sweep_or_onto_its_nearer_end() {
        let leg = SearchLeg {
            radius_m: 0.6,
            low_azimuth_rad: -2.9,
            high_azimuth_rad: 2.5,
        };
        assert!((leg.within(1.0) - 1.0).abs() < 1e-6);
        // Behind the robot, past the upper end: the upper end.
        assert!((leg.within(2.7) - 2.5).abs() < 1e-6);
        // Just past the lower end: the lower end.
        assert!((leg.within(-2.95) + 2.9).abs() < 1e-6);
        // 3.0 (a turn on) is 0.5 rad past the upper end but 0.38 below the
        // lower one (as -3.28): the lower end.
        assert!((leg.within(3.0 + core::f32::consts::TAU) + 2.9).abs() < 1e-5);
    }

    #[test]
    fn a_travel_height_out_of_reach_is_refused() {
        let settings = PickSettings::default();
        let q = ready_posture::<f32>();
        let err = SearchPlan::new(&robot(), &q, &start(&q), 2.5, &settings);
        assert_eq!(err, Err(SearchError::TravelHeightOutOfReach));
        let mut bad = start(&q);
        bad.x = f32::NAN;
        let err = SearchPlan::new(&robot(), &q, &bad, 0.8, &settings);
        assert_eq!(err, Err(SearchError::InvalidInput));
    }
}
