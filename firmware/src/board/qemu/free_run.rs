//! The emulated board running free (cargo feature `free-run`): the control
//! loop runs on its own ticker ([`ControlSource::Ticker`], the STM32F407's
//! path) and reads and drives a simulated plant on the host through
//! [`PlantIo`], as the real board reads its encoders and drives its servos.
//! Neither side waits for the other:
//!
//! - the host's plant runs on its own clock and sends its state (a
//!   `SensorSample` frame: joint and conveyor counts, the part switch, the
//!   plant's time stamp) every few milliseconds; the link task leaves the
//!   newest in [`deliver_state`]'s mailbox, and [`FreeRunPlant::read_sample`]
//!   reads whatever is newest there, as an encoder read gives whatever the
//!   counter holds;
//! - [`FreeRunPlant::apply`] leaves the period's torques and gripper in
//!   [`PLANT_COMMANDS`] (the newest replaces one the link has not sent yet),
//!   and the host's plant applies the newest command it has;
//! - [`FreeRunPlant::disable`] sends nothing and withdraws a command not yet
//!   sent: the host's drives then brake the arm when their watchdog runs out,
//!   as amplifiers whose enable dropped leave the arm to its brakes.
//!
//! A period's sample carries the state's own time stamp (the instant of its
//! counts, [`PlantIo::reading_time_us`]), not the period's start: the
//! state's age varies with the link (a few milliseconds, tens when the host
//! holds QEMU off), and speeds differenced over a few periods would take
//! that variation for motion. A period that finds no state newer than the
//! last one's runs nothing (the control loop skips it; the host's drives
//! hold the last command). The camera trigger's edge is the latch of the
//! state read in that period: the control loop's `TriggerEvent` carries the
//! state's stamp, and the host's camera exposes the scene of exactly that
//! state, so the counts paired with the frame are the exposure's, as on the
//! real board.

use core::cell::Cell;

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::signal::Signal;
use shared::protocol::{ActuatorCommand, GripperCommand, SensorSample};

use crate::board::{validate_torques, BoardError, HomingInputs, PlantIo, PlantReading, JOINTS};

/// The newest plant state from the host (written by the link task).
static PLANT_STATE: Mutex<CriticalSectionRawMutex, Cell<Option<SensorSample>>> =
    Mutex::new(Cell::new(None));

/// Plant -> link: the newest command for the host's plant.
pub static PLANT_COMMANDS: Signal<CriticalSectionRawMutex, ActuatorCommand> = Signal::new();

/// The link task's side: a plant state arrived (the newest wins; an older
/// one arriving late, reordered, is ignored).
pub fn deliver_state(sample: &SensorSample) {
    PLANT_STATE.lock(|state| {
        let newer = state
            .get()
            .is_none_or(|held| sample.time_us >= held.time_us);
        if newer {
            state.set(Some(*sample));
        }
    });
}

/// The simulated plant behind the link.
pub struct FreeRunPlant {
    /// The state `reading_time_us` found, which `read_sample` returns (the
    /// link task, at a lower priority, cannot replace it in between).
    pending: Option<SensorSample>,
    /// The sequence number of the state read last (echoed in the commands,
    /// so the host can bound the states in flight).
    last_seq: u32,
}

impl FreeRunPlant {
    pub(super) fn take() -> Self {
        FreeRunPlant {
            pending: None,
            last_seq: 0,
        }
    }

    fn newest() -> Result<SensorSample, BoardError> {
        PLANT_STATE.lock(Cell::get).ok_or(BoardError::NoPlantState)
    }
}

impl PlantIo for FreeRunPlant {
    /// The newest state's own time stamp (the plant's clock).
    fn reading_time_us(&mut self, _now_us: u64) -> Result<u64, BoardError> {
        let state = Self::newest()?;
        self.pending = Some(state);
        Ok(state.time_us)
    }

    fn read_sample(&mut self, _camera_trigger: bool) -> Result<PlantReading, BoardError> {
        let state = match self.pending.take() {
            Some(state) => state,
            None => Self::newest()?,
        };
        self.last_seq = state.seq;
        Ok(PlantReading {
            joint_counts: state.joint_counts,
            conveyor_counts: state.conveyor_counts,
            part_in_gripper: state.part_in_gripper,
            emergency_stop: false,
            drive_fault: false,
        })
    }

    /// The homing inputs of the state `read_sample` returned (the host's
    /// plant holds each index latch until the next pulse).
    fn read_homing_inputs(&mut self) -> Result<HomingInputs, BoardError> {
        let state = Self::newest()?;
        Ok(HomingInputs {
            joint_pots_rad: state.joint_pots_rad,
            joint_index_counts: state.joint_index_counts,
        })
    }

    fn apply(&mut self, torque_nm: &[f32; JOINTS], gripper_closed: bool) -> Result<(), BoardError> {
        if let Err(error) = validate_torques(torque_nm) {
            self.disable();
            return Err(error);
        }
        PLANT_COMMANDS.signal(ActuatorCommand {
            seq: self.last_seq,
            joint_torque_nm: *torque_nm,
            gripper: if gripper_closed {
                GripperCommand::Close
            } else {
                GripperCommand::Open
            },
            camera_trigger: None,
        });
        Ok(())
    }

    fn disable(&mut self) {
        PLANT_COMMANDS.reset();
    }

    /// The simulator's brakes are its drives' watchdog's.
    fn set_brakes(&mut self, _engaged: bool) {}
}
