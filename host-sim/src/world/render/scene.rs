//! What one camera frame shows, in the disc frame, at the start, middle and
//! end of its exposure: the disc (turning), the marks, the part's body, and
//! the arm as capsules along its links from the forward kinematics of the
//! true joint angles. The middle is the trigger instant, where the
//! controller's labelled points are taken, so a mark's true centre for
//! scoring is its middle position.

use nalgebra::{Isometry3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use shared::app::tool::EFFECTOR_MARKS_FLANGE_M;
use shared::robot::{JointTrig, JointVector, Puma560};

use crate::scenario::pick::ImageSettings;
use crate::world::dimensions::DISC_RADIUS_M;
use crate::world::workcell::Workcell;
use crate::world::World;

/// Start, middle (the trigger instant) and end of the exposure.
pub const START: usize = 0;
pub const MID: usize = 1;
pub const END: usize = 2;

/// Which mark a mark is (for scoring: the renderer draws them all alike).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum MarkKind {
    DiscCentre,
    Reference,
    /// Part feature `i` in the part's fixed order.
    Feature(u8),
    /// Gripper mark 0 or 1.
    Effector(u8),
    /// A bright object on the disc that is no mark (a bolt head, a glint):
    /// what identification must not take for one.
    Distractor(u8),
}

impl MarkKind {
    /// The class name used in reports.
    pub fn class(&self) -> &'static str {
        match self {
            Self::DiscCentre => "disc centre",
            Self::Reference => "reference",
            Self::Feature(_) => "part feature",
            Self::Effector(_) => "gripper",
            Self::Distractor(_) => "distractor",
        }
    }
}

/// A flat round mark: centre and normal (towards its visible side) at the
/// start, middle and end of the exposure.
#[derive(Debug, Clone, PartialEq)]
pub struct Mark {
    pub kind: MarkKind,
    pub centre_disc: [Vector3<f64>; 3],
    pub normal_disc: [Vector3<f64>; 3],
    pub radius_m: f64,
}

impl Mark {
    /// `count` points of the rim at exposure instant `k` (0 start, 1 middle, 2 end).
    pub fn rim(&self, k: usize, count: usize) -> Vec<Vector3<f64>> {
        self.rim_at(
            &self.centre_disc[k.min(2)],
            &self.normal_disc[k.min(2)],
            count,
        )
    }

    /// The rim at a centre and normal between the exposure's instants.
    pub fn rim_at(
        &self,
        centre: &Vector3<f64>,
        normal: &Vector3<f64>,
        count: usize,
    ) -> Vec<Vector3<f64>> {
        let (e1, e2) = plane_basis(normal);
        (0..count)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / count as f64;
                centre + (e1 * a.cos() + e2 * a.sin()) * self.radius_m
            })
            .collect()
    }
}

/// A capsule of the arm: its axis' two ends at the exposure's start and end.
#[derive(Debug, Clone, PartialEq)]
pub struct Capsule {
    pub ends_disc: [[Vector3<f64>; 2]; 2],
    pub radius_m: f64,
    /// Marks drawn on it are nearer the camera than its surface by this much
    /// in the depth test (the gripper's mark carrier), m.
    pub carries_marks: bool,
}

/// The part's body: a prism whose top is its features' convex hull grown by
/// a margin; outlines at the exposure's three instants.
#[derive(Debug, Clone, PartialEq)]
pub struct PartBody {
    pub top_disc: [Vec<Vector3<f64>>; 3],
    pub bottom_disc: [Vec<Vector3<f64>>; 3],
    /// The top face's outward normal at the middle of the exposure.
    pub up_disc: Vector3<f64>,
}

/// One frame's scene, disc frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// The trigger instant (middle of the exposure), s.
    pub time_s: f64,
    /// The disc's angle at the exposure's three instants, rad.
    pub theta_rad: [f64; 3],
    pub disc_radius_m: f64,
    /// Height of the disc surface above the floor, m.
    pub disc_above_floor_m: f64,
    pub marks: Vec<Mark>,
    pub part: Option<PartBody>,
    pub arm: Vec<Capsule>,
}

/// Where the part is during the exposure.
#[derive(Debug, Clone, PartialEq)]
pub enum PartPlacement {
    /// On the disc: its rotating-frame features turn with the disc.
    OnDisc,
    /// In the gripper: its base-frame features at the middle of the exposure,
    /// carried by the flange.
    Held { features_base: Vec<Vector3<f64>> },
    /// Put down, base frame, still.
    Placed { features_base: Vec<Vector3<f64>> },
}

/// The state a frame is rendered from.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameState {
    pub time_s: f64,
    pub theta_rad: [f64; 3],
    pub q_rad: [JointVector<f64>; 3],
    pub part: PartPlacement,
    pub part_height_m: f64,
}

impl FrameState {
    /// The world's state at its current instant, with the exposure centred on
    /// it: the disc's angle from the conveyor's profile, the joints moved
    /// linearly at their current speeds.
    pub fn from_world(world: &World, exposure_s: f64) -> Self {
        let t = world.time_s();
        let half = exposure_s / 2.0;
        let conveyor = world.conveyor();
        let state = world.plant().state();
        let truth = world.truth();
        let part = if truth.part_held {
            PartPlacement::Held {
                features_base: world.part_features_base(),
            }
        } else if world.placed_position_base().is_some() {
            PartPlacement::Placed {
                features_base: world.part_features_base(),
            }
        } else {
            PartPlacement::OnDisc
        };
        Self {
            time_s: t,
            theta_rad: [
                conveyor.theta(t - half),
                conveyor.theta(t),
                conveyor.theta(t + half),
            ],
            q_rad: [
                state.q - state.qd * half,
                state.q,
                state.q + state.qd * half,
            ],
            part,
            part_height_m: world.experiment().part.height_m,
        }
    }
}

/// Two unit vectors spanning the plane normal to `normal`.
pub fn plane_basis(normal: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let n = normal.normalize();
    let helper = if n.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e1 = n.cross(&helper).normalize();
    (e1, n.cross(&e1))
}

/// Radii of the arm's capsules, m, by link (1: the pedestal, 2: upper arm,
/// 3: the shoulder offset, 4: forearm; 5 and 6 have no length).
const LINK_RADII_M: [f64; 6] = [0.09, 0.065, 0.05, 0.04, 0.035, 0.035];
/// The gripper in the flange frame (z along the tool): body, fingers and the
/// bar whose top carries the two marks (`EFFECTOR_MARKS_FLANGE_M`, z = 0.03,
/// facing the flange's -z).
const GRIPPER_BODY: ([f64; 3], [f64; 3], f64) = ([0.0, 0.0, -0.01], [0.0, 0.0, 0.085], 0.022);
const GRIPPER_FINGERS: [([f64; 3], [f64; 3], f64); 2] = [
    ([0.014, 0.0, 0.085], [0.014, 0.0, 0.12], 0.007),
    ([-0.014, 0.0, 0.085], [-0.014, 0.0, 0.12], 0.007),
];
const MARK_BAR_RADIUS_M: f64 = 0.017;
const MARK_BAR_HALF_LENGTH_M: f64 = 0.068;

/// The arm's capsule axes in the base frame at `q` (each `(a, b, radius, carries_marks)`).
fn arm_axes(
    model: &Puma560<f64>,
    q: &JointVector<f64>,
) -> Vec<(Vector3<f64>, Vector3<f64>, f64, bool)> {
    let chain = model.frame_chain_with(&JointTrig::new(q));
    let mut axes = Vec::new();
    for (i, link) in model.dh_table().iter().enumerate() {
        let (Some(origin), Some(next), Some(frame)) = (
            chain.origins.get(i),
            chain.origins.get(i + 1),
            chain.axes.get(i),
        ) else {
            continue;
        };
        let radius = LINK_RADII_M.get(i).copied().unwrap_or(0.03);
        // A_i: d along z_{i-1}, then a along x_i: two straight pieces.
        let elbow = origin + frame[2] * link.d;
        for (a, b) in [(*origin, elbow), (elbow, *next)] {
            if (b - a).norm() > 1e-6 {
                axes.push((a, b, radius, false));
            }
        }
    }
    let flange = flange_pose(&chain);
    let at = |p: [f64; 3]| (flange * Point3::from(p)).coords;
    let (a, b, r) = GRIPPER_BODY;
    axes.push((at(a), at(b), r, false));
    for (a, b, r) in GRIPPER_FINGERS {
        axes.push((at(a), at(b), r, false));
    }
    // The bar runs through both marks' centres, its top at their height.
    let [m0, m1] = EFFECTOR_MARKS_FLANGE_M.map(Vector3::from);
    let along = (m1 - m0).normalize();
    let middle = (m0 + m1) / 2.0 + Vector3::new(0.0, 0.0, MARK_BAR_RADIUS_M);
    let end = |sign: f64| {
        let p = middle + along * (sign * MARK_BAR_HALF_LENGTH_M);
        at([p.x, p.y, p.z])
    };
    axes.push((end(-1.0), end(1.0), MARK_BAR_RADIUS_M, true));
    axes
}

fn flange_pose(chain: &shared::robot::FrameChain<f64>) -> Isometry3<f64> {
    let rotation = Rotation3::from_matrix_unchecked(chain.base_from_flange_rotation());
    Isometry3::from_parts(
        Translation3::from(chain.flange_origin()),
        UnitQuaternion::from_rotation_matrix(&rotation),
    )
}

/// The distractors of `settings` in the rotating frame with their radii:
/// spread over the disc between 0.08 m and 0.42 m from its centre (golden
/// angle steps, so the same every run), alternately smaller and larger than
/// every mark (`distractor_radii_m`).
pub fn distractors_rotating(settings: &ImageSettings) -> Vec<(Vector3<f64>, f64)> {
    (0..settings.distractors)
        .map(|k| {
            let k_f = k as f64;
            let radius = 0.08 + 0.34 * (k_f * 0.618_034 + 0.37).fract();
            let angle = 1.1 + k_f * 2.399_963;
            let size = if k % 2 == 0 {
                settings.distractor_radii_m[0]
            } else {
                settings.distractor_radii_m[1]
            };
            (
                Vector3::new(radius * angle.cos(), radius * angle.sin(), 0.0),
                size,
            )
        })
        .collect()
}

/// Builds the scene of `frame` in `workcell` with the mark sizes and the
/// part's margin of `settings`.
pub fn build_scene(workcell: &Workcell, frame: &FrameState, settings: &ImageSettings) -> Scene {
    let model = Puma560::<f64>::new();
    let disc_from_base_iso = {
        let yaw = workcell.base_from_disc_yaw_rad;
        let base_from_disc = Isometry3::from_parts(
            Translation3::from(workcell.base_from_disc_translation_m),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw),
        );
        base_from_disc.inverse()
    };
    let flange: [Isometry3<f64>; 3] = frame
        .q_rad
        .map(|q| disc_from_base_iso * flange_pose(&model.frame_chain_with(&JointTrig::new(&q))));
    let turn = |theta: f64| {
        Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), theta),
        )
    };

    let mut marks = Vec::new();
    let z = Vector3::z();
    marks.push(Mark {
        kind: MarkKind::DiscCentre,
        centre_disc: [Vector3::zeros(); 3],
        normal_disc: [z; 3],
        radius_m: settings.centre_mark_radius_m,
    });
    marks.push(Mark {
        kind: MarkKind::Reference,
        centre_disc: frame.theta_rad.map(|theta| workcell.reference_disc(theta)),
        normal_disc: [z; 3],
        radius_m: settings.reference_mark_radius_m,
    });

    for (i, (p_rotating, radius_m)) in distractors_rotating(settings).into_iter().enumerate() {
        marks.push(Mark {
            kind: MarkKind::Distractor(u8::try_from(i).unwrap_or(u8::MAX)),
            centre_disc: frame
                .theta_rad
                .map(|theta| Workcell::disc_from_rotating(theta, &p_rotating)),
            normal_disc: [z; 3],
            radius_m,
        });
    }

    // The part at the middle of the exposure, and its motion to the other instants.
    let (features_mid, up_mid, motion): (Vec<Vector3<f64>>, Vector3<f64>, [Isometry3<f64>; 3]) =
        match &frame.part {
            PartPlacement::OnDisc => {
                let mid = frame.theta_rad[MID];
                (
                    workcell
                        .features_rotating
                        .iter()
                        .map(|p| Workcell::disc_from_rotating(mid, p))
                        .collect(),
                    z,
                    frame.theta_rad.map(|theta| turn(theta - mid)),
                )
            }
            PartPlacement::Held { features_base } => {
                let to_disc: Vec<Vector3<f64>> = features_base
                    .iter()
                    .map(|p| workcell.disc_from_base(p))
                    .collect();
                // Grasped with the gripper pointing down: the part's top faces the flange's -z.
                let up = -(flange[MID].rotation * Vector3::z());
                let inverse_mid = flange[MID].inverse();
                (to_disc, up, flange.map(|f| f * inverse_mid))
            }
            PartPlacement::Placed { features_base } => (
                features_base
                    .iter()
                    .map(|p| workcell.disc_from_base(p))
                    .collect(),
                z,
                [Isometry3::identity(); 3],
            ),
        };
    let moved = |k: usize, p: &Vector3<f64>| (motion[k] * Point3::from(*p)).coords;
    for (i, feature) in features_mid.iter().enumerate() {
        marks.push(Mark {
            kind: MarkKind::Feature(u8::try_from(i).unwrap_or(u8::MAX)),
            centre_disc: [moved(START, feature), *feature, moved(END, feature)],
            normal_disc: [
                motion[START].rotation * up_mid,
                up_mid,
                motion[END].rotation * up_mid,
            ],
            radius_m: if i == 0 && settings.key_feature_mark_radius_m > 0.0 {
                settings.key_feature_mark_radius_m
            } else {
                settings.feature_mark_radius_m
            },
        });
    }
    let part = part_outline(&features_mid, &up_mid, settings.part_margin_m).map(|top_mid| {
        let bottom_mid: Vec<Vector3<f64>> = top_mid
            .iter()
            .map(|p| p - up_mid * frame.part_height_m)
            .collect();
        let at = |k: usize, points: &[Vector3<f64>]| -> Vec<Vector3<f64>> {
            points.iter().map(|p| moved(k, p)).collect()
        };
        PartBody {
            top_disc: [at(START, &top_mid), top_mid.clone(), at(END, &top_mid)],
            bottom_disc: [
                at(START, &bottom_mid),
                bottom_mid.clone(),
                at(END, &bottom_mid),
            ],
            up_disc: up_mid,
        }
    });

    for (index, [x, y, zf]) in EFFECTOR_MARKS_FLANGE_M.iter().enumerate() {
        let p = Point3::new(*x, *y, *zf);
        marks.push(Mark {
            kind: MarkKind::Effector(index as u8),
            centre_disc: flange.map(|f| (f * p).coords),
            normal_disc: flange.map(|f| -(f.rotation * Vector3::z())),
            radius_m: settings
                .effector_mark_radii_m
                .get(index)
                .copied()
                .unwrap_or(settings.effector_mark_radii_m[0]),
        });
    }

    let axes_start = arm_axes(&model, &frame.q_rad[START]);
    let axes_end = arm_axes(&model, &frame.q_rad[END]);
    let arm = axes_start
        .iter()
        .zip(axes_end.iter())
        .map(
            |(&(a0, b0, radius_m, carries_marks), &(a1, b1, _, _))| Capsule {
                ends_disc: [
                    [workcell.disc_from_base(&a0), workcell.disc_from_base(&b0)],
                    [workcell.disc_from_base(&a1), workcell.disc_from_base(&b1)],
                ],
                radius_m,
                carries_marks,
            },
        )
        .collect();

    Scene {
        time_s: frame.time_s,
        theta_rad: frame.theta_rad,
        disc_radius_m: DISC_RADIUS_M,
        disc_above_floor_m: workcell.base_from_disc_translation_m.z,
        marks,
        part,
        arm,
    }
}

/// Arc samples per corner of the part's rounded outline.
const ARC_SAMPLES: usize = 8;

/// The part's top outline: the convex hull of its features (in the plane
/// normal to `up` through their mean) grown by `margin_m`, corners rounded.
fn part_outline(
    features: &[Vector3<f64>],
    up: &Vector3<f64>,
    margin_m: f64,
) -> Option<Vec<Vector3<f64>>> {
    let count = features.len();
    if count == 0 {
        return None;
    }
    let centre = features.iter().fold(Vector3::zeros(), |s, p| s + p) / count as f64;
    let (e1, e2) = plane_basis(up);
    let flat: Vec<[f64; 2]> = features
        .iter()
        .map(|p| {
            let d = p - centre;
            [d.dot(&e1), d.dot(&e2)]
        })
        .collect();
    let hull = super::raster::convex_hull(&flat);
    let n = hull.len();
    let mut outline = Vec::new();
    for i in 0..n {
        let (Some(prev), Some(here), Some(next)) = (
            hull.get((i + n - 1) % n),
            hull.get(i),
            hull.get((i + 1) % n),
        ) else {
            continue;
        };
        // Outward normals of the edges before and after this corner (hull
        // counter-clockwise); a lone point or a segment gets a full round end.
        let normal = |a: &[f64; 2], b: &[f64; 2]| {
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let length = dx.hypot(dy);
            (length > 1e-12).then(|| dy.atan2(dx) - std::f64::consts::FRAC_PI_2)
        };
        let (start, mut end) = match (normal(prev, here), normal(here, next)) {
            (Some(a), Some(b)) => (a, b),
            (None, Some(b)) => (b - std::f64::consts::PI, b),
            (Some(a), None) => (a, a + std::f64::consts::PI),
            (None, None) => (0.0, std::f64::consts::TAU),
        };
        while end < start {
            end += std::f64::consts::TAU;
        }
        for s in 0..=ARC_SAMPLES {
            let a = start + (end - start) * s as f64 / ARC_SAMPLES as f64;
            let x = here[0] + margin_m * a.cos();
            let y = here[1] + margin_m * a.sin();
            outline.push(centre + e1 * x + e2 * y);
        }
    }
    Some(outline)
}

impl Scene {
    /// The same scene with nothing moving during the exposure (no motion
    /// blur): everything where it is at the middle.
    pub fn without_motion(&self) -> Self {
        let mut still = self.clone();
        still.theta_rad = [self.theta_rad[MID]; 3];
        for mark in &mut still.marks {
            mark.centre_disc = [mark.centre_disc[MID]; 3];
            mark.normal_disc = [mark.normal_disc[MID]; 3];
        }
        if let Some(part) = &mut still.part {
            part.top_disc = [
                part.top_disc[MID].clone(),
                part.top_disc[MID].clone(),
                part.top_disc[MID].clone(),
            ];
            part.bottom_disc = [
                part.bottom_disc[MID].clone(),
                part.bottom_disc[MID].clone(),
                part.bottom_disc[MID].clone(),
            ];
        }
        for capsule in &mut still.arm {
            let [[a0, b0], [a1, b1]] = capsule.ends_disc;
            let mid = [a0.lerp(&a1, 0.5), b0.lerp(&b1, 0.5)];
            capsule.ends_disc = [mid, mid];
        }
        still
    }
}
