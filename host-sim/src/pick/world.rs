//! The simulated world of the full pick: a drawn workcell (camera, disc, part,
//! robot base: truth the controller never reads), the PUMA 560 plant, the disc
//! conveyor, the camera with its vision computer, and the gripper.
//!
//! The controller meets it only through the protocol: it is told the
//! [`CellConfig`] (nothing calibrated), reads [`SensorSample`]s and
//! [`CameraFeatureFrame`]s, and acts by [`ActuatorCommand`]s, one per control
//! period. Everything else here (the truth, the layout, the grasp) is for the
//! runner's records and the tests.
//!
//! The part's grasp point is the mean of its features (the top centre of a
//! flat-topped part) and its yaw the direction from feature 0 to feature 1 (the
//! contract's part pose); on the disc it moves by the paper's Eq 1,
//! `p_base = Rz(yaw) Rz(theta) p_rotating + T`. Once grasped it is fixed to the
//! flange; released, it stays where the gripper opened (no falling model).

use std::f64::consts::{PI, TAU};

use anyhow::{anyhow, bail, Context, Result};
use nalgebra::{Isometry3, Point3, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use shared::fusion::CounterWidth;
use shared::protocol::{
    ActuatorCommand, CameraFeatureFrame, CellConfig, GripperCommand, SensorSample, JOINTS,
};
use shared::robot::JointVector;

use super::camera_sim::{CameraSim, SceneMarks};
use super::record::CellLayout;
use super::scenario::PickExperiment;
use crate::workcell::generator::DISC_RADIUS_M;
use crate::workcell::scenario::{DiscPlacement, FeatureHeights};
use crate::workcell::{random_workcell, Scenario, Workcell};
use crate::world::conveyor::{Conveyor, ConveyorProfile, ConveyorStop, MissedBurst, SpeedRamp};
use crate::world::gripper::{try_grasp, GraspTolerance};
use crate::world::plant::{JointEncoders, RobotPlant};

/// The drop-off: this far from the base axis, opposite the disc, this high.
pub const DROP_OFF_DISTANCE_M: f64 = 0.55;
pub const DROP_OFF_HEIGHT_M: f64 = 0.3;
/// Distance from the base axis at which a stopped disc leaves the part, m.
pub const STOP_REACH_M: f64 = 0.6;
/// Azimuth between the disc centre and the drop-off, rad (100 degrees).
pub const DROP_OFF_TURN_RAD: f64 = 100.0 * PI / 180.0;
/// The unknown tool payload sits halfway down the gripper, on the flange's axis.
const TOOL_PAYLOAD_COM_FLANGE_M: [f64; 3] = [0.0, 0.0, shared::app::tool::TOOL_LENGTH_M / 2.0];
/// Telemetry period the world asks for, seconds (50 Hz).
const TELEMETRY_PERIOD_S: f64 = 0.02;

/// A drive given no new command holds the last one this long, then brakes.
pub const DRIVE_WATCHDOG_S: f64 = 0.005;
/// The brake's viscous coefficient, N m s/rad (it also holds the arm against
/// gravity, as a holding brake does).
const BRAKE_DAMPING_NM_S: f64 = 20.0;
/// Step of the search for the stop instant, seconds; refined by bisection.
const STOP_SEARCH_STEP_S: f64 = 0.01;

/// The true state of the world at one instant, base frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldTruth {
    pub time_s: f64,
    /// The part's grasp point (mean of its features), yaw and velocity.
    pub part_base_m: [f64; 3],
    pub part_yaw_rad: f64,
    pub part_velocity_base_m_s: [f64; 3],
    pub part_held: bool,
    /// The gripper's grasp point and yaw from the plant's true joint angles.
    pub tool_base_m: [f64; 3],
    pub tool_yaw_rad: f64,
    /// Conveyor angle (unwrapped, 0 at t = 0) and speed.
    pub theta_rad: f64,
    pub omega_rad_s: f64,
    pub q_rad: [f64; JOINTS],
    pub qd_rad_s: [f64; JOINTS],
    /// The torque the drives last delivered (after saturation).
    pub tau_nm: [f64; JOINTS],
}

/// What happened when the gripper closed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GraspAttempt {
    pub t_s: f64,
    pub succeeded: bool,
    /// Gripper grasp point minus the part's, base frame.
    pub position_error_base_m: [f64; 3],
    pub horizontal_error_m: f64,
    pub vertical_error_m: f64,
    /// Yaw error modulo pi (two fingers).
    pub yaw_error_rad: f64,
    pub relative_speed_m_s: f64,
}

/// Where the part is.
#[derive(Debug, Clone, PartialEq)]
enum PartState {
    /// On the disc, its features fixed in the rotating frame.
    OnDisc,
    /// In the gripper, its features fixed in the flange frame.
    Held { features_flange: Vec<Vector3<f64>> },
    /// Put down where the gripper opened.
    Placed { features_base: Vec<Vector3<f64>> },
}

/// The simulated workcell.
#[derive(Debug)]
pub struct World {
    experiment: PickExperiment,
    workcell: Workcell,
    plant: RobotPlant,
    encoders: JointEncoders,
    conveyor: Conveyor,
    camera: CameraSim,
    tolerance: GraspTolerance,
    control_period_s: f64,
    ticks: u64,
    sensor_seq: u32,
    part: PartState,
    gripper_closed: bool,
    grasp: Option<GraspAttempt>,
    placed_base: Option<[f64; 3]>,
    last_tau: JointVector<f64>,
    drop_off_base: Vector3<f64>,
    /// The camera was knocked to its new pose (the bump fault has happened).
    camera_bumped: bool,
    /// Consecutive periods without a command (a stall), for the drives' watchdog.
    unattended_ticks: u64,
}

fn array(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

fn mean(points: &[Vector3<f64>]) -> Vector3<f64> {
    let count = points.len().max(1) as f64;
    points.iter().fold(Vector3::zeros(), |sum, p| sum + p) / count
}

/// Yaw of the direction feature 0 -> feature 1 in the XY-plane (the contract's part yaw).
fn part_yaw(features: &[Vector3<f64>]) -> f64 {
    match (features.first(), features.get(1)) {
        (Some(a), Some(b)) => (b.y - a.y).atan2(b.x - a.x),
        _ => 0.0,
    }
}

/// The recorder's scenario with this experiment's part and camera tilt: the
/// workcell generator's ranges (Section 5's setup) do the rest.
fn workcell_scenario(experiment: &PickExperiment) -> Scenario {
    let [low, high] = experiment.camera.tilt_deg;
    Scenario {
        name: experiment.name.clone(),
        pixel_sigma_px: experiment.camera.pixel_sigma_px,
        dropout_probability: experiment.camera.dropout_probability,
        outlier_probability: experiment.camera.outlier_probability,
        part_feature_count: usize::from(experiment.part.feature_count),
        feature_heights: FeatureHeights::FlatTop {
            min_m: experiment.part.height_m,
            max_m: experiment.part.height_m,
        },
        camera_tilt_deg: (low, high),
        disc_placement: DiscPlacement {
            distance_from_base_axis_m: (
                experiment.cell.disc_distance_m[0],
                experiment.cell.disc_distance_m[1],
            ),
            below_shoulder_m: (
                experiment.cell.disc_below_shoulder_m[0],
                experiment.cell.disc_below_shoulder_m[1],
            ),
            azimuth_deg: (
                experiment.cell.disc_azimuth_deg[0],
                experiment.cell.disc_azimuth_deg[1],
            ),
        },
        ..Scenario::paper()
    }
}

/// The first instant at or after `after_s` from which decelerating at
/// `deceleration` leaves the disc at rest with angle `target` (mod 2 pi). The rest
/// angle grows monotonically while the ripple's acceleration stays below the
/// deceleration, so a scan for the crossing plus bisection finds it.
fn stop_instant_for_rest_angle(
    conveyor: &Conveyor,
    after_s: f64,
    deceleration: f64,
    target: f64,
    min_speed_rad_s: f64,
) -> Result<f64> {
    let turn_index =
        |t: f64| ((conveyor.rest_angle_if_stopped_at(t, deceleration) - target) / TAU).floor();
    let horizon_s = after_s + 2.0 * TAU / min_speed_rad_s + 1.0;
    let mut t0 = after_s;
    let k0 = turn_index(t0);
    let at_target = |t: f64| {
        let d = (conveyor.rest_angle_if_stopped_at(t, deceleration) - target).rem_euclid(TAU);
        d.min(TAU - d) < 1e-12
    };
    if at_target(t0) {
        return Ok(t0);
    }
    while t0 < horizon_s {
        let t1 = t0 + STOP_SEARCH_STEP_S;
        if turn_index(t1) != k0 {
            let (mut low, mut high) = (t0, t1);
            for _ in 0..80 {
                let mid = 0.5 * (low + high);
                if turn_index(mid) == k0 {
                    low = mid;
                } else {
                    high = mid;
                }
            }
            return Ok(high);
        }
        t0 = t1;
    }
    bail!("no conveyor stop instant within {horizon_s:.1} s puts the part in front of the robot")
}

impl World {
    pub fn new(experiment: &PickExperiment, seed: u64) -> Result<Self> {
        experiment.validate().context("pick experiment")?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (workcell, _) = random_workcell(&mut rng, &workcell_scenario(experiment))
            .map_err(|e| anyhow!("{e}"))?;
        let error = experiment.robot.link_mass_error;
        let link_mass_scale: [f64; 6] =
            core::array::from_fn(|_| 1.0 - error + 2.0 * error * rng.random::<f64>());
        let camera_seed: u64 = rng.random();
        let width = match experiment.conveyor.counter_bits {
            16 => CounterWidth::Bits16,
            _ => CounterWidth::Bits32,
        };
        let start_raw = match experiment.faults.counter_counts_before_wrap {
            // Still draw, so the fault changes nothing else of the world.
            Some(before_wrap) => {
                let _ = rng.random::<u32>();
                width.max().saturating_sub(before_wrap)
            }
            None => rng.random::<u32>() & width.max(),
        };

        let plant = RobotPlant::new(
            link_mass_scale,
            experiment.robot.payload_kg,
            Vector3::from(TOOL_PAYLOAD_COM_FLANGE_M),
            shared::planning::ready_posture(),
        )?;
        let gear = shared::robot::Puma560::<f64>::new();
        let mut counts_per_rad = [0.0; 6];
        for (c, drive) in counts_per_rad.iter_mut().zip(gear.drive_params().iter()) {
            *c = experiment.robot.joint_counts_per_motor_rev * drive.gear_ratio.abs() / TAU;
        }
        let encoders = JointEncoders { counts_per_rad };

        let settings = experiment.conveyor;
        let mut conveyor = Conveyor::new(
            ConveyorProfile {
                speed_rad_s: settings.speed_rad_s,
                ripple_fraction: settings.ripple_fraction,
                ripple_hz: settings.ripple_hz,
            },
            settings.counts_per_rev,
            width,
            start_raw,
        )?;
        // A disc that does not turn needs no stop: the setting is then moot.
        if let (Some(stop), true) = (settings.stop, settings.speed_rad_s != 0.0) {
            if settings.ripple_fraction * settings.speed_rad_s.abs() * TAU * settings.ripple_hz
                >= stop.deceleration_rad_s2
            {
                bail!("conveyor.stop.deceleration_rad_s2 must exceed the ripple's acceleration");
            }
            // The part's azimuth in the rotating frame, and the robot's in the disc frame.
            let part_rotating = mean(&workcell.features_rotating);
            let robot_disc = workcell.disc_from_base(&Vector3::new(
                0.0,
                0.0,
                workcell.base_from_disc_translation_m.z,
            ));
            // On the part's circle, the point at a comfortable reach from the base
            // axis (the nearest point when the circle stays further away): the
            // operator stops the disc with the part in front of the robot.
            let (d, r) = (robot_disc.xy().norm(), part_rotating.xy().norm());
            let cos_off = ((d * d + r * r - STOP_REACH_M * STOP_REACH_M) / (2.0 * d * r.max(1e-9)))
                .clamp(-1.0, 1.0);
            let target = robot_disc.y.atan2(robot_disc.x) + cos_off.acos()
                - part_rotating.y.atan2(part_rotating.x);
            let min_speed = settings.speed_rad_s.abs() * (1.0 - settings.ripple_fraction);
            let start_s = stop_instant_for_rest_angle(
                &conveyor,
                stop.after_s,
                stop.deceleration_rad_s2,
                target,
                min_speed,
            )?;
            conveyor = conveyor.with_stop(ConveyorStop {
                start_s,
                deceleration_rad_s2: stop.deceleration_rad_s2,
            })?;
        }

        if let Some(change) = experiment.faults.conveyor_change {
            conveyor = conveyor.with_speed_change(SpeedRamp {
                start_s: change.at_s,
                target_rad_s: change.speed_rad_s,
                acceleration_rad_s2: change.acceleration_rad_s2,
            })?;
        }
        if let Some(missed) = experiment.faults.missed_counts {
            conveyor = conveyor.with_missed_counts(MissedBurst {
                at_s: missed.at_s,
                counts: missed.counts,
                instant: missed.instant,
            })?;
        }

        let camera = CameraSim::new(workcell.camera.clone(), &experiment.camera, camera_seed)?;
        // Beside the disc, 100 degrees round from it towards the robot's front
        // (+X), well inside joint 1's range and clear of the disc's footprint.
        let disc = workcell.base_from_disc_translation_m;
        let disc_azimuth = disc.y.atan2(disc.x);
        let away = disc_azimuth - DROP_OFF_TURN_RAD.copysign(disc_azimuth);
        let drop_off_base = Vector3::new(
            DROP_OFF_DISTANCE_M * away.cos(),
            DROP_OFF_DISTANCE_M * away.sin(),
            DROP_OFF_HEIGHT_M,
        );
        Ok(Self {
            experiment: experiment.clone(),
            tolerance: experiment.grasp_tolerance(),
            control_period_s: 1.0 / (experiment.robot.control_rate_hz),
            workcell,
            plant,
            encoders,
            conveyor,
            camera,
            ticks: 0,
            sensor_seq: 0,
            part: PartState::OnDisc,
            gripper_closed: false,
            grasp: None,
            placed_base: None,
            last_tau: JointVector::zeros(),
            drop_off_base,
            camera_bumped: false,
            unattended_ticks: 0,
        })
    }

    /// What an integrator tells the controller: intrinsics (A5), L, the encoders'
    /// scales, the drop-off and (experiment 2 only) the disc surface's height.
    /// Nothing calibrated: no camera pose, no base pose, no part.
    pub fn cell_config(&self) -> CellConfig {
        let intrinsics = self.workcell.camera.intrinsics;
        let rate = self.experiment.robot.control_rate_hz;
        CellConfig {
            image_width_px: u16::try_from(intrinsics.width).unwrap_or(u16::MAX),
            image_height_px: u16::try_from(intrinsics.height).unwrap_or(u16::MAX),
            f_px: intrinsics.f_px as f32,
            cx_px: intrinsics.cx as f32,
            cy_px: intrinsics.cy as f32,
            pixel_sigma_px: self.experiment.camera.pixel_sigma_px as f32,
            reference_radius_m: self.workcell.reference_radius_m as f32,
            part_feature_count: self.experiment.part.feature_count,
            conveyor_counts_per_rev: self.conveyor.counts_per_rev(),
            conveyor_counter_bits: self.conveyor.width().bits(),
            joint_counts_per_rad: self.encoders.counts_per_rad.map(|c| c as f32),
            disc_height_in_base_m: self
                .experiment
                .disc_height_known
                .then_some(self.workcell.base_from_disc_translation_m.z as f32),
            drop_off_base_m: array(&self.drop_off_base).map(|x| x as f32),
            camera_period_ms: self.experiment.camera.frame_period_ms,
            telemetry_period_ticks: (rate * TELEMETRY_PERIOD_S).round().clamp(1.0, 65_535.0) as u16,
        }
    }

    pub fn time_s(&self) -> f64 {
        self.ticks as f64 * self.control_period_s
    }

    pub fn control_period_s(&self) -> f64 {
        self.control_period_s
    }

    pub fn experiment(&self) -> &PickExperiment {
        &self.experiment
    }

    pub fn conveyor(&self) -> &Conveyor {
        &self.conveyor
    }

    pub fn plant(&self) -> &RobotPlant {
        &self.plant
    }

    pub fn camera(&self) -> &CameraSim {
        &self.camera
    }

    /// Encoder readings now: joint counts from the plant's true angles, the
    /// conveyor's raw (wrapping) counter.
    pub fn sensor_sample(&mut self) -> SensorSample {
        let t = self.time_s();
        let sample = SensorSample {
            seq: self.sensor_seq,
            time_us: (t * 1e6).round() as u64,
            joint_counts: self.encoders.read(&self.plant.state().q),
            conveyor_counts: self.conveyor.encoder_raw(t),
            part_in_gripper: matches!(self.part, PartState::Held { .. }),
        };
        self.sensor_seq = self.sensor_seq.wrapping_add(1);
        sample
    }

    /// Camera frames that have arrived by now (none while the vision link is down:
    /// those are lost).
    pub fn due_camera_frames(&mut self) -> Vec<CameraFeatureFrame> {
        let now = self.time_s();
        let frames = self.camera.due_frames(now);
        match self.experiment.faults.vision_outage {
            Some(outage) if outage.contains(now) => Vec::new(),
            _ => frames,
        }
    }

    /// The control loop is stalled now (the control-stall fault): no sensor
    /// sample is read and no command comes; see [`World::apply_unattended`].
    pub fn control_stalled(&self) -> bool {
        self.experiment
            .faults
            .control_stall
            .is_some_and(|stall| stall.contains(self.time_s()))
    }

    /// One control period without a command: the drives hold the last torque
    /// for `DRIVE_WATCHDOG_S`, then their watchdog brakes each joint (viscous,
    /// holding the arm against gravity) until commands come back.
    pub fn apply_unattended(&mut self) -> Result<()> {
        self.unattended_ticks += 1;
        let held_s = self.unattended_ticks as f64 * self.control_period_s;
        let substeps = self.experiment.robot.plant_substeps;
        let dt = self.control_period_s / f64::from(substeps);
        for _ in 0..substeps {
            let tau = if held_s <= DRIVE_WATCHDOG_S {
                self.last_tau
            } else {
                let state = self.plant.state();
                self.plant.model().gravity_torque(&state.q) - state.qd * BRAKE_DAMPING_NM_S
            };
            self.plant
                .step(&tau, dt)
                .with_context(|| format!("plant (braked) at t = {:.3} s", self.time_s()))?;
        }
        self.ticks += 1;
        Ok(())
    }

    /// Exposes frame `trigger_id` of `scene`, the marks at `time_s` (kept
    /// from then: a free-running plant's camera, triggered at an instant the
    /// trigger event names after the fact).
    pub fn expose_camera(&mut self, trigger_id: u32, time_s: f64, scene: &SceneMarks) {
        self.camera.expose(trigger_id, time_s, scene);
    }

    /// Knocks the camera to its new pose once the bump's time has come.
    fn bump_camera_if_due(&mut self) {
        let Some(bump) = self.experiment.faults.camera_bump else {
            return;
        };
        if self.camera_bumped || self.time_s() < bump.at_s {
            return;
        }
        self.camera_bumped = true;
        let mut camera = self.camera.camera().clone();
        let x_axis = camera.disc_from_camera_rotation.column(0).into_owned();
        let turn = nalgebra::Rotation3::from_axis_angle(
            &nalgebra::Unit::new_normalize(x_axis),
            bump.rotation_deg.to_radians(),
        );
        camera.disc_from_camera_rotation = turn.matrix() * camera.disc_from_camera_rotation;
        camera.optical_centre_disc += x_axis * bump.shift_m;
        self.camera.move_to(camera);
    }

    /// One control period under `command`: the camera exposes now if triggered,
    /// the gripper acts now, then the plant integrates the delivered torque.
    pub fn apply(&mut self, command: &ActuatorCommand) -> Result<()> {
        self.unattended_ticks = 0;
        self.bump_camera_if_due();
        if let Some(trigger_id) = command.camera_trigger {
            let scene = self.scene_marks();
            let now = self.time_s();
            self.camera.expose(trigger_id, now, &scene);
        }
        match (command.gripper, self.gripper_closed) {
            (GripperCommand::Close, false) => {
                self.gripper_closed = true;
                self.close_gripper()?;
            }
            (GripperCommand::Open, true) => {
                self.gripper_closed = false;
                self.open_gripper()?;
            }
            _ => {}
        }
        let commanded =
            JointVector::from_iterator(command.joint_torque_nm.iter().map(|&t| f64::from(t)));
        let limit = self.plant.model().joint_limits().torque_max;
        self.last_tau = commanded.zip_map(&limit, |t, max| {
            if t.is_finite() {
                t.clamp(-max, max)
            } else {
                0.0
            }
        });
        let substeps = self.experiment.robot.plant_substeps;
        let dt = self.control_period_s / f64::from(substeps);
        for _ in 0..substeps {
            self.plant
                .step(&commanded, dt)
                .with_context(|| format!("plant at t = {:.3} s", self.time_s()))?;
        }
        self.ticks += 1;
        Ok(())
    }

    fn flange_pose(&self) -> Isometry3<f64> {
        self.plant.model().forward_kinematics(&self.plant.state().q)
    }

    /// The gripper's grasp point and its velocity (central difference along qd).
    fn tool_point_and_velocity(&self) -> (Vector3<f64>, Vector3<f64>) {
        let state = self.plant.state();
        let model = self.plant.model();
        let h = 1e-6;
        let at =
            |q: &JointVector<f64>| shared::app::tool::tool_point_base(&model.forward_kinematics(q));
        let velocity = (at(&(state.q + state.qd * h)) - at(&(state.q - state.qd * h))) / (2.0 * h);
        (at(&state.q), velocity)
    }

    fn tool_yaw(&self) -> f64 {
        let x = self.flange_pose().rotation * Vector3::x();
        x.y.atan2(x.x)
    }

    /// The part's features in the base frame now.
    pub fn part_features_base(&self) -> Vec<Vector3<f64>> {
        match &self.part {
            PartState::OnDisc => {
                let theta = self.conveyor.theta(self.time_s());
                self.workcell
                    .features_rotating
                    .iter()
                    .map(|p| {
                        self.workcell
                            .base_from_disc(&Workcell::disc_from_rotating(theta, p))
                    })
                    .collect()
            }
            PartState::Held { features_flange } => {
                let pose = self.flange_pose();
                features_flange
                    .iter()
                    .map(|p| (pose * Point3::from(*p)).coords)
                    .collect()
            }
            PartState::Placed { features_base } => features_base.clone(),
        }
    }

    fn part_velocity_base(&self, grasp_point: &Vector3<f64>) -> Vector3<f64> {
        match &self.part {
            PartState::OnDisc => {
                // Rigid rotation about the disc's vertical axis (Eq 1 differentiated).
                let omega = self.conveyor.omega(self.time_s());
                Vector3::new(0.0, 0.0, omega)
                    .cross(&(grasp_point - self.workcell.base_from_disc_translation_m))
            }
            PartState::Held { .. } => self.tool_point_and_velocity().1,
            PartState::Placed { .. } => Vector3::zeros(),
        }
    }

    /// Where the camera's marks are now (a free-running plant keeps them for
    /// a trigger that names this instant later).
    pub fn scene_marks(&self) -> SceneMarks {
        let theta = self.conveyor.theta(self.time_s());
        let [first, second] = shared::app::tool::effector_marks_base(&self.flange_pose());
        SceneMarks {
            centre_disc: Vector3::zeros(),
            reference_disc: self.workcell.reference_disc(theta),
            part_disc: self
                .part_features_base()
                .iter()
                .map(|p| self.workcell.disc_from_base(p))
                .collect(),
            effector_disc: [
                self.workcell.disc_from_base(&first),
                self.workcell.disc_from_base(&second),
            ],
        }
    }

    /// Judges the one grasp of the run. A miss knocks the part: the attempt is
    /// final and later closes do nothing.
    fn close_gripper(&mut self) -> Result<()> {
        if self.grasp.is_some() || self.part != PartState::OnDisc {
            return Ok(());
        }
        let features = self.part_features_base();
        let grasp_point = mean(&features);
        let part_velocity = self.part_velocity_base(&grasp_point);
        let (tool, tool_velocity) = self.tool_point_and_velocity();
        let outcome = try_grasp(
            &self.tolerance,
            &tool,
            &tool_velocity,
            self.tool_yaw(),
            &grasp_point,
            &part_velocity,
            part_yaw(&features),
        );
        let errors = outcome.errors();
        self.grasp = Some(GraspAttempt {
            t_s: self.time_s(),
            succeeded: outcome.succeeded(),
            position_error_base_m: array(&(tool - grasp_point)),
            horizontal_error_m: errors.horizontal_error_m,
            vertical_error_m: errors.vertical_error_m,
            yaw_error_rad: errors.yaw_error_rad,
            relative_speed_m_s: errors.relative_speed_m_s,
        });
        if outcome.succeeded() {
            let flange_from_base = self.flange_pose().inverse();
            let features_flange: Vec<Vector3<f64>> = features
                .iter()
                .map(|p| (flange_from_base * Point3::from(*p)).coords)
                .collect();
            // The part's centre of mass: half its height below the grasp point.
            let part_com_base =
                grasp_point - Vector3::new(0.0, 0.0, self.experiment.part.height_m / 2.0);
            let part_com_flange = (flange_from_base * Point3::from(part_com_base)).coords;
            let tool_kg = self.experiment.robot.payload_kg;
            let part_kg = self.experiment.part.mass_kg;
            let total_kg = tool_kg + part_kg;
            let com_flange = if total_kg > 0.0 {
                (Vector3::from(TOOL_PAYLOAD_COM_FLANGE_M) * tool_kg + part_com_flange * part_kg)
                    / total_kg
            } else {
                Vector3::zeros()
            };
            self.plant.set_payload(total_kg, com_flange)?;
            self.part = PartState::Held { features_flange };
        }
        Ok(())
    }

    /// Releases a held part where it is; the arm carries the tool alone again.
    fn open_gripper(&mut self) -> Result<()> {
        if let PartState::Held { .. } = self.part {
            let features_base = self.part_features_base();
            self.placed_base = Some(array(&mean(&features_base)));
            self.part = PartState::Placed { features_base };
            self.plant.set_payload(
                self.experiment.robot.payload_kg,
                Vector3::from(TOOL_PAYLOAD_COM_FLANGE_M),
            )?;
        }
        Ok(())
    }

    /// The true state now.
    pub fn truth(&self) -> WorldTruth {
        let t = self.time_s();
        let features = self.part_features_base();
        let grasp_point = mean(&features);
        let state = self.plant.state();
        let (tool, _) = self.tool_point_and_velocity();
        WorldTruth {
            time_s: t,
            part_base_m: array(&grasp_point),
            part_yaw_rad: part_yaw(&features),
            part_velocity_base_m_s: array(&self.part_velocity_base(&grasp_point)),
            part_held: matches!(self.part, PartState::Held { .. }),
            tool_base_m: array(&tool),
            tool_yaw_rad: self.tool_yaw(),
            theta_rad: self.conveyor.theta(t),
            omega_rad_s: self.conveyor.omega(t),
            q_rad: state.q.into(),
            qd_rad_s: state.qd.into(),
            tau_nm: self.last_tau.into(),
        }
    }

    pub fn grasp(&self) -> Option<GraspAttempt> {
        self.grasp
    }

    pub fn placed_position_base(&self) -> Option<[f64; 3]> {
        self.placed_base
    }

    pub fn drop_off_base(&self) -> [f64; 3] {
        array(&self.drop_off_base)
    }

    /// The fixed geometry for the top view, base frame.
    pub fn layout(&self) -> CellLayout {
        CellLayout {
            disc_centre_base_m: array(&self.workcell.base_from_disc_translation_m),
            disc_radius_m: DISC_RADIUS_M,
            camera_centre_base_m: array(
                &self
                    .workcell
                    .base_from_disc(&self.workcell.camera.optical_centre_disc),
            ),
            drop_off_base_m: array(&self.drop_off_base),
        }
    }

    /// The drawn workcell: the truth the controller's calibration is compared with.
    pub fn workcell(&self) -> &Workcell {
        &self.workcell
    }

    /// Moves the clock to `ticks` periods without integrating the plant (tests
    /// that need the disc somewhere else).
    #[cfg(test)]
    fn set_ticks(&mut self, ticks: u64) {
        self.ticks = ticks;
    }

    /// Puts the arm at `q` moving at `qd` (tests that need the gripper somewhere).
    #[cfg(test)]
    fn set_arm(&mut self, q: JointVector<f64>, qd: JointVector<f64>) {
        self.plant
            .set_state(crate::world::plant::JointState { q, qd });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pick::scenario::PickScenarioFile;
    use shared::planning::{gripper_down_rotation, solve_ik, IkConfig};

    fn experiment(name: &str) -> PickExperiment {
        PickScenarioFile::default_experiment(name).unwrap()
    }

    /// A quick stop: the part is in front of the robot within a few seconds.
    fn quick_stop() -> PickExperiment {
        let mut e = experiment("experiment-1");
        e.conveyor.speed_rad_s = 2.0;
        e.conveyor.stop = Some(super::super::scenario::StopSettings {
            after_s: 0.0,
            deceleration_rad_s2: 4.0,
        });
        e
    }

    fn command(tau: &JointVector<f64>, gripper: GripperCommand) -> ActuatorCommand {
        ActuatorCommand {
            seq: 0,
            joint_torque_nm: core::array::from_fn(|i| tau[i] as f32),
            gripper,
            camera_trigger: None,
        }
    }

    fn hold(world: &World) -> ActuatorCommand {
        let tau = world
            .plant()
            .model()
            .gravity_torque(&world.plant().state().q);
        command(&tau, GripperCommand::Open)
    }

    #[test]
    fn the_disc_stops_with_the_part_in_front_of_the_robot() {
        for (seed, speed) in [(1, 2.0), (2, -2.0), (3, 0.5)] {
            let mut e = quick_stop();
            e.conveyor.speed_rad_s = speed;
            let mut world = World::new(&e, seed).unwrap();
            let stop = world.conveyor().stop().unwrap();
            assert!(stop.start_s >= 0.0 && stop.start_s < 2.0 * TAU / speed.abs() + 1.0);
            world.set_ticks(40_000);
            let part = Vector3::from(world.truth().part_base_m);
            let disc = world.workcell().base_from_disc_translation_m;
            // At the comfortable reach, or as near it as the part's circle comes.
            let (d, r) = (disc.xy().norm(), (part - disc).xy().norm());
            let wanted = STOP_REACH_M.clamp((d - r).abs(), d + r);
            let quantum = TAU / f64::from(e.conveyor.counts_per_rev);
            assert!(
                (part.xy().norm() - wanted).abs() < 2.0 * r * quantum + 1e-9,
                "seed {seed}: part {} m from the base axis, wanted {wanted}",
                part.xy().norm()
            );
            assert_eq!(world.truth().omega_rad_s, 0.0);
            assert!(Vector3::from(world.truth().part_velocity_base_m_s).norm() < 1e-12);
        }
    }

    #[test]
    fn every_default_experiment_builds_and_stops_after_calibration() {
        let file = PickScenarioFile::embedded_default().unwrap();
        for e in &file.experiment {
            for seed in 0..4 {
                let world = World::new(e, seed).unwrap();
                match (e.conveyor.stop, world.conveyor().stop()) {
                    (Some(asked), Some(chosen)) => {
                        // Within one revolution (plus margin) of the earliest instant.
                        assert!(chosen.start_s >= asked.after_s);
                        assert!(chosen.start_s < asked.after_s + TAU / 0.5 + 0.1);
                    }
                    (None, None) => {}
                    other => panic!("{}: stop {other:?}", e.name),
                }
            }
        }
        // Same seed, same world.
        let e = experiment("turning");
        let (a, b) = (World::new(&e, 9).unwrap(), World::new(&e, 9).unwrap());
        assert_eq!(a.workcell(), b.workcell());
        assert_eq!(a.cell_config(), b.cell_config());
    }

    #[test]
    fn gravity_compensation_holds_the_arm_still_for_two_seconds() {
        // The wire carries f32 torques: their rounding (1e-7 relative), with no
        // static friction at rest (Coulomb is smoothed), lets the arm creep by
        // about 1e-3 rad in 2 s; f64 commands hold it to 1e-6 (plant's own test).
        let mut world = World::new(&experiment("experiment-1"), 5).unwrap();
        let q0 = world.truth().q_rad;
        let tool0 = Vector3::from(world.truth().tool_base_m);
        for _ in 0..2000 {
            let c = hold(&world);
            world.apply(&c).unwrap();
        }
        let q = world.truth().q_rad;
        for (a, b) in q.iter().zip(q0.iter()) {
            assert!((a - b).abs() < 4e-3, "{q:?} vs {q0:?}");
        }
        let tool_drift = (Vector3::from(world.truth().tool_base_m) - tool0).norm();
        assert!(tool_drift < 2e-3, "{tool_drift}");
        // Without compensation the same arm falls by far more.
        let mut falling = World::new(&experiment("experiment-1"), 5).unwrap();
        for _ in 0..200 {
            falling
                .apply(&command(&JointVector::zeros(), GripperCommand::Open))
                .unwrap();
        }
        let fall = Vector3::from(falling.truth().tool_base_m) - tool0;
        assert!(fall.norm() > 0.01, "{fall}");
        assert!((world.time_s() - 2.0).abs() < 1e-9);
        assert_eq!(world.plant().saturations(), 0);
        let sample = world.sensor_sample();
        assert_eq!(sample.seq, 0);
        assert_eq!(world.sensor_sample().seq, 1);
        assert_eq!(sample.time_us, 2_000_000);
    }

    #[test]
    fn the_cell_config_carries_nothing_calibrated() {
        let world = World::new(&experiment("experiment-1"), 6).unwrap();
        let config = world.cell_config();
        assert_eq!(config.disc_height_in_base_m, None);
        assert_eq!(config.conveyor_counter_bits, 16);
        assert_eq!(config.part_feature_count, 3);
        assert_eq!(config.camera_period_ms, 200);
        // The encoders: the controller's (count + 0.5) / counts_per_rad recovers q.
        let mut world = world;
        let sample = world.sensor_sample();
        let q = world.truth().q_rad;
        for ((count, per_rad), angle) in sample
            .joint_counts
            .iter()
            .zip(config.joint_counts_per_rad.iter())
            .zip(q.iter())
        {
            let back = (f64::from(*count) + 0.5) / f64::from(*per_rad);
            assert!((back - angle).abs() <= 0.5 / f64::from(*per_rad) + 1e-6);
        }
        let known = World::new(&experiment("experiment-2-4cm"), 6).unwrap();
        let height = known.cell_config().disc_height_in_base_m.unwrap();
        assert!((f64::from(height) - known.workcell().base_from_disc_translation_m.z).abs() < 1e-6);
        // Drop-off 100 degrees round from the disc, towards the robot's front.
        let layout = known.layout();
        let [dx, dy, _] = layout.disc_centre_base_m;
        let [ox, oy, oz] = layout.drop_off_base_m;
        let between = (dx * ox + dy * oy) / (dx.hypot(dy) * ox.hypot(oy));
        assert!((between - DROP_OFF_TURN_RAD.cos()).abs() < 1e-9);
        assert!(oy.atan2(ox).abs() <= dy.atan2(dx).abs().max(DROP_OFF_TURN_RAD) + 1e-9);
        assert!((ox.hypot(oy) - DROP_OFF_DISTANCE_M).abs() < 1e-12 && oz == DROP_OFF_HEIGHT_M);
    }

    #[test]
    fn a_close_far_from_the_part_misses_and_is_final() {
        let mut world = World::new(&experiment("experiment-1"), 7).unwrap();
        let mut c = hold(&world);
        c.gripper = GripperCommand::Close;
        world.apply(&c).unwrap();
        let attempt = world.grasp().unwrap();
        assert!(!attempt.succeeded);
        assert!(attempt.horizontal_error_m > 0.05 || attempt.vertical_error_m > 0.05);
        assert!(!world.truth().part_held);
        // Open and close again: the knocked part is not grasped later.
        world.apply(&hold(&world)).unwrap();
        world.apply(&c).unwrap();
        assert_eq!(world.grasp(), Some(attempt));
    }

    #[test]
    fn a_close_on_the_part_grasps_it_and_it_moves_with_the_gripper() {
        let mut grasped = 0;
        for seed in 0..8 {
            let mut world = World::new(&quick_stop(), seed).unwrap();
            world.set_ticks(10_000);
            let truth = world.truth();
            let part = Vector3::from(truth.part_base_m);
            let target = Isometry3::from_parts(
                shared::app::tool::flange_for_tool_down(&part).into(),
                gripper_down_rotation(truth.part_yaw_rad).into(),
            );
            let model = *world.plant().model();
            let Ok(q) = solve_ik(
                &model,
                &target,
                &world.plant().state().q,
                &IkConfig::default(),
            ) else {
                continue; // This draw's part is out of reach: try the next workcell.
            };
            world.set_arm(q, JointVector::zeros());
            let before = world.truth();
            assert!((Vector3::from(before.tool_base_m) - part).norm() < 1e-4);
            let mut c = hold(&world);
            c.gripper = GripperCommand::Close;
            c.camera_trigger = Some(3);
            world.apply(&c).unwrap();
            let attempt = world.grasp().unwrap();
            assert!(attempt.succeeded, "seed {seed}: {attempt:?}");
            assert!(world.truth().part_held);
            let offset =
                Vector3::from(world.truth().part_base_m) - Vector3::from(world.truth().tool_base_m);
            // Move the arm elsewhere: the part keeps its place in the gripper.
            let mut moved = q;
            moved[0] += 0.3;
            moved[2] += 0.1;
            world.set_arm(moved, JointVector::zeros());
            let after = world.truth();
            let new_offset = Vector3::from(after.part_base_m) - Vector3::from(after.tool_base_m);
            // Fixed in the flange: the base-frame offset only turns with it.
            assert!((new_offset.norm() - offset.norm()).abs() < 1e-9);
            assert!(new_offset.norm() < 1e-4);
            assert!((Vector3::from(after.part_base_m) - part).norm() > 0.1);
            // The camera sees the part where the gripper holds it.
            world.set_ticks(world.ticks + 500);
            let frames = world.due_camera_frames();
            assert_eq!(frames.len(), 1);
            // Releasing puts it down where it is.
            let mut open = hold(&world);
            open.gripper = GripperCommand::Open;
            world.apply(&open).unwrap();
            let placed = Vector3::from(world.placed_position_base().unwrap());
            assert!((placed - Vector3::from(after.part_base_m)).norm() < 0.05);
            assert!(!world.truth().part_held);
            grasped += 1;
        }
        assert!(grasped >= 2, "only {grasped} reachable workcells in 8");
    }
}
