//! One control period of the world: the camera exposes, the gripper acts, the
//! plant integrates the delivered torque (or, in a stall, the drives' watchdog
//! brakes); and the part's motion on the disc, in the gripper or put down.

use anyhow::{Context, Result};
use nalgebra::{Isometry3, Point3, Vector3};
use shared::protocol::{ActuatorCommand, GripperCommand};
use shared::robot::JointVector;

use super::{
    array, mean, part_yaw, GraspAttempt, PartState, World, WorldTruth, BRAKE_DAMPING_NM_S,
    DRIVE_WATCHDOG_S, TOOL_PAYLOAD_COM_FLANGE_M,
};
use crate::world::gripper::try_grasp;
use crate::world::vision::SceneMarks;
use crate::world::workcell::Workcell;

impl World {
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
                // The drive's own brake keeps within the share of the rating
                // its maker allows for its torque constant and ripple (the
                // controller's `DRIVE_TORQUE_HEADROOM`): undamped, a wrist
                // joint at speed asked for 1.06 of its rating.
                let state = self.plant.state();
                let wanted =
                    self.plant.model().gravity_torque(&state.q) - state.qd * BRAKE_DAMPING_NM_S;
                let headroom = f64::from(shared::control::puma::DRIVE_TORQUE_HEADROOM);
                let rated = self.plant.model().joint_limits().torque_max;
                JointVector::from_fn(|j, _| {
                    let max = rated[j] * headroom;
                    wanted[j].clamp(-max, max)
                })
            };
            self.plant
                .step(&tau, dt)
                .with_context(|| format!("plant (braked) at t = {:.3} s", self.time_s()))?;
            self.homing_sensors.track(&self.plant.state().q);
        }
        self.ticks += 1;
        Ok(())
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

    /// Exposes frame `trigger_id` of `scene`, the marks at `time_s` (kept
    /// from then: a free-running plant's camera, triggered at an instant the
    /// trigger event names after the fact).
    pub fn expose_camera(&mut self, trigger_id: u32, time_s: f64, scene: &SceneMarks) {
        self.camera.expose(trigger_id, time_s, scene);
    }

    /// One control period under `command`: the camera exposes now if triggered,
    /// the gripper acts now, then the plant integrates the delivered torque.
    pub fn apply(&mut self, command: &ActuatorCommand) -> Result<()> {
        self.unattended_ticks = 0;
        self.bump_camera_if_due();
        if let Some(trigger_id) = command.camera_trigger {
            let now = self.time_s();
            match self.image_vision.take() {
                Some(mut vision) => {
                    let seen = vision.see(self, trigger_id);
                    self.image_vision = Some(vision);
                    let frame = seen.with_context(|| format!("camera frame at t = {now:.3} s"))?;
                    self.camera.deliver(now, frame);
                }
                None => {
                    let scene = self.scene_marks();
                    self.camera.expose(trigger_id, now, &scene);
                }
            }
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
            self.homing_sensors.track(&self.plant.state().q);
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
            tau_nm: self.plant.applied_torque().into(),
        }
    }
}
