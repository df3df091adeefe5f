//! Which layouts the arm can serve: the world keeps these (and, asked to,
//! only the others, to show how the controller stops on them).
//!
//! A layout can be served when all of these hold (the PUMA 560 gripper
//! down, the controller's reach margins, joint ranges from
//! `docs/reference/puma560-model.md`):
//! 1. the part's path: over at least [`required_arc_deg`] of one contiguous
//!    arc of the circle the part's grasp point runs round as the disc turns, the
//!    gripper reaches it at the grasp point and at the hover height above it:
//!    within 93 % of the arm's stretch (`shared::planning::MAX_STRETCH`), at
//!    least 0.30 m from the base axis, with joint angles 4 degrees inside
//!    every joint's range (inverse kinematics from the ready posture turned
//!    towards it; the controller's `WINDOW_JOINT_MARGIN_RAD`) and well
//!    conditioned. The arc is the disc's turn during the grasp's
//!    sequence ([`grasp_sequence_s`], 2.95 s) at its top speed (mean speed
//!    plus ripple), and never under [`SERVE_ARC_DEG`]: at the default
//!    0.5 rad/s (5 % ripple) that is 90 degrees (room to meet the part), at
//!    1 rad/s (10 % ripple) 186. Along a shorter arc no grasp and lift can be
//!    planned (the controller then stops with `PartOutOfReach`);
//! 2. the camera sees the gripper at the cell's travel height: somewhere over
//!    the disc the arm reaches at that height, both marks are in view (the
//!    search looks for them there, knowing nothing yet);
//! 3. the camera sees the gripper over the disc low down: somewhere over the
//!    disc the arm reaches 0.20 m above the part's top (the calibration's
//!    middle height), both marks are in view;
//! 4. (the generator's own) the camera sees the whole disc rim.
//!
//! The disc's rim is kept clear of the robot's column by the ranges (its
//! centre at least 0.65 m from the base axis) and of the drop-off by the
//! world (`DROP_OFF_CLEARANCE_M`).

use std::f64::consts::TAU;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use shared::app::pick::settings::PickSettings;
use shared::app::pick::window::WINDOW_JOINT_MARGIN_RAD;
use shared::app::tool::{effector_marks_base, TOOL_LENGTH_M};
use shared::planning::{
    gripper_down_rotation, ready_posture, solve_ik, well_conditioned, within_reach, IkConfig,
};
use shared::robot::{JointVector, Puma560};

use super::dimensions::DISC_RADIUS_M;
use super::workcell::Workcell;

/// The least contiguous arc of the part's circle the arm must reach, degrees.
pub const SERVE_ARC_DEG: f64 = 90.0;

/// The grasp's sequence, s: from meeting the part at the hover height to the
/// end of the lift, which the pick's plan holds within the arm's ranges as
/// the disc carries the part (`shared::app::pick::window`): the longest
/// track, the descent, the shortest settle (the pick waits longer for a
/// settled arm only where the window holds for it), the close and the lift
/// (2.95 s with the default settings).
pub fn grasp_sequence_s(settings: &PickSettings) -> f64 {
    f64::from(
        settings.track_window_s
            + settings.descend_s
            + settings.grasp_settle_s
            + settings.grasp_close_s
            + settings.lift_s,
    )
}

/// The contiguous arc of the part's circle the arm must reach, degrees, for a
/// disc turning at up to `top_speed_rad_s` (see the module's condition 1).
pub fn required_arc_deg(top_speed_rad_s: f64, settings: &PickSettings) -> f64 {
    SERVE_ARC_DEG.max((top_speed_rad_s.abs() * grasp_sequence_s(settings)).to_degrees())
}
/// Samples of the part's circle (every 2 degrees).
const CIRCLE_SAMPLES: usize = 180;
/// Closest a gripper-down grasp point may come to the base axis, m (the
/// controller's `MIN_RADIUS_FROM_BASE_AXIS_M`).
const MIN_RADIUS_M: f64 = 0.30;
/// The calibration's middle height above the part's top, m.
const LOW_VIEW_HEIGHT_M: f64 = 0.20;
/// Pixels the marks keep from the image border.
const VIEW_MARGIN_PX: f64 = 3.0;
/// Grid step of the points over the disc tried for the gripper's view, m.
const VIEW_GRID_M: f64 = 0.05;

/// Why a layout cannot be served.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Unservable {
    /// The part's circle is reachable over `arc_deg` at most, less than the
    /// `needed_deg` of [`required_arc_deg`].
    PartPathOutOfReach { arc_deg: f64, needed_deg: f64 },
    /// Nowhere over the disc at travel height does the camera see the marks.
    GripperNotSeenAtTravelHeight,
    /// Nowhere over the disc low down does the camera see the marks.
    GripperNotSeenOverDisc,
}

impl std::fmt::Display for Unservable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::PartPathOutOfReach {
                arc_deg,
                needed_deg,
            } => write!(
                f,
                "the part's circle is reachable over {arc_deg:.0} deg, less than the \
                 {needed_deg:.0} deg the disc turns in a grasp"
            ),
            Self::GripperNotSeenAtTravelHeight => write!(
                f,
                "the camera sees the gripper nowhere over the disc at travel height"
            ),
            Self::GripperNotSeenOverDisc => write!(
                f,
                "the camera sees the gripper nowhere over the disc at the calibration height"
            ),
        }
    }
}

/// The arm's geometry for the checks, in f64.
struct Arm {
    robot: Puma560<f64>,
    ik: IkConfig<f64>,
}

impl Arm {
    fn new() -> Self {
        Self {
            robot: Puma560::<f64>::new(),
            ik: IkConfig::default(),
        }
    }

    /// The flange pose gripper down over the grasp point `tool` (base frame),
    /// the wrist as in the ready posture turned to the point's azimuth.
    fn pose_over(&self, tool: &Vector3<f64>) -> Isometry3<f64> {
        let azimuth = tool.y.atan2(tool.x);
        Isometry3::from_parts(
            Translation3::from(tool + Vector3::new(0.0, 0.0, TOOL_LENGTH_M)),
            UnitQuaternion::from_rotation_matrix(&gripper_down_rotation(
                std::f64::consts::PI + azimuth,
            )),
        )
    }

    /// Whether the arm holds the gripper down over `tool` within its ranges.
    fn reaches(&self, tool: &Vector3<f64>) -> bool {
        let radius = tool.xy().norm();
        let pose = self.pose_over(tool);
        if radius < MIN_RADIUS_M || !within_reach(&self.robot, &pose.translation.vector) {
            return false;
        }
        // The seed: the ready posture turned so its flange points at the target
        // (joint 1 ahead of the azimuth by the arm plane's offset).
        let mut seed: JointVector<f64> = ready_posture();
        let offset = (0.15005 / radius).clamp(-1.0, 1.0).asin();
        seed.x = tool.y.atan2(tool.x) + offset;
        let limits = self.robot.joint_limits();
        if seed.x < limits.position_min.x - 0.2 || seed.x > limits.position_max.x + 0.2 {
            return false;
        }
        // The inverse kinematics clamp to the ranges: a solution on a stop
        // would pass without the controller's margin.
        let margin = f64::from(WINDOW_JOINT_MARGIN_RAD);
        let inside = |q: &JointVector<f64>| {
            q.iter()
                .zip(limits.position_min.iter().zip(limits.position_max.iter()))
                .all(|(x, (lo, hi))| *x >= *lo + margin && *x <= *hi - margin)
        };
        solve_ik(&self.robot, &pose, &seed, &self.ik)
            .is_ok_and(|q| well_conditioned(&self.robot, &q) && inside(&q))
    }

    /// Whether the camera sees both marks of the gripper held down over `tool`.
    fn marks_seen(&self, workcell: &Workcell, tool: &Vector3<f64>) -> bool {
        effector_marks_base(&self.pose_over(tool))
            .iter()
            .all(|mark| {
                workcell
                    .camera
                    .project_in_view(&workcell.disc_from_base(mark), VIEW_MARGIN_PX)
                    .is_some()
            })
    }
}

/// Whether the arm holds the gripper down over the grasp point `tool` (base
/// frame) and at the hover height above it, within its reach and joint ranges.
pub fn grasp_reachable(tool: &Vector3<f64>, settings: &PickSettings) -> bool {
    let arm = Arm::new();
    let hover = Vector3::new(0.0, 0.0, f64::from(settings.hover_height_m));
    arm.reaches(tool) && arm.reaches(&(tool + hover))
}

/// The longest contiguous run of `true` round the circle, in samples.
fn longest_circular_run(reachable: &[bool]) -> usize {
    let n = reachable.len();
    if reachable.iter().all(|&r| r) {
        return n;
    }
    let (mut best, mut run) = (0, 0);
    for k in 0..2 * n {
        if reachable[k % n] {
            run += 1;
            best = best.max(run);
        } else {
            run = 0;
        }
    }
    best.min(n)
}

/// The longest contiguous arc of the part's circle the arm reaches, degrees.
pub fn reachable_part_arc_deg(workcell: &Workcell, settings: &PickSettings) -> f64 {
    let arm = Arm::new();
    let count = workcell.features_rotating.len().max(1) as f64;
    let part_rotating = workcell.features_rotating.iter().sum::<Vector3<f64>>() / count;
    let hover = Vector3::new(0.0, 0.0, f64::from(settings.hover_height_m));
    let reachable: Vec<bool> = (0..CIRCLE_SAMPLES)
        .map(|k| {
            let theta = k as f64 * TAU / CIRCLE_SAMPLES as f64;
            let grasp =
                workcell.base_from_disc(&Workcell::disc_from_rotating(theta, &part_rotating));
            arm.reaches(&grasp) && arm.reaches(&(grasp + hover))
        })
        .collect();
    longest_circular_run(&reachable) as f64 * 360.0 / CIRCLE_SAMPLES as f64
}

/// Whether somewhere over the disc, the grasp point at base-frame height
/// `tool_z`, the arm reaches and the camera sees both marks.
fn gripper_seen_over_disc(workcell: &Workcell, arm: &Arm, tool_z: f64) -> bool {
    let steps = (DISC_RADIUS_M / VIEW_GRID_M).floor() as i32;
    let centre = workcell.base_from_disc_translation_m;
    (-steps..=steps).any(|i| {
        (-steps..=steps).any(|j| {
            let (x, y) = (f64::from(i) * VIEW_GRID_M, f64::from(j) * VIEW_GRID_M);
            if x.hypot(y) > DISC_RADIUS_M {
                return false;
            }
            let tool = Vector3::new(centre.x + x, centre.y + y, tool_z);
            arm.marks_seen(workcell, &tool) && arm.reaches(&tool)
        })
    })
}

/// Whether the arm can serve `workcell` with its disc turning at up to
/// `top_speed_rad_s` (see the module's conditions), or why not.
pub fn check_serve(
    workcell: &Workcell,
    settings: &PickSettings,
    top_speed_rad_s: f64,
) -> Result<(), Unservable> {
    let arc_deg = reachable_part_arc_deg(workcell, settings);
    let needed_deg = required_arc_deg(top_speed_rad_s, settings);
    if arc_deg < needed_deg {
        return Err(Unservable::PartPathOutOfReach {
            arc_deg,
            needed_deg,
        });
    }
    let arm = Arm::new();
    if !gripper_seen_over_disc(workcell, &arm, f64::from(settings.search_tool_height_m)) {
        return Err(Unservable::GripperNotSeenAtTravelHeight);
    }
    let part_top = workcell
        .features_rotating
        .iter()
        .map(|f| f.z)
        .fold(f64::NEG_INFINITY, f64::max)
        + workcell.base_from_disc_translation_m.z;
    if !gripper_seen_over_disc(workcell, &arm, part_top + LOW_VIEW_HEIGHT_M) {
        return Err(Unservable::GripperNotSeenOverDisc);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_round_the_circle_are_counted_across_its_start() {
        assert_eq!(longest_circular_run(&[true, false, true, true]), 3);
        assert_eq!(longest_circular_run(&[false, false]), 0);
        assert_eq!(longest_circular_run(&[true, true]), 2);
        assert_eq!(longest_circular_run(&[false, true, true, false, true]), 2);
    }

    #[test]
    fn a_faster_disc_needs_a_longer_reachable_arc() {
        let settings = PickSettings::default();
        // The default disc (0.5 rad/s, 5 % ripple): the fixed 90 degrees.
        assert_eq!(required_arc_deg(0.525, &settings), SERVE_ARC_DEG);
        // 1 rad/s with 10 % ripple: 1.1 rad/s for 2.95 s is 186 degrees.
        let fast = required_arc_deg(-1.1, &settings);
        assert!((fast - 185.9).abs() < 0.1, "{fast}");
    }

    #[test]
    fn the_arm_reaches_in_front_not_behind_nor_far() {
        let arm = Arm::new();
        assert!(arm.reaches(&Vector3::new(0.6, 0.0, 0.3)));
        assert!(arm.reaches(&Vector3::new(0.0, 0.6, 0.3)));
        // Behind the robot, where joint 1 ends (160 degrees either way).
        assert!(!arm.reaches(&Vector3::new(-0.6, 0.05, 0.3)));
        // Beyond the stretch, and at the column.
        assert!(!arm.reaches(&Vector3::new(1.0, 0.0, 0.3)));
        assert!(!arm.reaches(&Vector3::new(0.2, 0.0, 0.3)));
    }
}
