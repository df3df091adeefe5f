//! Homing at power-on, before the pick moves: the six joints' counter
//! offsets from their potentiometers and index pulses ([`super::homing`]),
//! with the arm held and moved in joint space.
//!
//! The sequence, one sample per control period:
//! 1. *Coarse.* The arm is held where it stands (each joint's spring
//!    anchored at its first count, the nominal model's gravity torque fed
//!    forward at the first potentiometer reading) while
//!    [`COARSE_SAMPLES`](super::homing::COARSE_SAMPLES) potentiometer readings
//!    are averaged per joint.
//! 2. *Seek.* Every joint turns slowly (at most [`SEARCH_SPEED_RAD_S`],
//!    towards the middle of its range) until an index pulse latches its
//!    counter; a joint that has met its index stops there. A joint that
//!    travels its search span, or whose reference has stood at the span's
//!    end for [`STALL_LIMIT_S`], without an index stops homing with its
//!    cause.
//! 3. *Return.* Every joint goes back to the count it stood at power-on.
//! 4. *Settle.* The arm is held there until it is at rest; every reading,
//!    each potentiometer must agree with its homed angle within its
//!    tolerance.
//!
//! Then the offsets are known: the pick reads `count - offset`, so its
//! control period gains a subtraction per joint and nothing else
//! ([`HomedOffsets::apply`]).
//!
//! The law is the joint brake's (`pick::brake`), stiffer: a spring to a
//! reference and damping to its speed, with the nominal model's gravity and
//! (part of its) friction fed forward (Eq 23's G and F terms), within the
//! drives' torque headroom.

use crate::app::homing::{HomingError, IndexGrid, JointHoming, JointHomingSpec, JOINTS};
use crate::app::joint_observer::JointObserver;
use crate::control::TaskSpaceModel;
use crate::kernels::micros_to_seconds;
use crate::protocol::{FaultCause, PickPhase, PickTelemetry, SensorSample};
use crate::robot::table::GEAR_RATIO;
use crate::robot::{DriveOptions, JointVector, Puma560};

/// Commissioning: each joint's angle of its index 0, rad (the other indexes
/// are a motor turn, `2 pi / |G|` of joint angle, apart). Measured once on
/// the arm; the simulated arm has its index pulses here.
pub const INDEX_PHASE_RAD: [f32; JOINTS] = [0.0213, -0.0127, 0.0341, 0.0072, -0.0288, 0.0151];
/// A potentiometer's tolerance as a share of its joint's index pitch: under
/// half, so the nearest index is the right one (0.35: 20 mrad on joint 2,
/// whose pitch is the finest).
pub const POT_TOLERANCE_OF_PITCH: f32 = 0.35;
/// The search's span as a share of the pitch: over one, so an index is met.
pub const SEARCH_SPAN_OF_PITCH: f32 = 1.5;
/// Fastest a joint turns while homing, rad/s.
pub const SEARCH_SPEED_RAD_S: f32 = 0.08;
/// The reference's acceleration while homing, rad/s^2.
pub const SEARCH_ACCELERATION_RAD_S2: f32 = 0.4;
/// Longest the reference may stand at the end of its search while the joint
/// has met no index (a stalled joint), s.
pub const STALL_LIMIT_S: f32 = 1.0;
/// The arm is at rest after homing when no joint turns faster, rad/s.
pub const REST_SPEED_RAD_S: f32 = 0.01;
/// Least time the arm rests before the pick starts, s.
pub const SETTLE_S: f32 = 0.1;
/// Longest the settle waits for rest before handing over anyway, s (the
/// pick holds the arm from its first period).
pub const SETTLE_LIMIT_S: f32 = 2.0;
/// Stiffness of each joint's spring to its reference, N m/rad: stiff
/// enough that the friction the feed-forward leaves (the true friction
/// is within 30 % of the table's) lags a joint by under 10 mrad, so it
/// turns smoothly rather than sticking and slipping.
const STIFFNESS_NM: [f32; JOINTS] = [1500.0, 3000.0, 1500.0, 60.0, 60.0, 40.0];
/// Damping of each joint, N m s/rad: about 0.7 of critical with the arm's
/// inertia (armature included) at the ready posture.
const DAMPING_NM_S: [f32; JOINTS] = [100.0, 180.0, 60.0, 4.0, 4.0, 3.0];
/// The share of the table's friction fed forward: the lower end of the
/// true friction's spread, so the feed-forward never drives a joint ahead
/// of its reference.
const FRICTION_FEED_FORWARD_SHARE: f32 = 0.7;
/// The speed observer's bandwidth, rad/s, and the largest jump it accepts.
const OBSERVER_BANDWIDTH_RAD_S: f32 = 150.0;
const OBSERVER_MAX_JUMP_RAD: f32 = 0.05;
/// The longest period step taken into the reference, s (a stalled link does
/// not make the reference leap).
const MAX_STEP_S: f32 = 0.02;
/// Coulomb smoothing of the fed-forward friction, rad/s (the pick's).
const COULOMB_WIDTH_RAD_S: f64 = 0.01;

/// The homing data of the PUMA 560 whose counters read `counts_per_rad`:
/// its index grids (gear ratios, [`INDEX_PHASE_RAD`]), its potentiometers'
/// tolerance and the search span.
pub fn puma_homing_specs(counts_per_rad: &[f32; JOINTS]) -> [JointHomingSpec; JOINTS] {
    core::array::from_fn(|j| {
        let gear = GEAR_RATIO.get(j).copied().unwrap_or(1.0) as f32;
        let grid = IndexGrid::of_gear(gear, INDEX_PHASE_RAD.get(j).copied().unwrap_or(0.0));
        JointHomingSpec {
            grid,
            pot_tolerance_rad: POT_TOLERANCE_OF_PITCH * grid.pitch_rad,
            counts_per_rad: counts_per_rad.get(j).copied().unwrap_or(0.0),
            search_span_rad: SEARCH_SPAN_OF_PITCH * grid.pitch_rad,
        }
    })
}

/// The counter offsets homing found: `angle = (count - offset) /
/// counts_per_rad`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HomedOffsets {
    /// Per joint, counts (modulo 2^32, as the counters wrap).
    pub counts: [i32; JOINTS],
}

impl HomedOffsets {
    /// No offset (counters already zero at q = 0).
    pub const ZERO: Self = Self {
        counts: [0; JOINTS],
    };

    /// Offsets good to the potentiometers' tolerance, from one sample's
    /// potentiometers: for the drive interlock's soft limits while homing
    /// (a joint whose potentiometer reads no number gets none).
    pub fn from_potentiometers(sample: &SensorSample, counts_per_rad: &[f32; JOINTS]) -> Self {
        Self {
            counts: core::array::from_fn(|j| {
                let count = sample.joint_counts.get(j).copied().unwrap_or(0);
                let pot = sample.joint_pots_rad.get(j).copied().unwrap_or(f32::NAN);
                let per_rad = counts_per_rad.get(j).copied().unwrap_or(0.0);
                let at_pot = f64::from(pot) * f64::from(per_rad);
                if at_pot.is_finite() && at_pot.abs() < f64::from(i32::MAX) {
                    count.wrapping_sub(libm::round(at_pot) as i32)
                } else {
                    0
                }
            }),
        }
    }

    /// `sample` as a counter zeroed at q = 0 would read it: its counts and
    /// its latched index counts less the offsets. Six subtractions: all that
    /// homing adds to the pick's period.
    #[inline]
    pub fn apply(&self, sample: &mut SensorSample) {
        for (count, offset) in sample.joint_counts.iter_mut().zip(self.counts) {
            *count = count.wrapping_sub(offset);
        }
    }
}

/// Where homing stands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HomingStage {
    /// Averaging the potentiometers, the arm held.
    Coarse,
    /// Turning the joints towards their index pulses.
    Seek,
    /// Going back to the power-on posture.
    Return,
    /// Holding it until the arm rests.
    Settle,
    /// Done: the offsets.
    Homed(HomedOffsets),
    /// Stopped on an error, the arm held where it was.
    Failed(HomingError),
}

/// One joint's reference: position relative to its power-on count, rad, and
/// speed, rad/s.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Reference {
    position_rad: f32,
    speed_rad_s: f32,
    target_rad: f32,
}

impl Reference {
    /// One step of `dt_s` towards the target, within the search's speed and
    /// acceleration; it stops on the target.
    fn advance(&mut self, dt_s: f32) {
        let error = self.target_rad - self.position_rad;
        let braking = libm::sqrtf(2.0 * SEARCH_ACCELERATION_RAD_S2 * error.abs());
        let desired = SEARCH_SPEED_RAD_S.min(braking).copysign(error);
        let step = SEARCH_ACCELERATION_RAD_S2 * dt_s;
        self.speed_rad_s += (desired - self.speed_rad_s).max(-step).min(step);
        self.position_rad += self.speed_rad_s * dt_s;
        if (self.target_rad - self.position_rad) * error <= 0.0 {
            self.position_rad = self.target_rad;
            self.speed_rad_s = 0.0;
        }
    }

    fn arrived(&self) -> bool {
        self.position_rad == self.target_rad && self.speed_rad_s == 0.0
    }
}

/// Homing at power-on: fed every sample until [`PowerOnHoming::stage`] is
/// `Homed` or `Failed`; each period's torques hold or move the arm.
#[derive(Debug, Clone)]
pub struct PowerOnHoming {
    joints: [JointHoming; JOINTS],
    specs: [JointHomingSpec; JOINTS],
    model: Puma560<f32>,
    stage: HomingStage,
    /// The counts of the first sample: the references are relative to them.
    start_counts: Option<[i32; JOINTS]>,
    /// The joint angles at `start_counts` as far as known (the first
    /// potentiometer reading, then their average), for the gravity torque.
    start_angle_rad: [f32; JOINTS],
    reference: [Reference; JOINTS],
    homed: [bool; JOINTS],
    observer: JointObserver,
    last_time_us: Option<u64>,
    /// When the current stage began (and, while seeking, when each
    /// joint's reference reached its end), s since the first sample.
    now_s: f32,
    stage_since_s: f32,
    search_end_since_s: [Option<f32>; JOINTS],
    rest_since_s: Option<f32>,
}

impl PowerOnHoming {
    /// Homing of the PUMA 560 whose counters read `counts_per_rad`.
    pub fn new(counts_per_rad: &[f32; JOINTS]) -> Result<Self, HomingError> {
        let specs = puma_homing_specs(counts_per_rad);
        let mut joints = [JointHoming::new(0, specs[0])?; JOINTS];
        for (j, (joint, spec)) in joints.iter_mut().zip(specs.iter()).enumerate() {
            *joint = JointHoming::new(j, *spec)?;
        }
        let model = Puma560::<f64>::new()
            .with_drive(DriveOptions {
                armature: true,
                friction: true,
            })
            .try_with_coulomb_smoothing(COULOMB_WIDTH_RAD_S)
            .map_err(|_| HomingError::BadSpec { joint: 0 })?
            .cast::<f32>();
        Ok(Self {
            joints,
            specs,
            model,
            stage: HomingStage::Coarse,
            start_counts: None,
            start_angle_rad: [0.0; JOINTS],
            reference: [Reference::default(); JOINTS],
            homed: [false; JOINTS],
            observer: JointObserver::new(OBSERVER_BANDWIDTH_RAD_S, OBSERVER_MAX_JUMP_RAD),
            last_time_us: None,
            now_s: 0.0,
            stage_since_s: 0.0,
            search_end_since_s: [None; JOINTS],
            rest_since_s: None,
        })
    }

    /// Where homing stands.
    pub fn stage(&self) -> HomingStage {
        self.stage
    }

    /// The offsets, once homed.
    pub fn offsets(&self) -> Option<HomedOffsets> {
        match self.stage {
            HomingStage::Homed(offsets) => Some(offsets),
            _ => None,
        }
    }

    /// The error homing stopped on, if it did.
    pub fn error(&self) -> Option<HomingError> {
        match self.stage {
            HomingStage::Failed(error) => Some(error),
            _ => None,
        }
    }

    /// One period: the torques for `sample`, N m.
    pub fn period(&mut self, sample: &SensorSample) -> [f32; JOINTS] {
        let dt_s = self.last_time_us.map_or(0.0, |last| {
            micros_to_seconds(sample.time_us.saturating_sub(last)).min(MAX_STEP_S)
        });
        self.last_time_us = Some(sample.time_us);
        self.now_s += dt_s;
        let first = self.start_counts.is_none();
        let start = *self.start_counts.get_or_insert(sample.joint_counts);
        if first {
            for (angle, pot) in self.start_angle_rad.iter_mut().zip(sample.joint_pots_rad) {
                if pot.is_finite() {
                    *angle = pot;
                }
            }
        }
        let q_relative = JointVector::<f32>::from_fn(|j, _| {
            let count = sample.joint_counts.get(j).copied().unwrap_or(0);
            let from = start.get(j).copied().unwrap_or(0);
            let per_rad = self.specs.get(j).map_or(1.0, |s| s.counts_per_rad);
            count.wrapping_sub(from) as f32 / per_rad
        });
        if self
            .observer
            .update(&q_relative, &JointVector::zeros(), dt_s)
            .is_err()
        {
            self.observer.restart();
            let _ = self
                .observer
                .update(&q_relative, &JointVector::zeros(), dt_s);
        }
        let qd = self.observer.qd();
        if let Err(error) = self.advance(sample, dt_s, &qd) {
            self.fail(error, &q_relative);
        }
        self.torque(&q_relative, &qd)
    }

    /// The stage's work for this sample.
    fn advance(
        &mut self,
        sample: &SensorSample,
        dt_s: f32,
        qd: &JointVector<f32>,
    ) -> Result<(), HomingError> {
        match self.stage {
            HomingStage::Coarse => {
                let mut all = true;
                for (j, joint) in self.joints.iter_mut().enumerate() {
                    let pot = sample.joint_pots_rad.get(j).copied().unwrap_or(f32::NAN);
                    let count = sample.joint_counts.get(j).copied().unwrap_or(0);
                    all &= joint.at_rest(pot, count)?;
                }
                if all {
                    self.start_seek();
                }
            }
            HomingStage::Seek => {
                for (j, joint) in self.joints.iter_mut().enumerate() {
                    let (Some(homed), Some(reference)) =
                        (self.homed.get_mut(j), self.reference.get_mut(j))
                    else {
                        continue;
                    };
                    if *homed {
                        continue;
                    }
                    let count = sample.joint_counts.get(j).copied().unwrap_or(0);
                    let index = sample.joint_index_counts.get(j).copied().flatten();
                    if joint.seeking(count, index)? {
                        *homed = true;
                        // Stop where the reference is.
                        reference.target_rad = reference.position_rad;
                        continue;
                    }
                    let end_since = self.search_end_since_s.get_mut(j);
                    if let Some(since) = end_since {
                        if reference.arrived() {
                            let at = *since.get_or_insert(self.now_s);
                            if self.now_s - at > STALL_LIMIT_S {
                                let per_rad = joint_spec(&self.specs, j).counts_per_rad;
                                let from = self
                                    .start_counts
                                    .and_then(|s| s.get(j).copied())
                                    .unwrap_or(count);
                                return Err(HomingError::IndexNotSeen {
                                    joint: j,
                                    travelled_rad: (count.wrapping_sub(from) as f32 / per_rad)
                                        .abs(),
                                });
                            }
                        }
                    }
                }
                if self.homed.iter().all(|h| *h) {
                    for reference in self.reference.iter_mut() {
                        reference.target_rad = 0.0;
                    }
                    self.enter(HomingStage::Return);
                }
            }
            HomingStage::Return => {
                if self.reference.iter().all(Reference::arrived) {
                    self.enter(HomingStage::Settle);
                }
            }
            HomingStage::Settle => {
                self.check_potentiometers(sample)?;
                let resting = qd.iter().all(|v| v.abs() <= REST_SPEED_RAD_S);
                self.rest_since_s = if resting {
                    Some(self.rest_since_s.unwrap_or(self.now_s))
                } else {
                    None
                };
                let rested = self
                    .rest_since_s
                    .is_some_and(|since| self.now_s - since >= SETTLE_S);
                if rested || self.now_s - self.stage_since_s > SETTLE_LIMIT_S {
                    self.stage = HomingStage::Homed(self.homed_offsets());
                }
            }
            HomingStage::Homed(_) | HomingStage::Failed(_) => {}
        }
        for reference in self.reference.iter_mut() {
            reference.advance(dt_s);
        }
        Ok(())
    }

    /// The coarse angles are known: the search starts, each joint towards
    /// the middle of its range.
    fn start_seek(&mut self) {
        let limits = *self.model.joint_limits();
        for j in 0..JOINTS {
            let from = self
                .start_counts
                .and_then(|s| s.get(j).copied())
                .unwrap_or(0);
            let Some(joint) = self.joints.get(j) else {
                continue;
            };
            let coarse = joint.coarse_angle(from).unwrap_or(0.0);
            if let Some(angle) = self.start_angle_rad.get_mut(j) {
                *angle = coarse;
            }
            let middle = 0.5 * (at(&limits.position_min, j) + at(&limits.position_max, j));
            let direction = if coarse <= middle { 1.0 } else { -1.0 };
            // Past the span, so that the joint's own travel says when the
            // search has failed.
            let span = joint_spec(&self.specs, j).search_span_rad;
            if let Some(reference) = self.reference.get_mut(j) {
                reference.target_rad = direction * 1.1 * span;
            }
        }
        self.enter(HomingStage::Seek);
    }

    fn enter(&mut self, stage: HomingStage) {
        self.stage = stage;
        self.stage_since_s = self.now_s;
    }

    /// Once homed, each potentiometer must agree with its joint's angle.
    fn check_potentiometers(&self, sample: &SensorSample) -> Result<(), HomingError> {
        for (j, joint) in self.joints.iter().enumerate() {
            let pot = sample.joint_pots_rad.get(j).copied().unwrap_or(f32::NAN);
            if !pot.is_finite() {
                return Err(HomingError::PotentiometerNotFinite { joint: j });
            }
            let count = sample.joint_counts.get(j).copied().unwrap_or(0);
            let angle = joint.angle(count).unwrap_or(pot);
            let disagreement_rad = pot - angle;
            if disagreement_rad.abs() > joint_spec(&self.specs, j).pot_tolerance_rad {
                return Err(HomingError::PotentiometerDisagrees {
                    joint: j,
                    disagreement_rad,
                });
            }
        }
        Ok(())
    }

    fn homed_offsets(&self) -> HomedOffsets {
        HomedOffsets {
            // Modulo 2^32 on purpose: the counters wrap the same way.
            counts: core::array::from_fn(|j| {
                self.joints
                    .get(j)
                    .and_then(JointHoming::offset_counts)
                    .map_or(0, |offset| offset as i32)
            }),
        }
    }

    /// Stops on `error`: every reference stands where its joint is.
    fn fail(&mut self, error: HomingError, q_relative: &JointVector<f32>) {
        for (reference, q) in self.reference.iter_mut().zip(q_relative.iter()) {
            *reference = Reference {
                position_rad: *q,
                speed_rad_s: 0.0,
                target_rad: *q,
            };
        }
        self.stage = HomingStage::Failed(error);
    }

    /// The law: spring and damper to the reference, gravity and friction
    /// fed forward, within the drives' headroom.
    fn torque(&self, q_relative: &JointVector<f32>, qd: &JointVector<f32>) -> [f32; JOINTS] {
        let q = JointVector::<f32>::from_fn(|j, _| {
            self.start_angle_rad.get(j).copied().unwrap_or(0.0) + at(q_relative, j)
        });
        let speed = JointVector::<f32>::from_fn(|j, _| {
            self.reference.get(j).map_or(0.0, |r| r.speed_rad_s)
        });
        let gravity = TaskSpaceModel::gravity_torque(&self.model, &q);
        let friction =
            TaskSpaceModel::friction_torque(&self.model, &speed) * FRICTION_FEED_FORWARD_SHARE;
        let limits = TaskSpaceModel::torque_limits(&self.model);
        core::array::from_fn(|j| {
            let reference = self.reference.get(j).copied().unwrap_or_default();
            let spring = STIFFNESS_NM.get(j).copied().unwrap_or(0.0)
                * (reference.position_rad - at(q_relative, j));
            let damping =
                DAMPING_NM_S.get(j).copied().unwrap_or(0.0) * (reference.speed_rad_s - at(qd, j));
            let value = at(&gravity, j) + at(&friction, j) + spring + damping;
            let max = at(&limits, j);
            let max = if max.is_finite() { max.abs() } else { 0.0 };
            if value.is_finite() {
                value.max(-max).min(max)
            } else {
                0.0
            }
        })
    }
}

/// Joint `j` of `v`, or 0.
fn at(v: &JointVector<f32>, j: usize) -> f32 {
    v.get(j).copied().unwrap_or(0.0)
}

fn joint_spec(specs: &[JointHomingSpec; JOINTS], j: usize) -> JointHomingSpec {
    specs.get(j).copied().unwrap_or(JointHomingSpec {
        grid: IndexGrid {
            pitch_rad: 1.0,
            phase_rad: 0.0,
        },
        pot_tolerance_rad: 0.0,
        counts_per_rad: 1.0,
        search_span_rad: 0.0,
    })
}

/// The telemetry that tells the host homing stopped, and why (the pick
/// never started: nothing but the fault and the link's count).
pub fn fault_telemetry(
    sample: &SensorSample,
    error: &HomingError,
    frames_rejected: u32,
) -> PickTelemetry {
    PickTelemetry {
        time_us: sample.time_us,
        phase: PickPhase::Faulted,
        fault: Some(fault_cause(error)),
        theta_rad: 0.0,
        omega_rad_s: 0.0,
        sigma_theta_rad: 0.0,
        sigma_omega_rad_s: 0.0,
        part_base_m: None,
        part_yaw_base_rad: 0.0,
        part_velocity_base_m_s: [0.0; 3],
        part_sigma_m: 0.0,
        tool_base_m: [0.0; 3],
        tool_reference_base_m: [0.0; 3],
        tool_yaw_rad: 0.0,
        tool_reference_yaw_rad: 0.0,
        frames_paired: 0,
        frames_unpaired: 0,
        saturated_ticks: 0,
        frames_rejected,
    }
}

/// The pick's fault cause for a homing error.
pub fn fault_cause(error: &HomingError) -> FaultCause {
    match error {
        HomingError::IndexNotSeen { .. } => FaultCause::HomingIndexNotSeen,
        HomingError::BadSpec { .. } => FaultCause::BadConfig,
        HomingError::PotentiometerNotFinite { .. }
        | HomingError::PotentiometerUnsteady { .. }
        | HomingError::PotentiometerDisagrees { .. } => FaultCause::HomingPotentiometer,
    }
}
