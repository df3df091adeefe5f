//! Building the pick: the controller for a cell configuration (its dynamic
//! model, Eq 23's gains, the conveyor filter of Eq 1, the view monitor's
//! limits) and the three parts the firmware and the simulator run.

use heapless::{Deque, Vec};
use nalgebra::Vector3;

use super::camera_trigger::CameraTrigger;
use super::cell::{Cell, ConfigError};
use super::drop_off::check_drop_off;
use super::early::EarlyFinish;
use super::job_slot::JobSlot;
use super::motion::Motion;
use super::pairing::FramePairer;
use super::refresh::Refresh;
use super::route::Route;
use super::settings::PickSettings;
use super::sightings::Sightings;
use super::step::Step;
use super::supervisor::Supervisor;
use super::view_monitor::{ViewLimits, ViewMonitor};
use super::worker::PickWorker;
use super::{PickController, PickCounters};
use crate::app::joint_observer::JointObserver;
use crate::app::joint_speed::JointSpeedWindow;
use crate::control::{ControllerConfig, TaskSpaceController};
use crate::fusion::{ConveyorFilter, ConveyorMeanSpeed};
use crate::planning::TaskState;
use crate::protocol::{CellConfig, GripperCommand};
use crate::robot::{DriveOptions, JointVector, Puma560};

/// Eq 23's gains for the pick (see [`ControllerConfig::puma560`]).
fn controller_config() -> Result<ControllerConfig<f32>, ConfigError> {
    ControllerConfig::puma560().map_err(|_| ConfigError::new("controller gains", "cannot be built"))
}

/// The pick's three parts for one cell configuration.
#[derive(Debug, Clone)]
pub struct PickParts {
    /// The control loop.
    pub control: PickController,
    /// The camera frames' pairing with their triggers.
    pub pairer: FramePairer,
    /// The background jobs (estimates, intercept plans).
    pub worker: PickWorker,
}

impl PickParts {
    /// The parts for the cell `config`, with the pick's default settings.
    /// `session` tells this configuration's job results from an older one's.
    pub fn new(config: &CellConfig, session: u32) -> Result<Self, ConfigError> {
        Self::with_settings(config, PickSettings::default(), session)
    }

    /// The parts for the cell `config` with `settings`.
    pub fn with_settings(
        config: &CellConfig,
        settings: PickSettings,
        session: u32,
    ) -> Result<Self, ConfigError> {
        Ok(Self {
            control: PickController::new(config, settings, session)?,
            pairer: FramePairer::for_config(config),
            worker: PickWorker::new(config, settings)?,
        })
    }
}

/// The width of the controller's Coulomb friction law, rad/s. Eq 23 takes
/// friction at the reference's joint speeds (`J^+ Yd_dot`, see
/// [`crate::control::computed_torque`]), which carry no encoder noise, so the
/// law may be as narrow as the plant's: 0.01 rad/s reaches 76 % of the full
/// Coulomb torque at 0.01 rad/s. (Taken at the measured speeds, a law this
/// narrow flipped the full Coulomb torque on a one-count change of the speed
/// and the hold hunted; 0.05 rad/s avoided that but fed forward too little
/// friction to a slowly moving joint, which then stuck and slipped.)
const CONTROLLER_COULOMB_WIDTH_RAD_S: f64 = 0.01;

/// The controller's dynamic model for Eq 23 (and for the planner's torque
/// check): the nominal PUMA 560 with armature and smoothed friction, in `f32`.
pub(super) fn controller_model() -> Result<Puma560<f32>, ConfigError> {
    Ok(Puma560::<f64>::new()
        .with_drive(DriveOptions {
            armature: true,
            friction: true,
        })
        .try_with_coulomb_smoothing(CONTROLLER_COULOMB_WIDTH_RAD_S)
        .map_err(|_| ConfigError::new("controller model", "cannot be built"))?
        .cast::<f32>())
}

/// `previous`'s dynamic model, or a new one. Out of line: with the choice
/// inlined, the firmware's build of [`PickController::replacing`] held two
/// copies of the controller's construction (4 KB more flash).
#[inline(never)]
fn model_of(previous: Option<&PickController>) -> Result<Puma560<f32>, ConfigError> {
    match previous {
        Some(previous) => Ok(previous.model),
        None => controller_model(),
    }
}

impl PickController {
    /// The control loop for the cell `config`; `session` tells this
    /// configuration's job results from an older one's.
    pub fn new(
        config: &CellConfig,
        settings: PickSettings,
        session: u32,
    ) -> Result<Self, ConfigError> {
        Self::replacing(None, config, settings, session)
    }

    /// The control loop for the cell `config`, as [`PickController::new`]
    /// makes it, with `previous`'s dynamic model if there is one (no
    /// configuration changes the model): the firmware reconfigures this way so
    /// that building the model (`controller_model` and `Puma560::new`, 7.6 KB
    /// of stack) is not on the control loop's stack while the worker may be
    /// deep in a job.
    pub fn replacing(
        previous: Option<&PickController>,
        config: &CellConfig,
        settings: PickSettings,
        session: u32,
    ) -> Result<Self, ConfigError> {
        let cell = Cell::new(config)?;
        let conveyor = ConveyorFilter::new(config.conveyor_counts_per_rev, cell.counter_width, 1.0)
            .map_err(|_| {
                ConfigError::new(
                    "conveyor_counts_per_rev",
                    "is refused by the conveyor filter",
                )
            })?;
        let model = model_of(previous)?;
        check_drop_off(&model, &cell.drop_off_base, &settings)?;
        let controller = TaskSpaceController::new(controller_config()?)
            .map_err(|_| ConfigError::new("controller gains", "cannot be built"))?;
        let rest = TaskState::at_rest(Vector3::zeros(), 0.0);
        Ok(PickController {
            cell,
            settings,
            model,
            controller,
            observer: JointObserver::new(150.0, 0.05),
            conveyor_mean: ConveyorMeanSpeed::new(conveyor.rad_per_count()),
            conveyor,
            conveyor_state: None,
            outbox: Deque::new(),
            start_time_us: None,
            last_time_us: 0,
            now_s: 0.0,
            ticks: 0,
            camera_trigger: CameraTrigger::new(),
            last_paired_s: 0.0,
            step: Step::Start,
            step_started_s: 0.0,
            motion: Motion::Hold(rest),
            reference: rest,
            gripper: GripperCommand::Open,
            fault: None,
            estimate: None,
            poses: Vec::new(),
            jobs: JobSlot::new(session),
            next_plan_attempt_s: 0.0,
            plan_lead_s: settings.plan_budget_s,
            calibration_rounds: 0,
            early: EarlyFinish::new(),
            estimate_serial: 0,
            refresh: Refresh::new(),
            qdd_commanded: JointVector::zeros(),
            tool_measured: Vector3::zeros(),
            tool_yaw_measured: 0.0,
            counters: PickCounters::default(),
            view: ViewMonitor::new(ViewLimits {
                residual_px: settings.view_residual_px,
                strikes: settings.view_strikes,
                slip_tolerance_m: settings.slip_tolerance_m,
            }),
            flange_measured: Vector3::zeros(),
            part_in_gripper: false,
            speed_window: JointSpeedWindow::new(),
            brake: None,
            on_brakes: false,
            integral_reset_s: 0.0,
            last_command: None,
            link_frames_rejected: 0,
            supervisor: Supervisor::new(),
            intercept_attempts: 0,
            window_omega: 0.0,
            window_settle_max_s: 0.0,
            last_unsettled_s: 0.0,
            route: Route::new(),
            sightings: Sightings::new(),
            calibration_accepted: false,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(conveyor_counts_per_rev: u32, part_feature_count: u8) -> CellConfig {
        crate::test_cell::test_cell_config(conveyor_counts_per_rev, part_feature_count)
    }

    #[test]
    fn a_controller_replacing_another_is_a_new_controller() {
        let settings = PickSettings::default();
        let first = PickController::new(&config(4096, 4), settings, 1)
            .unwrap_or_else(|e| panic!("{}", e.field));
        let next = config(2048, 3);
        let reconfigured = PickController::replacing(Some(&first), &next, settings, 2)
            .unwrap_or_else(|e| panic!("{}", e.field));
        let new = PickController::new(&next, settings, 2).unwrap_or_else(|e| panic!("{}", e.field));
        assert_eq!(format!("{reconfigured:?}"), format!("{new:?}"));
        let mut bad = next;
        bad.conveyor_counts_per_rev = 0;
        assert_eq!(
            PickController::replacing(Some(&first), &bad, settings, 3)
                .map(|_| ())
                .map_err(|e| e.field),
            PickController::new(&bad, settings, 3)
                .map(|_| ())
                .map_err(|e| e.field)
        );
    }
}
