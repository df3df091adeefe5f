//! The safety invariants of a pick, checked against the world's truth every
//! control period: what the controller could get wrong, each with a stated
//! limit, and the worst value of each over a run.
//!
//! - joint positions within the arm's ranges (`shared::robot` limits);
//! - joint speeds within their limits;
//! - the gripper's grasp point at least [`STRIKE_CLEARANCE_M`] above the disc
//!   while over it (within 5 cm of its rim) and not holding the part;
//! - the arm clear of the camera by [`CAMERA_CLEARANCE_M`];
//! - the arm clear of itself by [`SELF_CLEARANCE_M`] (non-adjacent links);
//! - the gripper within [`NEAR_PART_M`] of the part and not holding it closes
//!   on it at most at [`NEAR_PART_SPEED_M_S`] (the relative velocity's
//!   component towards the part: moving away, as after a release, cannot
//!   strike it);
//! - the torque the motors apply (after the amplifier: its lag, the true
//!   torque constant, the ripple) within the joint's limit.
//!
//! The arm is a coarse chain of capsules (segments with a radius) on the DH
//! frames: the column from the floor to the shoulder (radius 0.20 m), the
//! upper arm from the shoulder to the elbow offset sideways by `d3` (0.10 m),
//! the forearm from the elbow to the wrist centre (0.07 m), and the wrist and
//! gripper from the wrist centre to the grasp point (0.05 m). Self-clearance
//! is measured between the pairs that are not neighbours: column and forearm,
//! column and gripper, upper arm and gripper. The camera hangs from above: a
//! capsule from its optical centre 4 m straight up (0.10 m, the camera body
//! and its rod). A post from the camera to the floor would stand in the disc
//! for the cameras the generator puts less than 0.45 m off the disc's centre
//! (it puts the optical centre 0.3 to 2.1 m from its aim point), so the cell's
//! camera is taken as hung from the ceiling or a gantry.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use shared::robot::{JointTrig, JointVector, Puma560};

/// The gripper strikes the disc if its grasp point comes lower than this above
/// the disc's surface while not holding the part (parts are 40 mm or more high,
/// and the grasp point stops at their top).
pub const STRIKE_CLEARANCE_M: f64 = 0.02;
/// The arm's surface stays this far from the camera's.
pub const CAMERA_CLEARANCE_M: f64 = 0.05;
/// Two links that are not neighbours stay this far apart (surface to surface).
pub const SELF_CLEARANCE_M: f64 = 0.02;
/// Within this distance of the part (the gripper's grasp point to the part's,
/// the centre of its top) and not holding it, the gripper closes on it at most
/// at [`NEAR_PART_SPEED_M_S`]: the last 5 cm of an approach, ten times the
/// grasp's horizontal tolerance.
pub const NEAR_PART_M: f64 = 0.05;
/// The reduced speed of ISO 10218-1 (250 mm/s), applied to the gripper
/// relative to the part it is about to touch.
pub const NEAR_PART_SPEED_M_S: f64 = 0.25;

/// The capsules' radii, m: column, upper arm, forearm, wrist and gripper, camera.
const COLUMN_RADIUS_M: f64 = 0.20;
const UPPER_ARM_RADIUS_M: f64 = 0.10;
const FOREARM_RADIUS_M: f64 = 0.07;
const GRIPPER_RADIUS_M: f64 = 0.05;
const CAMERA_RADIUS_M: f64 = 0.10;
/// The camera's rod goes this far up from its optical centre, m.
const CAMERA_ROD_M: f64 = 4.0;

/// A segment with a radius.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Capsule {
    pub a: Vector3<f64>,
    pub b: Vector3<f64>,
    pub radius_m: f64,
}

impl Capsule {
    /// Surface-to-surface distance (negative when they overlap).
    pub fn clearance(&self, other: &Capsule) -> f64 {
        segment_distance(&self.a, &self.b, &other.a, &other.b) - self.radius_m - other.radius_m
    }
}

/// The shortest distance between segments `p1 q1` and `p2 q2` (closest points
/// by clamped parameters, Ericson, *Real-Time Collision Detection*, 5.1.9).
pub fn segment_distance(
    p1: &Vector3<f64>,
    q1: &Vector3<f64>,
    p2: &Vector3<f64>,
    q2: &Vector3<f64>,
) -> f64 {
    let d1 = q1 - p1;
    let d2 = q2 - p2;
    let r = p1 - p2;
    let a = d1.dot(&d1);
    let e = d2.dot(&d2);
    let f = d2.dot(&r);
    let eps = 1e-12;
    let (s, t) = if a <= eps && e <= eps {
        (0.0, 0.0)
    } else if a <= eps {
        (0.0, (f / e).clamp(0.0, 1.0))
    } else {
        let c = d1.dot(&r);
        if e <= eps {
            ((-c / a).clamp(0.0, 1.0), 0.0)
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let mut s = if denom > eps {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t = (b * s + f) / e;
            if t < 0.0 {
                t = 0.0;
                s = (-c / a).clamp(0.0, 1.0);
            } else if t > 1.0 {
                t = 1.0;
                s = ((b - c) / a).clamp(0.0, 1.0);
            }
            (s, t)
        }
    };
    ((p1 + d1 * s) - (p2 + d2 * t)).norm()
}

/// The arm's capsules at joint angles `q`: column, upper arm, forearm, gripper.
pub fn arm_capsules(model: &Puma560<f64>, q: &JointVector<f64>) -> [Capsule; 4] {
    let chain = model.frame_chain_with(&JointTrig::new(q));
    let [_, o1, o2, o3, o4, _, o6] = chain.origins;
    let z1 = chain.axes[1][2];
    let d3 = model.dh_table()[2].d;
    let flange = model.forward_kinematics(q);
    let tool = shared::app::tool::tool_point_base(&flange);
    [
        Capsule {
            a: Vector3::zeros(),
            b: o1,
            radius_m: COLUMN_RADIUS_M,
        },
        Capsule {
            a: o1 + z1 * d3,
            b: o2 + z1 * d3,
            radius_m: UPPER_ARM_RADIUS_M,
        },
        Capsule {
            a: o3,
            b: o4,
            radius_m: FOREARM_RADIUS_M,
        },
        Capsule {
            a: o6,
            b: tool,
            radius_m: GRIPPER_RADIUS_M,
        },
    ]
}

/// The smallest surface distance between links that are not neighbours.
pub fn self_clearance(capsules: &[Capsule; 4]) -> f64 {
    let [column, upper, forearm, gripper] = capsules;
    column
        .clearance(forearm)
        .min(column.clearance(gripper))
        .min(upper.clearance(gripper))
}

/// The camera's capsule: its optical centre and a rod straight up.
pub fn camera_capsule(camera_centre_base_m: &Vector3<f64>) -> Capsule {
    Capsule {
        a: *camera_centre_base_m,
        b: camera_centre_base_m + Vector3::new(0.0, 0.0, CAMERA_ROD_M),
        radius_m: CAMERA_RADIUS_M,
    }
}

/// The smallest distance of any joint from the ends of its range, rad
/// (negative: outside).
pub fn joint_limit_margin(model: &Puma560<f64>, q: &JointVector<f64>) -> f64 {
    let limits = model.joint_limits();
    (0..6)
        .map(|j| (q[j] - limits.position_min[j]).min(limits.position_max[j] - q[j]))
        .fold(f64::INFINITY, f64::min)
}

/// What the invariants read of one control period (truth, never the controller's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PeriodTruth {
    pub q: JointVector<f64>,
    pub qd: JointVector<f64>,
    pub part_base_m: Vector3<f64>,
    pub part_velocity_base_m_s: Vector3<f64>,
    pub part_held: bool,
    /// The largest |applied torque| / limit over the joints during the period.
    pub applied_torque_ratio: f64,
}

/// The worst value of each invariant over a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SafetyWorst {
    /// Closest any joint came to the end of its range, degrees.
    pub joint_limit_margin_deg: f64,
    /// Fastest joint / its speed limit.
    pub speed_ratio: f64,
    /// Lowest grasp point over the disc without the part, mm (NaN: never over it).
    pub disc_clearance_mm: f64,
    /// Closest the arm came to the camera, mm.
    pub camera_clearance_mm: f64,
    /// Closest two non-adjacent links came, mm.
    pub self_clearance_mm: f64,
    /// Fastest the gripper closed on the part within [`NEAR_PART_M`] of it
    /// without holding it, mm/s (0: never that near, or only moving away).
    pub near_part_speed_mm_s: f64,
    /// Largest applied torque / its joint's limit.
    pub applied_torque_ratio: f64,
}

impl Default for SafetyWorst {
    fn default() -> Self {
        Self {
            joint_limit_margin_deg: f64::NAN,
            speed_ratio: f64::NAN,
            disc_clearance_mm: f64::NAN,
            camera_clearance_mm: f64::NAN,
            self_clearance_mm: f64::NAN,
            near_part_speed_mm_s: f64::NAN,
            applied_torque_ratio: f64::NAN,
        }
    }
}

impl SafetyWorst {
    /// Every invariant these worst values break (a NaN where a value must
    /// exist breaks it too).
    pub fn violations(&self) -> Vec<String> {
        let mut found = Vec::new();
        let mut check = |ok: bool, text: String| {
            if !ok {
                found.push(text);
            }
        };
        check(
            self.joint_limit_margin_deg >= 0.0,
            format!(
                "a joint {:.2} deg past the end of its range",
                -self.joint_limit_margin_deg
            ),
        );
        check(
            self.speed_ratio <= 1.0,
            format!("joint speed {:.2} x its limit", self.speed_ratio),
        );
        // NaN: the gripper never came over the disc.
        check(
            self.disc_clearance_mm.is_nan() || self.disc_clearance_mm >= STRIKE_CLEARANCE_M * 1e3,
            format!("gripper {:.1} mm above the disc", self.disc_clearance_mm),
        );
        check(
            self.camera_clearance_mm >= CAMERA_CLEARANCE_M * 1e3,
            format!("arm {:.1} mm from the camera", self.camera_clearance_mm),
        );
        check(
            self.self_clearance_mm >= SELF_CLEARANCE_M * 1e3,
            format!("links {:.1} mm from each other", self.self_clearance_mm),
        );
        check(
            self.near_part_speed_mm_s <= NEAR_PART_SPEED_M_S * 1e3,
            format!(
                "gripper closing at {:.0} mm/s within {:.0} mm of the part",
                self.near_part_speed_mm_s,
                NEAR_PART_M * 1e3
            ),
        );
        check(
            self.applied_torque_ratio <= 1.0,
            format!(
                "applied torque {:.3} x its limit",
                self.applied_torque_ratio
            ),
        );
        found
    }
}

/// Tracks the invariants' worst values over a run.
#[derive(Debug, Clone)]
pub struct SafetyMonitor {
    model: Puma560<f64>,
    camera: Capsule,
    disc_centre_base_m: Vector3<f64>,
    disc_radius_m: f64,
    worst: SafetyWorst,
}

impl SafetyMonitor {
    /// For an arm of `model`'s kinematics in a cell with the camera's optical
    /// centre and the disc (centre on its surface, radius) where given.
    pub fn new(
        model: &Puma560<f64>,
        camera_centre_base_m: [f64; 3],
        disc_centre_base_m: [f64; 3],
        disc_radius_m: f64,
    ) -> Self {
        Self {
            model: *model,
            camera: camera_capsule(&Vector3::from(camera_centre_base_m)),
            disc_centre_base_m: Vector3::from(disc_centre_base_m),
            disc_radius_m,
            worst: SafetyWorst {
                joint_limit_margin_deg: f64::INFINITY,
                speed_ratio: 0.0,
                disc_clearance_mm: f64::INFINITY,
                camera_clearance_mm: f64::INFINITY,
                self_clearance_mm: f64::INFINITY,
                near_part_speed_mm_s: 0.0,
                applied_torque_ratio: 0.0,
            },
        }
    }

    /// Takes one period's truth in.
    pub fn observe(&mut self, truth: &PeriodTruth) {
        let w = &mut self.worst;
        let limits = self.model.joint_limits();
        w.joint_limit_margin_deg = w
            .joint_limit_margin_deg
            .min(joint_limit_margin(&self.model, &truth.q).to_degrees());
        for j in 0..6 {
            let ratio = truth.qd[j].abs() / limits.velocity_max[j];
            w.speed_ratio = if ratio.is_nan() {
                f64::NAN
            } else {
                w.speed_ratio.max(ratio)
            };
        }
        w.applied_torque_ratio = w.applied_torque_ratio.max(truth.applied_torque_ratio);
        let capsules = arm_capsules(&self.model, &truth.q);
        w.self_clearance_mm = w.self_clearance_mm.min(self_clearance(&capsules) * 1e3);
        let [_, upper, forearm, gripper] = capsules;
        let camera = [upper, forearm, gripper]
            .iter()
            .map(|c| c.clearance(&self.camera))
            .fold(f64::INFINITY, f64::min);
        w.camera_clearance_mm = w.camera_clearance_mm.min(camera * 1e3);
        let tool = gripper.b;
        let over_disc = (tool - self.disc_centre_base_m).xy().norm() <= self.disc_radius_m + 0.05;
        if !truth.part_held && over_disc {
            w.disc_clearance_mm = w
                .disc_clearance_mm
                .min((tool.z - self.disc_centre_base_m.z) * 1e3);
        }
        let to_part = truth.part_base_m - tool;
        if !truth.part_held && to_part.norm() < NEAR_PART_M {
            let h = 1e-6;
            let at = |q: &JointVector<f64>| {
                shared::app::tool::tool_point_base(&self.model.forward_kinematics(q))
            };
            let tool_velocity =
                (at(&(truth.q + truth.qd * h)) - at(&(truth.q - truth.qd * h))) / (2.0 * h);
            let relative = tool_velocity - truth.part_velocity_base_m_s;
            let closing = relative.dot(&to_part) / to_part.norm().max(1e-9);
            w.near_part_speed_mm_s = w.near_part_speed_mm_s.max(closing * 1e3);
        }
    }

    /// The worst values so far (NaN for a clearance never measured).
    pub fn worst(&self) -> SafetyWorst {
        let mut w = self.worst;
        for v in [
            &mut w.joint_limit_margin_deg,
            &mut w.disc_clearance_mm,
            &mut w.camera_clearance_mm,
            &mut w.self_clearance_mm,
        ] {
            if v.is_infinite() {
                *v = f64::NAN;
            }
        }
        w
    }
}

#[cfg(test)]
mod tests;
