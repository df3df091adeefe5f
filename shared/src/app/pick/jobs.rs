//! The pick's slow computations, run outside the control loop: where to show the
//! marks for the robot-to-disc calibration, and the intercept of the moving part.
//!
//! The control loop requests them and applies their results after a fixed delay
//! (see `PickSettings::estimate_budget_s`), holding its reference meanwhile.

use core::cell::Cell;

use heapless::Vec;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use super::estimate::CellEstimate;
use super::motion::{flange_over, Prediction};
use super::settings::PickSettings;
use super::window::{
    grasp_window_holds, inside_with_margin, yaw_offset_from, WINDOW_JOINT_MARGIN_RAD,
};
use crate::angle::wrap_pi;
use crate::app::tool::{effector_marks_base, TOOL_LENGTH_M};
use crate::observation::CameraIntrinsics;
use crate::planning::{
    gripper_down_rotation, gripper_yaw, plan_intercept_where, solve_ik, well_conditioned,
    within_reach, ArcPoint, IkConfig, InterceptLimits, InterceptPlan, PlanError, TaskState,
};
use crate::robot::{JointVector, Puma560};

/// Most poses shown for the robot-to-disc calibration, out of at most
/// `MAX_CANDIDATES` (3 heights, 2 radial and 5 lateral positions).
pub const MAX_CALIBRATION_POSES: usize = 8;
const MAX_CANDIDATES: usize = 30;

/// The candidates' lateral spacing over the disc, m (5 positions: 0.8 m
/// across, the disc's 0.9 m less the marks' margin).
const LATERAL_STEP_M: f32 = 0.2;

/// Closest a gripper-down grasp point may come to the base axis (the shoulder
/// singularity, and the robot's own column).
pub const MIN_RADIUS_FROM_BASE_AXIS_M: f32 = 0.30;

/// Pixels the marks keep from the image border at a calibration pose.
const VIEW_MARGIN_PX: f64 = 8.0;

/// The flange pose, gripper down, that puts the grasp point at `tool`.
fn flange_pose(tool: &Vector3<f32>, yaw: f32) -> Isometry3<f32> {
    Isometry3::from_parts(
        Translation3::from(tool + Vector3::new(0.0, 0.0, TOOL_LENGTH_M as f32)),
        UnitQuaternion::from_rotation_matrix(&gripper_down_rotation(yaw)),
    )
}

/// The wrist keeps its start configuration relative to the waist: the gripper's
/// yaw turns with the azimuth.
pub fn yaw_at_azimuth(start: &ArcPoint<f32>, azimuth: f32) -> f32 {
    start.yaw_rad + (azimuth - start.azimuth_rad)
}

/// Poses above the disc (grasp point `calibration_heights_m` above the part's
/// top, over the disc's near half and across its width) that the arm can
/// reach gripper-down and the camera sees both marks from: the widest spread
/// of them, on one side of the waist's stop, in visiting order
/// ([`in_visiting_order`]). `start` is the arm's start pose (for the wrist's
/// yaw), `q_seed` its joints where the calibration starts.
/// Out of line, so that its temporaries (inverse kinematics) are not in the
/// estimate job's frame, which lies under the bundle adjustment.
#[inline(never)]
pub fn calibration_poses(
    estimate: &CellEstimate,
    camera: &CameraIntrinsics,
    start: &ArcPoint<f32>,
    q_seed: &JointVector<f32>,
    settings: &PickSettings,
    robot: &Puma560<f32>,
) -> Vec<ArcPoint<f32>, MAX_CALIBRATION_POSES> {
    let centre = estimate.disc_centre();
    let distance = centre.xy().norm();
    let radial = if distance > 1e-3 {
        Vector3::new(centre.x / distance, centre.y / distance, 0.0)
    } else {
        Vector3::x()
    };
    let lateral = Vector3::new(-radial.y, radial.x, 0.0);
    let part_top = estimate.disc_height() + estimate.part_rotating.z;
    // Each candidate with its waist angle.
    let mut candidates: Vec<(ArcPoint<f32>, f32), MAX_CANDIDATES> = Vec::new();
    let mut q = *q_seed;
    let ik = IkConfig::default();
    for (row, height) in settings.calibration_heights_m.iter().enumerate() {
        for radial_offset in [-0.25_f32, -0.05] {
            for step in 0..5 {
                // Serpentine: alternate the lateral direction row by row.
                let k = if row % 2 == 0 { step } else { 4 - step };
                let side = (k as f32 - 2.0) * LATERAL_STEP_M;
                let tool = centre
                    + radial * radial_offset
                    + lateral * side
                    + Vector3::new(0.0, 0.0, part_top - centre.z + height);
                let point = ArcPoint::from_position(&tool, 0.0);
                if point.radius_m < MIN_RADIUS_FROM_BASE_AXIS_M {
                    continue;
                }
                let yaw = yaw_at_azimuth(start, point.azimuth_rad);
                let pose = flange_pose(&tool, yaw);
                let in_view = effector_marks_base(&pose).iter().all(|mark| {
                    estimate.project(camera, mark).is_some_and(|[u, v]| {
                        u >= VIEW_MARGIN_PX
                            && v >= VIEW_MARGIN_PX
                            && u <= f64::from(camera.width) - VIEW_MARGIN_PX
                            && v <= f64::from(camera.height) - VIEW_MARGIN_PX
                    })
                });
                if !in_view || !within_reach(robot, &pose.translation.vector) {
                    continue;
                }
                let seed = wrist_turned_to(
                    robot,
                    &waist_turned_towards(robot, &q, point.azimuth_rad),
                    yaw,
                );
                let Ok(solution) = solve_ik(robot, &pose, &seed, &ik) else {
                    continue;
                };
                // On a joint's stop the arcs between the poses would drive it
                // past: keep the window's margin.
                if !well_conditioned(robot, &solution) || !inside_with_margin(robot, &solution) {
                    continue;
                }
                q = solution;
                let mut arc = ArcPoint::from_position(&pose.translation.vector, yaw);
                arc.yaw_rad = yaw;
                let _ = candidates.push((arc, solution.x));
            }
        }
    }
    one_side_of_the_waist_stop(&mut candidates, q_seed.x);
    let mut poses = widest_spread(&candidates);
    let flange = robot.forward_kinematics(q_seed).translation.vector;
    in_visiting_order(&mut poses, flange);
    poses
}

/// Keeps the candidates on one side of the waist's stop: over a disc behind
/// the robot, poses on both sides of it lie a whole turn of the waist apart
/// (the moves between them swing the arm round the long way, and the last
/// one may leave it where the part's path can only be reached that way too:
/// `PartOutOfReach`). The side with more candidates stays, on a tie the
/// side the waist is on (`waist`).
fn one_side_of_the_waist_stop(
    candidates: &mut Vec<(ArcPoint<f32>, f32), MAX_CANDIDATES>,
    waist: f32,
) {
    let (low, high) = candidates.iter().fold(
        (f32::INFINITY, f32::NEG_INFINITY),
        |(low, high), (_, q1)| (low.min(*q1), high.max(*q1)),
    );
    if high - low <= core::f32::consts::PI {
        return;
    }
    let positive = candidates.iter().filter(|(_, q1)| *q1 >= 0.0).count();
    let negative = candidates.len() - positive;
    let keep_positive = positive > negative || (positive == negative && waist >= 0.0);
    candidates.retain(|(_, q1)| (*q1 >= 0.0) == keep_positive);
}

/// The candidates spread widest, by farthest-point selection: the first
/// the farthest from their mean, each next the farthest from those taken.
/// The marks' spread across the image is what measures their depth, and so
/// the base's height (a scale the disc's reference circle sets only through
/// its own 40 pixels): the widest 8 of 30 candidates took the part at the
/// grasp from 4.84 to 4.68 mm at the 95th percentile (1,000 cells at 5 Hz,
/// through points). The nearer radius stays 0.25 m inside the disc's
/// centre: 0.3 m gave 4.40 mm, but with it (and the arm then brought to
/// rest between poses when an early estimate met its target) 5 cells of
/// 1,000 through images stopped where the wrist was near its singularity
/// and found no intercept (`PartUnreachable`); 0.25 m alone cleared them.
fn widest_spread(candidates: &[(ArcPoint<f32>, f32)]) -> Vec<ArcPoint<f32>, MAX_CALIBRATION_POSES> {
    let mut poses: Vec<ArcPoint<f32>, MAX_CALIBRATION_POSES> = Vec::new();
    let Some(count) = core::num::NonZeroUsize::new(candidates.len()) else {
        return poses;
    };
    let mean = candidates
        .iter()
        .map(|(pose, _)| position(pose))
        .sum::<Vector3<f32>>()
        / count.get() as f32;
    let mut taken = [false; MAX_CANDIDATES];
    while !poses.is_full() {
        let farthest = candidates
            .iter()
            .zip(taken.iter())
            .enumerate()
            .filter(|(_, (_, taken))| !**taken)
            .map(|(k, ((pose, _), _))| {
                let from_taken = poses
                    .iter()
                    .map(|taken| (position(taken) - position(pose)).norm())
                    .fold(f32::INFINITY, f32::min);
                let from_mean = (position(pose) - mean).norm();
                (
                    k,
                    if poses.is_empty() {
                        from_mean
                    } else {
                        from_taken
                    },
                )
            })
            .fold(None, |best: Option<(usize, f32)>, (k, d)| match best {
                Some((_, most)) if d <= most + TIE_M => best,
                _ => Some((k, d)),
            });
        let Some((k, _)) = farthest else {
            break;
        };
        if let (Some(flag), Some((pose, _))) = (taken.get_mut(k), candidates.get(k)) {
            *flag = true;
            let _ = poses.push(*pose);
        }
    }
    poses
}

/// Where `pose` puts the flange, base frame.
fn position(pose: &ArcPoint<f32>) -> Vector3<f32> {
    let (s, c) = crate::control::trig::sin_cos(pose.azimuth_rad);
    Vector3::new(pose.radius_m * c, pose.radius_m * s, pose.z_m)
}

/// Distances within this of each other are a tie, m, which the candidates'
/// order breaks: the candidates lie on a symmetric grid, where the last bit
/// of a distance (the M4F's and the host's differ there) would otherwise
/// choose, and the emulated board's pick part from the host's.
const TIE_M: f32 = 1e-3;

/// Poses at one height within this of each other, m.
pub const SAME_HEIGHT_M: f32 = 0.01;

/// Orders `poses` for the arm at `flange`: first down a staircase, one pose
/// per height, highest first and each the nearest to the one before (the
/// camera confirms each step down from the height above it:
/// `max_descent_step_m`), so that after as many poses as there are heights
/// the marks have been shown at every one of them and an early estimate may
/// end the calibration (see `early`); then the rest, each the nearest to the
/// one before. The moves, not the dwells, are most of the calibration's
/// time: an even spread taken in the candidates' order crossed the disc
/// back and forth (17.5 s for 8 poses on the default cell, 13 s nearest
/// next).
fn in_visiting_order(poses: &mut [ArcPoint<f32>], flange: Vector3<f32>) {
    let mut at = flange;
    // Poses below this are the staircase's next steps.
    let mut step_below = f32::INFINITY;
    for next in 0..poses.len() {
        let Some(rest) = poses.get(next..) else {
            return;
        };
        let level = rest
            .iter()
            .map(|pose| pose.z_m)
            .filter(|&z| z < step_below)
            .fold(f32::NEG_INFINITY, f32::max);
        let on_stairs = level > f32::NEG_INFINITY;
        let nearest = rest
            .iter()
            .enumerate()
            .filter(|(_, pose)| {
                !on_stairs || (pose.z_m >= level - SAME_HEIGHT_M && pose.z_m < step_below)
            })
            .map(|(k, pose)| (k, (position(pose) - at).norm()))
            .fold(None, |best: Option<(usize, f32)>, (k, d)| match best {
                Some((_, least)) if d >= least - TIE_M => best,
                _ => Some((k, d)),
            });
        if let Some((k, _)) = nearest {
            poses.swap(next, next + k);
        }
        if let Some(pose) = poses.get(next) {
            at = position(pose);
            if on_stairs {
                step_below = pose.z_m - SAME_HEIGHT_M;
            }
        }
    }
}

/// `q` with joint 6 turned so that the gripper's yaw becomes `yaw` (pointing
/// down, the yaw turns against joint 6), to the angle of the three a turn
/// apart that lies nearest the middle of its range: the inverse kinematics
/// only follows its seed, and from a search that ended with the wrist turned
/// half a turn (`SEARCH_WRIST_TURNS_RAD`) it found no pose at all, joint 6
/// seeded half a turn from every candidate's (images, seed 11, cell 264:
/// `DiscOutOfReach`), or past its stop when turned back the wrong way.
fn wrist_turned_to(robot: &Puma560<f32>, q: &JointVector<f32>, yaw: f32) -> JointVector<f32> {
    let present = gripper_yaw(&robot.forward_kinematics(q).rotation);
    let limits = robot.joint_limits();
    let middle = 0.5 * (limits.position_min.b + limits.position_max.b);
    let turned = q.b - wrap_pi(yaw - present);
    let mut seed = *q;
    seed.b = middle + wrap_pi(turned - middle);
    seed
}

/// `q` with the waist turned so that the flange's azimuth becomes `azimuth`,
/// whichever way round keeps joint 1 inside its limits: the inverse
/// kinematics only follows its seed, and from an arm that ended its search on
/// the far side of the waist's range (at +154 degrees, say) the short way to a
/// disc behind the robot (at -166 degrees) runs past the waist's stop, while
/// the route reaches it the long way round.
fn waist_turned_towards(
    robot: &Puma560<f32>,
    q: &JointVector<f32>,
    azimuth: f32,
) -> JointVector<f32> {
    let flange = robot.forward_kinematics(q).translation.vector;
    let limits = robot.joint_limits();
    let mut waist = q.x + wrap_pi(azimuth - libm::atan2f(flange.y, flange.x));
    if waist > limits.position_max.x {
        waist -= core::f32::consts::TAU;
    } else if waist < limits.position_min.x {
        waist += core::f32::consts::TAU;
    }
    let mut seed = *q;
    seed.x = waist;
    seed
}

/// The joints with the flange at rest at `point`, solved from `q_seed`
/// with the waist turned towards it (`q_seed` itself if they cannot be):
/// the preliminary estimate is asked for while the arm is still on its way
/// back over the marks, and plans the calibration poses from where it will be.
pub fn joints_at(
    robot: &Puma560<f32>,
    point: &ArcPoint<f32>,
    q_seed: &JointVector<f32>,
) -> JointVector<f32> {
    let seed = waist_turned_towards(robot, q_seed, point.azimuth_rad);
    let pose = TaskState::at_rest(position(point), point.yaw_rad).pose();
    solve_ik(robot, &pose, &seed, &IkConfig::default()).unwrap_or(*q_seed)
}

/// The conveyor as the plan saw it: angle, speed, and the delay before the plan starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConveyorSnapshot {
    /// The conveyor angle, rad.
    pub theta: f32,
    /// The conveyor speed, rad/s.
    pub omega: f32,
    /// The delay before the plan starts, s.
    pub lead_s: f32,
}

/// Whether the grasp pose over the part is reachable at conveyor angle
/// `theta`, the inverse kinematics seeded with `q_seed` (already turned
/// towards the part: [`turned_towards`]).
fn reachable_at(
    estimate: &CellEstimate,
    theta: f32,
    q_seed: &JointVector<f32>,
    robot: &Puma560<f32>,
) -> bool {
    let grasp = estimate.grasp_point(theta, 0.0, 0.0);
    if grasp.position.xy().norm() < MIN_RADIUS_FROM_BASE_AXIS_M {
        return false;
    }
    let yaw = grasp.yaw + yaw_offset_from(q_seed, grasp.yaw, robot);
    let pose = flange_pose(&grasp.position, yaw);
    within_reach(robot, &pose.translation.vector)
        && solve_ik(robot, &pose, q_seed, &IkConfig::default())
            .is_ok_and(|q| well_conditioned(robot, &q))
}

/// `q_seed`, whose flange stands at azimuth `flange_azimuth`, with joint 1
/// turned by the azimuth from there to `target` (base frame): the inverse
/// kinematics then need not swing the waist round from afar, from where
/// they may not converge. On a fast disc the grasp's window spans a wide
/// arc (at 1 rad/s, 109 degrees in 1.9 s): seeded with the arm's start
/// alone, the far end of that arc failed to converge and no window was
/// ever admitted.
fn turned_towards(
    q_seed: &JointVector<f32>,
    flange_azimuth: f32,
    target: &Vector3<f32>,
) -> JointVector<f32> {
    let mut seed = *q_seed;
    seed.x += crate::angle::wrap_pi(libm::atan2f(target.y, target.x) - flange_azimuth);
    seed
}

/// The azimuth of the flange at joint angles `q`, rad.
fn flange_azimuth(q: &JointVector<f32>, robot: &Puma560<f32>) -> f32 {
    let flange = robot.forward_kinematics(q).translation.vector;
    libm::atan2f(flange.y, flange.x)
}

/// Conveyor angles at which [`part_path_enters_reach`] tries the part: every 10 degrees.
const PART_PATH_SAMPLES: u16 = 36;

/// Whether the part's circle (its grasp point as the disc turns, Eq 1)
/// enters the arm's workspace anywhere: a gripper-down grasp within reach and
/// joint ranges, well conditioned, clear of the base axis, at one of
/// [`PART_PATH_SAMPLES`] conveyor angles. When it never does, no intercept
/// can ever be planned, whatever the conveyor does: the layout cannot be
/// served (`FaultCause::PartOutOfReach`).
pub fn part_path_enters_reach(
    estimate: &CellEstimate,
    q_seed: &JointVector<f32>,
    robot: &Puma560<f32>,
) -> bool {
    // Each try starts from `q_seed` turned towards the part (`turned_towards`).
    let from_azimuth = flange_azimuth(q_seed, robot);
    (0..PART_PATH_SAMPLES).any(|k| {
        let theta = f32::from(k) * core::f32::consts::TAU / f32::from(PART_PATH_SAMPLES);
        let grasp = estimate.grasp_point(theta, 0.0, 0.0).position;
        let seed = turned_towards(q_seed, from_azimuth, &grasp);
        reachable_at(estimate, theta, &seed, robot)
    })
}

/// The earliest intercept of the part's hover point from `start` (at rest, joint
/// angles `q_start`), among those whose grasp window holds: riding with the
/// part, descending, grasping and lifting it keep every joint inside its
/// range with margin and within its speed limits, the part moving with the
/// disc all the while ([`grasp_window_holds`]). The part's future comes from
/// Eq 1 at constant conveyor speed. Where no window holds within the scan,
/// no intercept is planned (the pick waits and plans again, or stops with
/// `PartUnreachable`): never one whose grasp or lift drives a joint onto its
/// stop.
pub fn plan_part_intercept(
    start: &TaskState<f32>,
    q_start: &JointVector<f32>,
    estimate: &CellEstimate,
    conveyor: &ConveyorSnapshot,
    settings: &PickSettings,
    robot: &Puma560<f32>,
) -> Result<(InterceptPlan<f32>, Prediction), PlanError> {
    let mut prediction = Prediction {
        theta_at_start: conveyor.theta + conveyor.omega * conveyor.lead_s,
        omega: conveyor.omega,
        settle_max_s: settings.grasp_settle_s,
    };
    let theta_after = |d: f32| prediction.theta_at_start + prediction.omega * d;
    let target_after = |d: f32| {
        flange_over(
            &estimate.grasp_point(theta_after(d), prediction.omega, 0.0),
            settings.hover_height_m,
        )
    };
    // The window's inverse kinematics start from the arm's joints with
    // joint 1 turned by the azimuth from the flange to the part's hover
    // point, so they need not swing the waist round from afar.
    let from_azimuth = libm::atan2f(start.position.y, start.position.x);
    // Whether any duration of the scan was admissible (see below).
    let any_admissible = Cell::new(false);
    let admissible = |d: f32| {
        let seed = turned_towards(q_start, from_azimuth, &target_after(d).position);
        let ok = reachable_at(estimate, theta_after(d), &seed, robot)
            && grasp_window_holds(
                estimate,
                &prediction,
                d,
                &seed,
                (settings, settings.grasp_settle_s),
                robot,
            );
        if ok {
            any_admissible.set(true);
        }
        ok
    };
    let limits = InterceptLimits {
        max_duration_s: 14.0,
        duration_step_s: 0.2,
        joint_position_margin_rad: WINDOW_JOINT_MARGIN_RAD,
        ..InterceptLimits::default()
    };
    match plan_intercept_where(start, target_after, admissible, &limits, robot, q_start) {
        Ok(plan) => {
            // The window holds for the shortest settle; the close may wait
            // longer for a settled arm only where it holds for that too.
            let d = plan.duration();
            let seed = turned_towards(q_start, from_azimuth, &target_after(d).position);
            let longer = (settings, settings.grasp_settle_max_s);
            if grasp_window_holds(estimate, &prediction, d, &seed, longer, robot) {
                prediction.settle_max_s = settings.grasp_settle_max_s;
            }
            Ok((plan, prediction))
        }
        // The scan saw the part go round a whole turn and never found it
        // within reach for the grasp's window: the part's reachable arc is
        // shorter than the disc turns in that window (a fast disc, a far or
        // low part). Waiting for another turn cannot help: say so now.
        Err(PlanError::NoFeasibleIntercept)
            if !any_admissible.get()
                && libm::fabsf(prediction.omega)
                    * (limits.max_duration_s - limits.min_duration_s)
                    >= core::f32::consts::TAU =>
        {
            Err(PlanError::NoGraspWindow)
        }
        Err(e) => Err(e),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The arm as cell 10000084's search left it through images: the waist at
    /// +154 degrees, the disc behind the robot at -166 degrees.
    #[test]
    fn a_pose_behind_the_robot_is_found_from_the_far_side_of_the_waist() {
        let robot = Puma560::<f32>::new();
        let q_search_end = JointVector::from([2.693, 1.024, -3.084, 0.0, -0.78, 0.0]);
        let azimuth = (-166.0_f32).to_radians();
        let tool = Vector3::new(0.55 * azimuth.cos(), 0.55 * azimuth.sin(), 0.45);
        let pose = flange_pose(&tool, 0.0);
        let ik = IkConfig::default();
        let reached = |seed: &JointVector<f32>| {
            solve_ik(&robot, &pose, seed, &ik)
                .is_ok_and(|q| inside_with_margin(&robot, &q) && well_conditioned(&robot, &q))
        };
        // The short way round runs into the waist's stop.
        assert!(!reached(&q_search_end));
        let seed = waist_turned_towards(&robot, &q_search_end, azimuth);
        let limits = robot.joint_limits();
        assert!(seed.x >= limits.position_min.x && seed.x <= limits.position_max.x);
        assert!(reached(&seed), "seed {seed:?}");
    }

    /// The arm as cell 11000264's search left it through images, after its
    /// third round: the wrist turned half a turn (joint 6 at -172 degrees).
    #[test]
    fn a_pose_is_found_from_a_search_that_turned_the_wrist_half_a_turn() {
        let robot = Puma560::<f32>::new();
        let q_search_end = JointVector::from([1.096, 1.439, -3.667, 0.0, -0.913, -3.013]);
        let azimuth = 0.73_f32;
        let tool = Vector3::new(0.5 * azimuth.cos(), 0.5 * azimuth.sin(), 0.45);
        // The yaw every calibration pose is shown at: the start's, with the waist.
        let yaw = 4.11_f32;
        let pose = flange_pose(&tool, yaw);
        let ik = IkConfig::default();
        let reached = |seed: &JointVector<f32>| {
            solve_ik(&robot, &pose, seed, &ik)
                .is_ok_and(|q| inside_with_margin(&robot, &q) && well_conditioned(&robot, &q))
        };
        let waist_only = waist_turned_towards(&robot, &q_search_end, azimuth);
        assert!(!reached(&waist_only));
        let seed = wrist_turned_to(&robot, &waist_only, yaw);
        let limits = robot.joint_limits();
        assert!(seed[5] >= limits.position_min[5] && seed[5] <= limits.position_max[5]);
        assert!(reached(&seed), "seed {seed:?}");
        // The seed's yaw is the pose's.
        let seed_yaw = gripper_yaw(&robot.forward_kinematics(&seed).rotation);
        assert!(
            wrap_pi(seed_yaw - yaw).abs() < 0.05,
            "{seed_yaw} against {yaw}"
        );
    }

    #[test]
    fn the_poses_are_visited_down_a_staircase_then_nearest_next() {
        let at = |azimuth: f32, z_m: f32| ArcPoint {
            radius_m: 0.6,
            azimuth_rad: azimuth,
            z_m,
            yaw_rad: 0.0,
        };
        // An even spread taken in the candidates' order: across the disc
        // and back at each height.
        let mut poses = [
            at(-0.4, 0.6),
            at(0.4, 0.6),
            at(0.0, 0.6),
            at(0.4, 0.45),
            at(-0.4, 0.45),
            at(0.0, 0.3),
        ];
        // The arm halted at the disc's +0.4 side, high up.
        let flange = Vector3::new(0.6 * 0.5_f32.cos(), 0.6 * 0.5_f32.sin(), 0.7);
        in_visiting_order(&mut poses, flange);
        let order: [(f32, f32); 6] = poses.map(|p| (p.azimuth_rad, p.z_m));
        assert_eq!(
            order,
            [
                // One per height, highest first, each the nearest.
                (0.4, 0.6),
                (0.4, 0.45),
                (0.0, 0.3),
                // The rest, nearest next.
                (-0.4, 0.45),
                (-0.4, 0.6),
                (0.0, 0.6),
            ]
        );
    }
}
