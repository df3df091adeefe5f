//! How slowly each calibration move must go for its joints to keep within
//! their speed limits.
//!
//! A calibration move is an arc at the arcs' default task-space limits. Near
//! the base axis, or from where the search's look ended, such an arc can ask
//! a joint for nearly its whole speed limit (images seed 11, cell 701: joint
//! 2 at 0.95 from the look's end at the inner radius), and the supervisor
//! stops the pick at 0.9. The control period cannot afford the inverse
//! kinematics that proves a path, so the worker, which plans the poses,
//! proves each move and lengthens those that need it.

use heapless::Vec;

use super::jobs::MAX_CALIBRATION_POSES;
use super::route::azimuth_within_half_a_turn;
use crate::planning::{peak_speed_share, ArcLimits, ArcMove, ArcPoint, PlanError, TaskPath};
use crate::robot::{JointVector, Puma560};

/// A pose to show the marks at and the shortest duration of the move into
/// it (and, the calibration's second round visiting the poses in reverse,
/// of the same move back).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrationPose {
    /// Where the flange goes.
    pub point: ArcPoint<f32>,
    /// The move into it lasts at least this long, s (0: the arcs' default).
    pub min_duration_s: f32,
}

/// The share of a joint's speed limit a calibration move may ask for: the
/// plans' share (the supervisor stops the pick at 0.9).
const PACE_SHARE: f32 = 0.7;
/// Samples along a move (the quintic's peak lies mid-way; a dozen find it
/// within a few per cent).
const PACE_SAMPLES: usize = 12;
/// A slowed move is lengthened this much beyond the share's own ratio (the
/// samples may miss the peak by a little).
const PACE_MARGIN: f32 = 1.05;

/// The arc the pick flies from `from` to `target`, at least
/// `min_duration_s` long: azimuths within half a turn of
/// `waist_centre_azimuth`, as the route takes them, and the target's wrist
/// yaw (set from its azimuth in `(-pi, pi]`) turned by the same whole turns,
/// or a pose behind the robot asks joint 6 for a whole turn it does not
/// have. The worker proves the same arc the control period flies.
pub fn calibration_arc(
    from: &ArcPoint<f32>,
    target: &ArcPoint<f32>,
    waist_centre_azimuth: f32,
    min_duration_s: f32,
) -> Result<ArcMove<f32>, PlanError> {
    let near = |azimuth: f32| azimuth_within_half_a_turn(waist_centre_azimuth, azimuth);
    let mut start = *from;
    start.azimuth_rad = near(start.azimuth_rad);
    let mut end = *target;
    let azimuth = near(end.azimuth_rad);
    end.yaw_rad += azimuth - end.azimuth_rad;
    end.azimuth_rad = azimuth;
    let defaults = ArcLimits::<f32>::default();
    let limits = ArcLimits {
        min_duration_s: defaults.min_duration_s.max(min_duration_s),
        ..defaults
    };
    ArcMove::new(&start, &end, &limits)
}

/// `poses` in visiting order from `from` (the flange at rest, joints
/// `q_now`), each with the duration its move needs for every joint to keep
/// within [`PACE_SHARE`] of its speed limit. A move whose inverse kinematics
/// fails is left at the default (the pick checks its reach when it flies it).
pub fn paced(
    poses: &[ArcPoint<f32>],
    from: &ArcPoint<f32>,
    waist_centre_azimuth: f32,
    q_now: &JointVector<f32>,
    robot: &Puma560<f32>,
) -> Vec<CalibrationPose, MAX_CALIBRATION_POSES> {
    let mut paced = Vec::new();
    let mut at = *from;
    let mut q = *q_now;
    for target in poses {
        let mut min_duration_s = 0.0;
        // Measured once at the default pace; a move too fast is lengthened
        // in proportion (a time-scaled path's joint speeds scale with its
        // rate) and measured again, to be sure.
        for _ in 0..2 {
            let Ok(arc) = calibration_arc(&at, target, waist_centre_azimuth, min_duration_s) else {
                break;
            };
            let Ok((share, q_end)) = peak_speed_share(&arc, robot, &q, PACE_SAMPLES) else {
                break;
            };
            q = q_end;
            if share <= PACE_SHARE {
                break;
            }
            min_duration_s = arc.duration() * share / PACE_SHARE * PACE_MARGIN;
        }
        let _ = paced.push(CalibrationPose {
            point: *target,
            min_duration_s,
        });
        at = *target;
    }
    paced
}

/// `poses` for the second round, visited in reverse: each move is the first
/// round's move between the same two poses, flown back, and keeps its
/// duration; the first (to where the arm already is) needs none.
pub fn reversed(poses: &mut [CalibrationPose]) {
    poses.reverse();
    let mut carried = 0.0;
    for pose in poses.iter_mut() {
        core::mem::swap(&mut pose.min_duration_s, &mut carried);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(radius_m: f32, azimuth_rad: f32, z_m: f32) -> ArcPoint<f32> {
        ArcPoint {
            radius_m,
            azimuth_rad,
            z_m,
            yaw_rad: azimuth_rad,
        }
    }

    fn robot() -> Puma560<f32> {
        Puma560::<f64>::new().cast::<f32>()
    }

    /// A gripper-down flange half a metre out and up, and its joints.
    fn at_rest(robot: &Puma560<f32>) -> (ArcPoint<f32>, JointVector<f32>) {
        let position = nalgebra::Vector3::new(0.5, 0.0, 0.5);
        let pose = crate::planning::TaskState::at_rest(position, 0.0).pose();
        let seed = crate::planning::ready_posture::<f32>();
        let q =
            crate::planning::solve_ik(robot, &pose, &seed, &crate::planning::IkConfig::default())
                .unwrap();
        (ArcPoint::from_position(&position, 0.0), q)
    }

    fn share(arc: &ArcMove<f32>, robot: &Puma560<f32>, q: &JointVector<f32>) -> f32 {
        match peak_speed_share(arc, robot, q, 48) {
            Ok((s, _)) => s,
            Err(e) => panic!("{e:?} from {:?}", robot.forward_kinematics(q)),
        }
    }

    #[test]
    fn a_move_too_fast_for_a_joint_is_slowed_to_the_plans_share() {
        let robot = robot();
        let (from, q) = at_rest(&robot);
        // Out from the base axis and down at the arcs' default 0.5 m/s: the
        // shoulder (joint 2) turns fast.
        let mut near = from;
        near.radius_m = 0.31;
        let mut far = near;
        far.radius_m = 0.75;
        far.z_m -= 0.2;
        let moves = paced(&[near, far], &from, 0.0, &q, &robot);
        let [first, second] = moves.as_slice() else {
            panic!("two poses: {moves:?}");
        };
        let fast = calibration_arc(&near, &far, 0.0, 0.0).unwrap();
        let q_near = peak_speed_share(
            &calibration_arc(&from, &near, 0.0, 0.0).unwrap(),
            &robot,
            &q,
            12,
        )
        .unwrap()
        .1;
        let fast_share = share(&fast, &robot, &q_near);
        assert!(
            fast_share > PACE_SHARE,
            "the case needs pacing: {fast_share}"
        );
        assert!(second.min_duration_s > fast.duration());
        let slowed = calibration_arc(&near, &far, 0.0, second.min_duration_s).unwrap();
        let slowed_share = share(&slowed, &robot, &q_near);
        assert!(slowed_share <= PACE_SHARE, "{slowed_share}");
        assert!(
            slowed_share > 0.8 * PACE_SHARE,
            "no slower than it must: {slowed_share}"
        );
        // A short radial step needs no pacing.
        assert_eq!(first.min_duration_s, 0.0, "{first:?}");
    }

    #[test]
    fn the_second_round_flies_each_move_back_at_its_first_pace() {
        let mut poses = [1.0, 2.0, 3.0].map(|d| CalibrationPose {
            point: point(0.5, d, 0.5),
            min_duration_s: d,
        });
        reversed(&mut poses);
        let order = poses.map(|p| (p.point.azimuth_rad, p.min_duration_s));
        // Into 3.0: already there. 3.0 -> 2.0 is the move into 3.0 (3 s),
        // 2.0 -> 1.0 the move into 2.0 (2 s).
        assert_eq!(order, [(3.0, 0.0), (2.0, 3.0), (1.0, 2.0)]);
    }
}
