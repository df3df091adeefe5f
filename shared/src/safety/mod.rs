//! Drives that fail safe: the decisions behind the amplifier enable, kept here
//! (no_std, heap-free, no board types) so that they are unit-tested on the
//! host; the firmware's board code only carries them out.
//!
//! - [`deadline`]: control periods that overrun their deadline many times
//!   in a row stop the cell.
//! - [`drive_interlock`]: the per-period cut-out. Torques, joint soft limits,
//!   overspeed while braking and commanded-versus-measured motion decide
//!   whether the enable may be high; a trip is latched, with its joint and
//!   check, until the host acknowledges it.
//! - [`fault_latch`]: a board fault (panic, HardFault, unexpected interrupt,
//!   watchdog reset) latched until the host acknowledges it, and kept across
//!   the reset that follows a panic.
//! - [`joint_signs`]: per-joint encoder and motor signs of a board's wiring, so
//!   a swapped quadrature channel or motor lead is a configuration entry found
//!   at commissioning, not a runaway.
//! - [`parking`]: after a pick has ended, or the host link is lost, the arm
//!   is put on its holding brakes and the drives go off, after a bounded
//!   hold.
//! - [`reconfigure`]: a new cell configuration replaces the controller only
//!   with the pick ended, the arm at rest, the gripper empty and (on a board
//!   that owns them) the drives off.
//! - [`reversal`]: the order in which a sign-magnitude drive's direction line
//!   and preloaded duty change, so that the old magnitude never drives the new
//!   direction.

pub mod deadline;
pub mod drive_interlock;
pub mod fault_latch;
pub mod joint_signs;
pub mod parking;
pub mod reconfigure;
pub mod reversal;

pub use deadline::{DeadlineMonitor, DEADLINE_MISSES_TO_STOP};
pub use drive_interlock::{
    BoardFault, DriveInterlock, EncoderMotion, InterlockCheck, InterlockFault, InterlockLimits,
    InterlockOutput, InterlockSettings, PeriodInput,
};
pub use fault_latch::{fault_from_reset_word, reset_word, FaultLatch};
pub use joint_signs::{JointSigns, Sign};
pub use parking::{ParkState, Parking, ParkingInput, ParkingOutput};
pub use reconfigure::{check_reconfigure, CellState, ReconfigureRefusal, REST_SPEED_RAD_S};
pub use reversal::{sign_magnitude_steps, DriveStep};

/// Joints of the PUMA 560.
pub const JOINTS: usize = 6;
