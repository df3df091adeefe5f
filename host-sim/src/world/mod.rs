//! The simulated world of the workcell (issue: the full pick): the physics the
//! controller does not see directly, only through its sensors.
//!
//! - [`plant`]: the PUMA 560 in `f64` with armature and friction, integrated by RK4,
//!   with its drives' torque saturation and quantised joint encoders.
//! - [`conveyor`]: the disc with speed ripple and a wrapping quadrature encoder.
//! - [`gripper`]: closes on the part only within a stated tolerance.

pub mod conveyor;
pub mod gripper;
pub mod plant;
