//! Where each step of the pick takes the arm: the search's sweeps at travel
//! height (`search`), the calibration poses, the way back to where the part was located
//! from, the lift, the transfer to the drop-off and the way home. Every arc
//! goes round the base axis within joint 1's range (never through the back
//! of the robot, where joint 1 ends), with the wrist turned as at the start.

use nalgebra::Vector3;

use super::jobs::yaw_at_azimuth;
use super::motion::{height_profile, Motion};
use super::search::{SearchError, SearchPlan, MAX_SEARCH_LEGS, SEARCH_WRIST_TURNS_RAD};
use super::settings::PickSettings;
use super::step::Step;
use crate::angle::wrap_pi;
use crate::app::tool::TOOL_LENGTH_M;
use crate::planning::{ArcLimits, ArcMove, ArcPoint, InterceptPlan, PlanError, TaskState};
use crate::robot::{JointVector, Puma560};

/// The places the pick's route is planned from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Route {
    /// Where the arm stood at the first sample (and returns to).
    start_pose: ArcPoint<f32>,
    /// The flange's azimuth with joint 1 in the middle of its range (at the
    /// start's radius): every azimuth is taken within half a turn of it, so
    /// arcs keep to joint 1's range and never swing through its ends.
    waist_centre_azimuth: f32,
    /// The search's sweeps.
    search: SearchPlan,
    /// The sweep the search is in (or ended with).
    sweep: u8,
    /// The round of the search: the wrist's turn from its start's yaw
    /// (`SEARCH_WRIST_TURNS_RAD`).
    search_round: u8,
    /// The way the wrist turns in the search's later rounds: +1 turns the
    /// yaw up (joint 6 down, gripper pointing down), -1 down.
    search_turn_sign: f32,
    /// Sightings of the marks during each sweep (and the step out to it).
    seen_per_sweep: [u16; MAX_SEARCH_LEGS],
    /// The sum of the unit vectors towards the flange at those sightings.
    seen_direction_per_sweep: [[f32; 2]; MAX_SEARCH_LEGS],
    /// The flange height of the carry to the drop-off and back.
    transfer_z: f32,
    /// Where the arm stood when the part was first located (the last
    /// calibration pose): an abandoned intercept returns there to plan again.
    locate_pose: Option<ArcPoint<f32>>,
}

/// The travel height of the flange: the search's tool height over the tool.
pub(super) fn travel_z(settings: &PickSettings) -> f32 {
    settings.search_tool_height_m + TOOL_LENGTH_M as f32
}

impl Route {
    /// No start yet.
    pub(super) fn new() -> Self {
        Self {
            start_pose: ArcPoint {
                radius_m: 0.0,
                azimuth_rad: 0.0,
                z_m: 0.0,
                yaw_rad: 0.0,
            },
            waist_centre_azimuth: 0.0,
            search: SearchPlan::empty(),
            sweep: 0,
            search_round: 0,
            search_turn_sign: 1.0,
            seen_per_sweep: [0; MAX_SEARCH_LEGS],
            seen_direction_per_sweep: [[0.0; 2]; MAX_SEARCH_LEGS],
            transfer_z: 0.0,
            locate_pose: None,
        }
    }

    /// The arm starts at `start_pose`: the search is planned from its joint
    /// angles `q_start` and flange position `flange_start`.
    pub(super) fn start_from(
        &mut self,
        start_pose: ArcPoint<f32>,
        robot: &Puma560<f32>,
        q_start: &JointVector<f32>,
        flange_start: &Vector3<f32>,
        settings: &PickSettings,
    ) -> Result<(), SearchError> {
        self.start_pose = start_pose;
        let limits = robot.joint_limits();
        let middle = 0.5 * (limits.position_min.x + limits.position_max.x);
        self.waist_centre_azimuth = start_pose.azimuth_rad + wrap_pi(middle - q_start.x);
        self.search = SearchPlan::new(robot, q_start, flange_start, travel_z(settings), settings)?;
        // With the gripper pointing down, the yaw turns against joint 6: the
        // turns take joint 6 away from its nearer stop (a half turn from
        // anywhere in its +-266 degrees leaves 86 degrees at least).
        self.search_turn_sign = if q_start.b > 0.0 { 1.0 } else { -1.0 };
        Ok(())
    }

    /// The azimuth every arc keeps within half a turn of.
    pub(super) fn waist_centre_azimuth(&self) -> f32 {
        self.waist_centre_azimuth
    }

    /// An azimuth equivalent to `azimuth` within half a turn of the middle of
    /// joint 1's range, so arcs never swing the waist through its ends.
    pub(super) fn azimuth_near_start(&self, azimuth: f32) -> f32 {
        azimuth_within_half_a_turn(self.waist_centre_azimuth, azimuth)
    }

    /// `target` with its azimuth on the start's side.
    pub(super) fn near_start(&self, mut target: ArcPoint<f32>) -> ArcPoint<f32> {
        target.azimuth_rad = self.azimuth_near_start(target.azimuth_rad);
        target
    }

    /// An arc from `from` (at rest) to `target`, starting at `now_s`.
    pub(super) fn arc(
        &self,
        from: &TaskState<f32>,
        target: ArcPoint<f32>,
        now_s: f32,
        limits: &ArcLimits<f32>,
    ) -> Result<Motion, PlanError> {
        let mut start = ArcPoint::from_position(&from.position, from.yaw);
        start.azimuth_rad = self.azimuth_near_start(start.azimuth_rad);
        let path = ArcMove::new(&start, &target, limits)?;
        Ok(Motion::Arc {
            path,
            start_s: now_s,
        })
    }

    /// The search's point at `radius` and `azimuth`, at travel height, the
    /// wrist as at the start turned by the round's turn.
    fn search_point(&self, radius: f32, azimuth: f32) -> ArcPoint<f32> {
        ArcPoint {
            radius_m: radius,
            azimuth_rad: azimuth,
            z_m: self.search.flange_z_m(),
            yaw_rad: yaw_at_azimuth(&self.start_pose, azimuth) + self.search_wrist_turn(),
        }
    }

    /// The start pose with the wrist turned as the search's present round
    /// turned it: the calibration poses keep this wrist, the one the camera
    /// was last shown both marks with (the marks lie across the wrist, which
    /// hides one of them from a camera on that side; from poses at the start's
    /// yaw after a round that had to turn it, seed 14 cell 181 through images
    /// labelled no sighting at any of its 8 poses and grasped 8.8 mm off on
    /// the search's 13 sightings).
    pub(super) fn wrist_as_seen(&self) -> ArcPoint<f32> {
        ArcPoint {
            yaw_rad: self.start_pose.yaw_rad + self.search_wrist_turn(),
            ..self.start_pose
        }
    }

    /// The wrist's turn from its start's yaw in the search's present round, rad.
    pub(super) fn search_wrist_turn(&self) -> f32 {
        self.search_turn_sign
            * SEARCH_WRIST_TURNS_RAD
                .get(usize::from(self.search_round))
                .copied()
                .unwrap_or(0.0)
    }

    /// Starts the search's next round (its sweeps again from the first, the
    /// wrist turned further), or false when the last has run.
    pub(super) fn next_search_round(&mut self) -> bool {
        let next = self.search_round.saturating_add(1);
        if usize::from(next) >= SEARCH_WRIST_TURNS_RAD.len() {
            return false;
        }
        self.search_round = next;
        self.sweep = 0;
        self.seen_per_sweep = [0; MAX_SEARCH_LEGS];
        self.seen_direction_per_sweep = [[0.0; 2]; MAX_SEARCH_LEGS];
        true
    }

    /// The search is in sweep `leg`.
    pub(super) fn sweeping(&mut self, leg: u8) {
        self.sweep = leg;
    }

    /// The sweep the search is in, or ended with.
    pub(super) fn sweep(&self) -> u8 {
        self.sweep
    }

    /// The camera saw the marks during sweep `leg` (or the step out to it),
    /// the flange towards `direction_xy` (a unit vector) from the base axis.
    pub(super) fn seen_in(&mut self, leg: u8, direction_xy: [f32; 2]) {
        if let Some(count) = self.seen_per_sweep.get_mut(usize::from(leg)) {
            *count = count.saturating_add(1);
        }
        if let Some(sum) = self.seen_direction_per_sweep.get_mut(usize::from(leg)) {
            let [x, y] = direction_xy;
            if x.is_finite() && y.is_finite() {
                *sum = [sum[0] + x, sum[1] + y];
            }
        }
    }

    /// The flange's mean azimuth at the sightings of sweep `leg`, if any: on
    /// that radius, where the camera sees the marks (the mean over every
    /// sweep mixes radii whose views lie at other azimuths).
    pub(super) fn seen_azimuth(&self, leg: u8) -> Option<f32> {
        let [x, y] = *self.seen_direction_per_sweep.get(usize::from(leg))?;
        (libm::hypotf(x, y) > 1e-3).then(|| libm::atan2f(y, x))
    }

    /// The sweep in which the camera saw the marks most often, if it saw them.
    pub(super) fn most_seen_sweep(&self) -> Option<u8> {
        let mut best: Option<(u8, u16)> = None;
        for (leg, &count) in (0u8..).zip(self.seen_per_sweep.iter()) {
            if count > 0 && best.is_none_or(|(_, most)| count > most) {
                best = Some((leg, count));
            }
        }
        best.map(|(leg, _)| leg)
    }

    /// The search goes back to sweep `leg`'s radius.
    pub(super) fn return_to(&mut self, leg: u8) {
        self.sweep = leg;
    }

    /// Where sweep `leg` starts, if the search has it.
    pub(super) fn sweep_start(&self, leg: u8) -> Option<ArcPoint<f32>> {
        let (radius, from, _) = self.search.ends(leg)?;
        Some(self.search_point(radius, from))
    }

    /// Where sweep `leg` ends, if the search has it.
    pub(super) fn sweep_end(&self, leg: u8) -> Option<ArcPoint<f32>> {
        let (radius, _, to) = self.search.ends(leg)?;
        Some(self.search_point(radius, to))
    }

    /// Back over `azimuth` (where the marks were seen) on sweep `leg`'s
    /// radius, within its joint-1 range.
    pub(super) fn search_return(&self, leg: u8, azimuth: f32) -> Option<ArcPoint<f32>> {
        let sweep = self.search.leg(leg)?;
        Some(self.search_point(sweep.radius_m, sweep.within(azimuth)))
    }

    /// Where look pass `pass` over `azimuth` (where the marks were seen), on
    /// sweep `leg`'s radius, ends: `half_width_m` of arc past it, one way on
    /// even passes and the other on odd ones, within the sweep's joint-1 range.
    pub(super) fn search_look(
        &self,
        leg: u8,
        azimuth: f32,
        pass: u8,
        half_width_m: f32,
    ) -> Option<ArcPoint<f32>> {
        let sweep = self.search.leg(leg)?;
        let half_rad = half_width_m / sweep.radius_m.max(LOOK_MIN_RADIUS_M);
        let side = if pass.is_multiple_of(2) { 1.0 } else { -1.0 };
        let end = sweep.within(azimuth) + side * half_rad;
        let end = end.clamp(sweep.low_azimuth_rad, sweep.high_azimuth_rad);
        Some(self.search_point(sweep.radius_m, end))
    }

    /// The flange arc point over `tool` (a grasp-point position), wrist as at the start.
    pub(super) fn over(&self, tool: &Vector3<f32>, z_flange: f32) -> ArcPoint<f32> {
        let mut point = ArcPoint::from_position(tool, 0.0);
        point.azimuth_rad = self.azimuth_near_start(point.azimuth_rad);
        point.yaw_rad = yaw_at_azimuth(&self.start_pose, point.azimuth_rad);
        point.z_m = z_flange;
        point
    }

    /// The arm first locates the part from `reference`, unless it already has.
    pub(super) fn locating_from(&mut self, reference: &TaskState<f32>) {
        if self.locate_pose.is_none() {
            self.locate_pose = Some(ArcPoint::from_position(&reference.position, reference.yaw));
        }
    }

    /// Where the part was first located from, on the start's side.
    pub(super) fn locate_pose(&self) -> Option<ArcPoint<f32>> {
        self.locate_pose.map(|target| self.near_start(target))
    }

    /// Over the drop-off at the carry height: the flange's height now
    /// (`flange_z`) or the drop-off's hover height, whichever is higher.
    pub(super) fn carry_to(
        &mut self,
        drop_off: &Vector3<f32>,
        flange_z: f32,
        settings: &PickSettings,
    ) -> ArcPoint<f32> {
        let drop_hover_z = drop_off.z + TOOL_LENGTH_M as f32 + settings.drop_hover_m;
        self.transfer_z = flange_z.max(drop_hover_z);
        self.over(drop_off, self.transfer_z)
    }

    /// Down onto the drop-off, the part's grasp point on it.
    pub(super) fn lower_onto(&self, drop_off: &Vector3<f32>) -> ArcPoint<f32> {
        self.over(drop_off, drop_off.z + TOOL_LENGTH_M as f32)
    }

    /// Back up over the drop-off to the carry height.
    pub(super) fn raise_from(&self, drop_off: &Vector3<f32>) -> ArcPoint<f32> {
        self.over(drop_off, self.transfer_z)
    }

    /// Home: the start pose.
    pub(super) fn home(&self) -> ArcPoint<f32> {
        self.near_start(self.start_pose)
    }
}

/// Riding with the part for `step` (track at hover height, descend to the
/// grasp point, settle there), from `now_s`.
pub(super) fn follow(step: Step, settings: &PickSettings, now_s: f32) -> Result<Motion, PlanError> {
    let (from, to, duration) = match step {
        Step::Descend => (settings.hover_height_m, 0.0, settings.descend_s),
        Step::Track => (settings.hover_height_m, settings.hover_height_m, 1.0),
        _ => (0.0, 0.0, 1.0),
    };
    match height_profile(from, to, duration) {
        Some(offset) => Ok(Motion::Follow {
            offset,
            start_s: now_s,
        }),
        None => Err(PlanError::InvalidDuration),
    }
}

/// Lifting the part off the disc from `start`: up by `lift_height_m` over
/// `lift_s`, carried on round the base axis by half the lift at the speed it
/// had, to rest. Round the axis, at the grasp's distance from it, rather than
/// straight on along the part's velocity: on a fast disc (1 rad/s) straight
/// on is 20 cm or more, out of the arm's reach where the part's circle
/// passes near the edge of it.
pub(super) fn lift(
    start: &TaskState<f32>,
    settings: &PickSettings,
    now_s: f32,
) -> Result<Motion, PlanError> {
    let carry_s = 0.5 * settings.lift_s;
    let radius = start.position.xy().norm();
    let carried = if radius > MIN_CARRY_RADIUS_M {
        // The azimuthal part of the speed, as a turn about the base axis.
        let azimuth = Vector3::new(-start.position.y, start.position.x, 0.0) / radius;
        let turn = start.velocity.dot(&azimuth) * carry_s / radius;
        let (s, c) = libm::sincosf(turn);
        let (x, y) = (start.position.x, start.position.y);
        Vector3::new(c * x - s * y, s * x + c * y, start.position.z)
    } else {
        start.position
    };
    let mut end = TaskState::at_rest(
        carried + Vector3::new(0.0, 0.0, settings.lift_height_m),
        start.yaw,
    );
    end.yaw = start.yaw + start.yaw_rate * carry_s;
    InterceptPlan::between(start, &end, settings.lift_s, core::f32::consts::PI).map(|path| {
        Motion::Quintic {
            path,
            start_s: now_s,
        }
    })
}

/// Closer to the base axis than this a lift is not carried round it.
const MIN_CARRY_RADIUS_M: f32 = 0.01;

/// A look's half width turns to an angle at no less than this radius, m
/// (the sweeps lie farther out: the shoulder's singularity).
const LOOK_MIN_RADIUS_M: f32 = 0.1;

/// The azimuth equivalent to `azimuth` within half a turn of `centre`.
pub(super) fn azimuth_within_half_a_turn(centre: f32, azimuth: f32) -> f32 {
    centre + wrap_pi(azimuth - centre)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planning::ready_posture;

    fn started_with_joint_6(q6: f32) -> (Route, Puma560<f32>) {
        let robot = Puma560::<f64>::new().cast::<f32>();
        let mut q = ready_posture::<f32>();
        q[5] = q6;
        let flange = robot.forward_kinematics(&q).translation.vector;
        let mut route = Route::new();
        route
            .start_from(
                ArcPoint::from_position(&flange, 0.3),
                &robot,
                &q,
                &flange,
                &PickSettings::default(),
            )
            .unwrap();
        (route, robot)
    }

    #[test]
    fn each_round_of_the_search_turns_the_wrist_and_the_last_ends_it() {
        // Joint 6 anywhere in its range, near either stop or between.
        for q6 in [-4.5_f32, -1.0, 0.0, 1.0, 4.5] {
            let (mut route, robot) = started_with_joint_6(q6);
            let limits = robot.joint_limits();
            let first = route.sweep_start(0).unwrap();
            assert_eq!(route.search_wrist_turn(), 0.0);
            route.seen_in(2, [1.0, 0.0]);
            let mut rounds = 1;
            while route.next_search_round() {
                rounds += 1;
                // From the first sweep again, nothing seen yet in this round.
                assert_eq!(route.sweep(), 0);
                assert_eq!(route.most_seen_sweep(), None);
                let turn = route.search_wrist_turn();
                assert_eq!(turn.abs(), SEARCH_WRIST_TURNS_RAD[rounds - 1], "q6 {q6}");
                let start = route.sweep_start(0).unwrap();
                assert_eq!(start.azimuth_rad, first.azimuth_rad);
                assert!((start.yaw_rad - first.yaw_rad - turn).abs() < 1e-6);
                // The yaw turns against joint 6 (gripper down): it stays
                // 80 degrees inside its stops.
                let q6_turned = q6 - turn;
                let spare = 80f32.to_radians();
                assert!(
                    q6_turned - spare > limits.position_min[5]
                        && q6_turned + spare < limits.position_max[5],
                    "q6 {q6}, turn {turn}"
                );
            }
            assert_eq!(rounds, SEARCH_WRIST_TURNS_RAD.len());
            // After the last round no other starts, and the wrist stays turned.
            assert!(!route.next_search_round());
            assert_eq!(
                route.search_wrist_turn().abs(),
                SEARCH_WRIST_TURNS_RAD[rounds - 1]
            );
        }
    }
}
