//! The simulated world: everything the controller does not see directly, only
//! through its sensors, and the truth its estimates are judged against.
//!
//! - [`cell`]: the workcell of one pick experiment ([`World`]): plant, conveyor,
//!   camera and gripper in lock step with the controller's periods.
//! - [`workcell`]: the true geometry of one workcell (camera, disc, part, robot base).
//! - [`generator`]: random workcells drawn from a scenario's ranges.
//! - [`serve`]: which layouts the arm can serve.
//! - [`effector`]: end-effector poses the PUMA 560 can reach and the camera can see.
//! - [`dimensions`]: the disc's radius and the PUMA 560's shoulder height.
//! - [`camera`]: the pinhole camera of the contract.
//! - [`vision`]: the camera and its vision computer as the controller meets them.
//! - [`render`]: the camera's grey image of each frame (for measuring the mark detector).
//! - [`plant`]: the PUMA 560 in `f64` with armature and friction, integrated by RK4,
//!   with its drives' torque saturation and quantised joint encoders.
//! - [`drive`]: the true drives drawn per cell (friction, armature, torque
//!   constants) and the amplifier's current lag and ripple.
//! - [`conveyor`]: the disc with speed ripple and a wrapping quadrature encoder.
//! - [`gripper`]: closes on the part only within a stated tolerance.
//! - [`homing_sensors`]: the counters' power-on offsets, the potentiometers and
//!   the index pulses homing reads.

pub mod camera;
pub mod cell;
pub mod conveyor;
pub mod dimensions;
pub mod drive;
pub mod effector;
pub mod generator;
pub mod gripper;
pub mod homing_sensors;
pub mod image_vision;
pub mod plant;
pub mod render;
pub mod serve;
pub mod vision;
pub mod workcell;

pub use cell::{CellLayout, GraspAttempt, World, WorldTruth};
pub use generator::{random_workcell, GenerationError, WorkcellParameters};
pub use workcell::Workcell;
