//! Motion planning for the pick (paper Section 4, Fig 3's "sensing system generates
//! the desired commands Y^d, Y^d-dot, Y^d-ddot"): where the gripper must be, how
//! fast and how accelerating, for the task-space controller of Eq 23.
//!
//! - [`quintic`]: boundary-value quintic segments, continuous in position,
//!   velocity and acceleration, so the commanded acceleration of Eq 23 never jumps.
//! - [`ik`]: damped-least-squares inverse kinematics of the PUMA 560 (reachability
//!   checks and joint-space feasibility of a plan).
//! - [`intercept`]: the earliest smooth path that meets a moving part within task
//!   and joint limits.
//! - [`arc`]: rest-to-rest moves round the base axis (never through the shoulder singularity).
//! - [`path`]: the path trait and the joint-space proof every plan passes.
//! - [`grasp_pose`]: the gripper's pose above a part (pointing down, yaw following it).

pub mod arc;
pub mod grasp_pose;
pub mod ik;
pub mod intercept;
pub mod path;
pub mod quintic;
pub mod scaling;

mod error;

pub use arc::{ArcLimits, ArcMove, ArcPoint};
pub use error::PlanError;
pub use grasp_pose::{gripper_down_rotation, gripper_yaw, nearest_equivalent_yaw, ready_posture};
pub use ik::{solve_ik, IkConfig};
pub use intercept::{
    plan_intercept, plan_intercept_where, InterceptLimits, InterceptPlan, TaskState,
};
pub use path::{
    check_joint_limits, check_joint_limits_with_margin, peak_speed_share, well_conditioned,
    within_reach, within_stretch, TaskPath, MAX_STRETCH, MIN_ARM_MANIPULABILITY, MIN_WRIST_SINE,
};
pub use quintic::Quintic;
